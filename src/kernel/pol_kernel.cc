#include "structgp/kernel/pol_kernel.h"

#include <cassert>
#include <cmath>
#include <stdexcept>
#include <string>

#include "feature/trig_tensor.h"
#include "structgp/core/validate.h"

namespace structgp {

PolFormulaKernel::PolFormulaKernel(int num_joints, const PolOptions& options)
    : num_joints_(num_joints), options_(options) {
  if (num_joints < 1) {
    throw std::invalid_argument("PolFormulaKernel num_joints: expected at least 1, got " +
                                std::to_string(num_joints));
  }
  parameters_ = Vector::Zero(num_parameters());
  UpdateCache();
}

std::vector<std::string> PolFormulaKernel::block_names() const {
  std::vector<std::string> names = {"inertial", "coriolis"};
  if (options_.include_gravity) names.push_back("gravity");
  return names;
}

std::vector<std::string> PolFormulaKernel::parameter_names() const {
  std::vector<std::string> names = {"log_sigma"};
  for (const std::string& block : block_names()) names.push_back("log_scale_" + block);
  return names;
}

Vector PolFormulaKernel::parameters() const { return parameters_; }

std::unique_ptr<Kernel> PolFormulaKernel::WithParameters(const ConstVectorRef& theta) const {
  auto kernel = std::make_unique<PolFormulaKernel>(*this);
  kernel->AssignParameters(theta);
  return kernel;
}

void PolFormulaKernel::AssignParameters(const ConstVectorRef& theta) {
  RequireSize("PolFormulaKernel::WithParameters theta", theta.size(), num_parameters());
  RequireFinite("PolFormulaKernel::WithParameters theta", theta);
  parameters_ = theta;
  UpdateCache();
}

namespace internal {
PolConstants::PolConstants(const Vector& parameters, int num_joints, bool include_gravity) {
  const PolShape s = MakePolShape(parameters[0], num_joints);
  theta = s.theta;
  d_theta = -s.theta * s.one_minus_theta;
  c_psi = s.c_psi;
  d_c_psi = s.c_psi * s.dlog_c_psi;
  scale_inertial = std::exp(2.0 * parameters[1]);
  scale_coriolis = std::exp(2.0 * parameters[2]);
  scale_gravity = include_gravity ? std::exp(2.0 * parameters[3]) : 0.0;
}
}  // namespace internal

void PolFormulaKernel::UpdateCache() {
  k_ = internal::PolConstants(parameters_, num_joints_, options_.include_gravity);
}

PolKernelTerms PolFormulaKernel::Compute(const ConstVectorRef& a, const ConstVectorRef& b,
                                         double* d_log_sigma) const {
  assert(a.size() == input_dim() && b.size() == input_dim());
  const int n = num_joints_;
  const double* pa = a.data();
  const double* pb = b.data();
  double qd = 0.0;
  double qdd = 0.0;
  for (int j = 0; j < n; ++j) {
    qd += pa[n + j] * pb[n + j];
    qdd += pa[2 * n + j] * pb[2 * n + j];
  }
  const double inv_n = 1.0 / n;
  const double k_qdd = qdd * inv_n;             // eq. 7
  const double k_qdqd = qd * inv_n * qd * inv_n;  // eq. 8
  // R = prod_n (1 + theta cos d_n), E = R - 1 (accumulated without cancellation) and
  // dR/dtheta, in one pass.
  double r = 1.0;
  double e = 0.0;
  double dr = 0.0;
  for (int j = 0; j < n; ++j) {
    const double c = std::cos(pa[j] - pb[j]);
    const double t = k_.theta * c;
    dr = dr * (1.0 + t) + r * c;
    r *= 1.0 + t;
    e += t + e * t;
  }
  const double psi = k_.c_psi * r;  // k_psi_sigma, eq. 18
  const double psi2 = psi * psi;
  PolKernelTerms terms;
  terms.inertial = k_.scale_inertial * k_qdd * psi2;
  terms.coriolis = k_.scale_coriolis * k_.theta * k_qdqd * psi2;
  terms.gravity = k_.scale_gravity * k_.c_psi * e;  // k_psi_sigma - c_psi
  if (d_log_sigma != nullptr) {
    const double d_r = dr * k_.d_theta;  // dR / d log sigma
    const double d_psi = k_.d_c_psi * r + k_.c_psi * d_r;
    const double d_gravity = k_.d_c_psi * e + k_.c_psi * d_r;
    *d_log_sigma = k_.scale_inertial * k_qdd * 2.0 * psi * d_psi +
                   k_.scale_coriolis * k_qdqd * (k_.d_theta * psi2 + k_.theta * 2.0 * psi * d_psi) +
                   k_.scale_gravity * d_gravity;
  }
  return terms;
}

double PolFormulaKernel::Evaluate(const ConstVectorRef& a, const ConstVectorRef& b) const {
  const PolKernelTerms t = Compute(a, b, nullptr);
  return t.inertial + t.coriolis + t.gravity;
}

PolKernelTerms PolFormulaKernel::EvaluateTerms(const ConstVectorRef& a,
                                               const ConstVectorRef& b) const {
  return Compute(a, b, nullptr);
}

void PolFormulaKernel::Gradient(const ConstVectorRef& a, const ConstVectorRef& b,
                                VectorRef dk) const {
  assert(dk.size() == num_parameters());
  double d_log_sigma = 0.0;
  const PolKernelTerms t = Compute(a, b, &d_log_sigma);
  internal::PolGradient(t.inertial, t.coriolis, t.gravity, d_log_sigma,
                        options_.include_gravity, dk);
}

std::unique_ptr<Kernel> PolFormulaKernel::Clone() const {
  return std::make_unique<PolFormulaKernel>(*this);
}

}  // namespace structgp
