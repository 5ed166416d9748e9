#include "structgp/kernel/pol_chain_kernel.h"

#include <cassert>
#include <cmath>
#include <stdexcept>
#include <string>

#include "structgp/core/validate.h"

namespace structgp {

PolChainKernel::PolChainKernel(int num_joints, int output_joint)
    : num_joints_(num_joints), output_joint_(output_joint) {
  if (num_joints < 1) {
    throw std::invalid_argument("PolChainKernel num_joints: expected at least 1, got " +
                                std::to_string(num_joints));
  }
  if (output_joint < 1 || output_joint > num_joints) {
    throw std::invalid_argument("PolChainKernel output_joint: expected 1.." +
                                std::to_string(num_joints) + ", got " +
                                std::to_string(output_joint));
  }
  parameters_ = Vector::Zero(num_parameters());
  UpdateCache();
}

std::vector<std::string> PolChainKernel::parameter_names() const {
  return {"log_sigma", "log_scale_inertial", "log_scale_coriolis", "log_scale_gravity"};
}

std::unique_ptr<Kernel> PolChainKernel::WithParameters(const ConstVectorRef& theta) const {
  RequireSize("PolChainKernel::WithParameters theta", theta.size(), num_parameters());
  RequireFinite("PolChainKernel::WithParameters theta", theta);
  auto kernel = std::make_unique<PolChainKernel>(*this);
  kernel->parameters_ = theta;
  kernel->UpdateCache();
  return kernel;
}

void PolChainKernel::UpdateCache() {
  k_ = internal::PolConstants(parameters_, num_joints_, /*include_gravity=*/true);
}

PolKernelTerms PolChainKernel::Compute(const ConstVectorRef& a, const ConstVectorRef& b,
                                       double* d_log_sigma) const {
  assert(a.size() == input_dim() && b.size() == input_dim());
  const int n = num_joints_;
  const int J = output_joint_ - 1;  // 0-based
  const double* pa = a.data();
  const double* pb = b.data();
  const double inv_one_plus_theta = 1.0 / (1.0 + k_.theta);
  // Backward over the joints: T = prod_{l > current} f_l^2 (the suffix product S of the
  // header, 0-based), dT = dT/dtheta; A, B = suffix sums of a_k, b_k.
  double T = 1.0, dT = 0.0;
  double A = 0.0, B = 0.0;
  double inertial = 0.0, d_inertial = 0.0;
  double coriolis = 0.0, d_coriolis = 0.0;
  // Gravity as k_pol's: R = prod (1 + theta cos), E = R - 1 without cancellation, dR/dtheta.
  double r = 1.0, e = 0.0, dr = 0.0;
  for (int l = n - 1; l >= 0; --l) {
    const double ak = pa[n + l] * pb[n + l];
    const double bk = pa[2 * n + l] * pb[2 * n + l];
    if (l < J) {
      // Terms whose smallest joint index is l (< J): they depend on q_{l+1..}.
      inertial += bk * T;
      d_inertial += bk * dT;
      const double w = ak * (ak + 2.0 * A);
      coriolis += w * T;
      d_coriolis += w * dT;
    }
    A += ak;
    B += bk;
    if (l == J) {
      // Every term with all indices >= J depends on q_{J+1..}.
      inertial += B * T;
      d_inertial += B * dT;
      coriolis += A * A * T;
      d_coriolis += A * A * dT;
    }
    const double c = std::cos(pa[l] - pb[l]);
    const double t = k_.theta * c;
    const double f = (1.0 + t) * inv_one_plus_theta;
    const double df = (c - 1.0) * inv_one_plus_theta * inv_one_plus_theta;
    dT = 2.0 * f * df * T + f * f * dT;
    T *= f * f;
    dr = dr * (1.0 + t) + r * c;
    r *= 1.0 + t;
    e += t + e * t;
  }
  const double inv_n = 1.0 / n;
  PolKernelTerms terms;
  terms.inertial = k_.scale_inertial * inertial * inv_n;
  terms.coriolis = k_.scale_coriolis * k_.theta * coriolis * inv_n * inv_n;
  terms.gravity = k_.scale_gravity * k_.c_psi * e;
  if (d_log_sigma != nullptr) {
    const double di = k_.scale_inertial * d_inertial * inv_n;
    const double dc = k_.scale_coriolis * (coriolis + k_.theta * d_coriolis) * inv_n * inv_n;
    const double dg = k_.d_c_psi * e + k_.c_psi * dr * k_.d_theta;
    *d_log_sigma = k_.d_theta * (di + dc) + k_.scale_gravity * dg;
  }
  return terms;
}

double PolChainKernel::Evaluate(const ConstVectorRef& a, const ConstVectorRef& b) const {
  const PolKernelTerms t = Compute(a, b, nullptr);
  return t.inertial + t.coriolis + t.gravity;
}

PolKernelTerms PolChainKernel::EvaluateTerms(const ConstVectorRef& a,
                                             const ConstVectorRef& b) const {
  return Compute(a, b, nullptr);
}

void PolChainKernel::Gradient(const ConstVectorRef& a, const ConstVectorRef& b,
                              VectorRef dk) const {
  assert(dk.size() == num_parameters());
  double d_log_sigma = 0.0;
  const PolKernelTerms t = Compute(a, b, &d_log_sigma);
  internal::PolGradient(t.inertial, t.coriolis, t.gravity, d_log_sigma,
                        /*include_gravity=*/true, dk);
}

std::unique_ptr<Kernel> PolChainKernel::Clone() const {
  return std::make_unique<PolChainKernel>(*this);
}

}  // namespace structgp
