#include "structgp/feature/gravity_basis_feature_map.h"

#include <stdexcept>

#include "structgp/core/validate.h"
#include "trig_tensor.h"

namespace structgp {

using internal::kNumU;

GravityBasisFeatureMap::GravityBasisFeatureMap(int num_joints, const GravityBasisOptions& options)
    : num_joints_(num_joints), options_(options) {
  if (num_joints < 1 || num_joints > kMaxGravityBasisJoints) {
    throw std::invalid_argument("GravityBasisFeatureMap: expected 1 to " +
                                std::to_string(kMaxGravityBasisJoints) + " joints, got " +
                                std::to_string(num_joints));
  }
  dim_ = internal::IntPow(kNumU, num_joints) - 1;
}

std::vector<FeatureBlock> GravityBasisFeatureMap::blocks() const {
  return {FeatureBlock{"gravity", 0, dim_}};
}

std::vector<std::string> GravityBasisFeatureMap::shape_parameter_names() const {
  if (options_.pol_prior) return {"log_sigma"};
  return {};
}

Vector GravityBasisFeatureMap::default_shape_parameters() const {
  return Vector::Zero(num_shape_parameters());
}

void GravityBasisFeatureMap::Evaluate(const ConstVectorRef& x, VectorRef phi) const {
  if (x.size() != input_dim()) {
    RequireSize("GravityBasisFeatureMap::Evaluate x", x.size(), input_dim());
  }
  if (phi.size() != dim_) RequireSize("GravityBasisFeatureMap::Evaluate phi", phi.size(), dim_);
  double u[kMaxGravityBasisJoints * kNumU];
  for (int j = 0; j < num_joints_; ++j) internal::TrigU(x[j], u + j * kNumU);
  internal::TensorProduct<kNumU>(num_joints_, u, 1.0, true, internal::Multiply(), phi.data());
}

void GravityBasisFeatureMap::PriorVariance(const ConstVectorRef& shape, VectorRef lambda,
                                           Matrix* jacobian) const {
  if (!options_.pol_prior) {
    FeatureMap::PriorVariance(shape, lambda, jacobian);
    return;
  }
  RequireSize("GravityBasisFeatureMap::PriorVariance shape", shape.size(), 1);
  RequireSize("GravityBasisFeatureMap::PriorVariance lambda", lambda.size(), dim_);
  RequireFinite("GravityBasisFeatureMap::PriorVariance shape (log_sigma)", shape);
  const internal::PolShape s = internal::MakePolShape(shape[0], num_joints_);
  double w[kMaxGravityBasisJoints * kNumU], dw[kMaxGravityBasisJoints * kNumU];
  for (int j = 0; j < num_joints_; ++j) internal::WeightsU(s, w + j * kNumU, dw + j * kNumU);
  double* l = lambda.data();
  internal::TensorProduct<kNumU>(num_joints_, w, 1.0, true, internal::Multiply(), l);
  for (int k = 0; k < dim_; ++k) l[k] *= s.c_psi;
  if (jacobian != nullptr) {
    jacobian->resize(dim_, 1);
    double* d = jacobian->data();
    internal::TensorProduct<kNumU>(num_joints_, dw, 0.0, true, internal::Add(), d);
    for (int k = 0; k < dim_; ++k) d[k] = (d[k] + s.dlog_c_psi) * l[k];
  }
}

std::string GravityBasisFeatureMap::feature_name(int k) const {
  if (k < 0 || k >= dim_) {
    RequireInRange("GravityBasisFeatureMap::feature_name k", k, 0, dim_, true, false);
  }
  int index = k + 1;  // alpha = 0 is left out
  std::string digits(static_cast<size_t>(num_joints_), '0');
  for (int j = num_joints_ - 1; j >= 0; --j) {
    digits[static_cast<size_t>(j)] = static_cast<char>('0' + index % kNumU);
    index /= kNumU;
  }
  std::string name = "gravity[";
  for (int j = 0; j < num_joints_; ++j) {
    if (j > 0) name += ',';
    name += digits[static_cast<size_t>(j)];
  }
  return name + "]";
}

}  // namespace structgp
