#include "structgp/feature/pol_feature_map.h"

#include <cmath>
#include <stdexcept>
#include <string>

#include "structgp/core/validate.h"
#include "trig_tensor.h"

namespace structgp {

using internal::kNumU;
using internal::kNumV;

int PolFeatureDimension(int num_joints) {
  RequireInRange("PolFeatureDimension num_joints", num_joints, 1, kMaxPolJoints, true, true);
  const int n = num_joints;
  return (n + n * (n + 1) / 2) * internal::IntPow(kNumV, n) + internal::IntPow(kNumU, n) - 1;
}

PolFeatureMap::PolFeatureMap(int num_joints, const PolOptions& options)
    : num_joints_(num_joints), options_(options) {
  if (num_joints < 1 || num_joints > kMaxPolJoints) {
    throw std::invalid_argument("PolFeatureMap: expected 1 to " + std::to_string(kMaxPolJoints) +
                                " joints, got " + std::to_string(num_joints) +
                                " (use the kernel form, PolKernel, for more joints)");
  }
  num_v_ = internal::IntPow(kNumV, num_joints);
  num_u_ = internal::IntPow(kNumU, num_joints);
  num_velocity_pairs_ = num_joints * (num_joints + 1) / 2;
  gravity_begin_ = (num_joints + num_velocity_pairs_) * num_v_;
  dim_ = gravity_begin_ + (options.include_gravity ? num_u_ - 1 : 0);
}

std::vector<FeatureBlock> PolFeatureMap::blocks() const {
  std::vector<FeatureBlock> b = {
      {"inertial", 0, num_joints_ * num_v_},
      {"coriolis", num_joints_ * num_v_, num_velocity_pairs_ * num_v_},
  };
  if (options_.include_gravity) b.push_back({"gravity", gravity_begin_, num_u_ - 1});
  return b;
}

void PolFeatureMap::Evaluate(const ConstVectorRef& x, VectorRef phi) const {
  // The size checks build their message only on failure, so a correct call never allocates.
  if (x.size() != input_dim()) RequireSize("PolFeatureMap::Evaluate x", x.size(), input_dim());
  if (phi.size() != dim_) RequireSize("PolFeatureMap::Evaluate phi", phi.size(), dim_);
  const int n = num_joints_;
  const double* q = x.data();
  const double* qd = q + n;
  const double* qdd = q + 2 * n;
  double* p = phi.data();
  const int nv = num_v_;

  // V_beta(q) into the first inertial sub-block, built joint by joint.
  double v[kMaxPolJoints * kNumV];
  for (int j = 0; j < n; ++j) internal::TrigV(q[j], v + j * kNumV);
  internal::TensorProduct<kNumV>(n, v, 1.0, false, internal::Multiply(), p);

  // Coriolis sub-blocks qd_a qd_b V, a <= b, then inertial sub-blocks qdd_a V for a >= 2;
  // the first sub-block, which holds V, is scaled last.
  int offset = n * nv;
  for (int a = 0; a < n; ++a) {
    for (int b = a; b < n; ++b) {
      const double c = qd[a] * qd[b];
      double* out = p + offset;
      for (int k = 0; k < nv; ++k) out[k] = c * p[k];
      offset += nv;
    }
  }
  for (int a = 1; a < n; ++a) {
    const double c = qdd[a];
    double* out = p + a * nv;
    for (int k = 0; k < nv; ++k) out[k] = c * p[k];
  }
  const double c0 = qdd[0];
  for (int k = 0; k < nv; ++k) p[k] *= c0;

  if (options_.include_gravity) {
    // u(q) = (1, cos q, sin q) is the head of v(q): no further trigonometric calls.
    double u[kMaxPolJoints * kNumU];
    for (int j = 0; j < n; ++j) {
      for (int i = 0; i < kNumU; ++i) u[j * kNumU + i] = v[j * kNumV + i];
    }
    internal::TensorProduct<kNumU>(n, u, 1.0, true, internal::Multiply(), p + gravity_begin_);
  }
}

void PolFeatureMap::PriorVariance(const ConstVectorRef& shape, VectorRef lambda,
                                  Matrix* jacobian) const {
  RequireSize("PolFeatureMap::PriorVariance shape", shape.size(), 1);
  RequireSize("PolFeatureMap::PriorVariance lambda", lambda.size(), dim_);
  RequireFinite("PolFeatureMap::PriorVariance shape (log_sigma)", shape);
  const int n = num_joints_;
  const int nv = num_v_;
  const internal::PolShape s = internal::MakePolShape(shape[0], n);

  double wv[kMaxPolJoints * kNumV], dv[kMaxPolJoints * kNumV];
  for (int j = 0; j < n; ++j) internal::WeightsV(s, wv + j * kNumV, dv + j * kNumV);
  double* l = lambda.data();
  double* d = nullptr;
  internal::TensorProduct<kNumV>(n, wv, 1.0, false, internal::Multiply(), l);
  if (jacobian != nullptr) {
    jacobian->resize(dim_, 1);
    d = jacobian->data();  // d log lambda / d log sigma first, times lambda at the end
    internal::TensorProduct<kNumV>(n, dv, 0.0, false, internal::Add(), d);
  }

  const double c2 = s.c_psi * s.c_psi;
  const double dlog_c2 = 2.0 * s.dlog_c_psi;
  const double inv_n = 1.0 / n;
  int offset = n * nv;
  for (int a = 0; a < n; ++a) {
    for (int b = a; b < n; ++b) {
      const double f = s.theta * c2 * (a == b ? 1.0 : 2.0) * inv_n * inv_n;
      for (int k = 0; k < nv; ++k) l[offset + k] = f * l[k];
      if (d != nullptr) {
        const double g = dlog_c2 + s.dlog_theta();
        for (int k = 0; k < nv; ++k) d[offset + k] = d[k] + g;
      }
      offset += nv;
    }
  }
  for (int a = n - 1; a >= 0; --a) {
    const double f = c2 * inv_n;
    for (int k = 0; k < nv; ++k) l[a * nv + k] = f * l[k];
    if (d != nullptr) {
      for (int k = 0; k < nv; ++k) d[a * nv + k] = d[k] + dlog_c2;
    }
  }

  if (options_.include_gravity) {
    double wu[kMaxPolJoints * kNumU], du[kMaxPolJoints * kNumU];
    for (int j = 0; j < n; ++j) internal::WeightsU(s, wu + j * kNumU, du + j * kNumU);
    const int g = gravity_begin_;
    const int size = internal::TensorProduct<kNumU>(n, wu, 1.0, true, internal::Multiply(), l + g);
    for (int k = 0; k < size; ++k) l[g + k] *= s.c_psi;
    if (d != nullptr) {
      internal::TensorProduct<kNumU>(n, du, 0.0, true, internal::Add(), d + g);
      for (int k = 0; k < size; ++k) d[g + k] += s.dlog_c_psi;
    }
  }

  if (d != nullptr) {
    for (int k = 0; k < dim_; ++k) d[k] *= l[k];
  }
}

}  // namespace structgp
