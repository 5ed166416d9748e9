#include "structgp/feature/pol_kernel_formula.h"

#include <cmath>
#include <string>

#include "structgp/core/validate.h"
#include "trig_tensor.h"

namespace structgp {
namespace {

// Checks the arguments; builds an error message only when something is wrong.
void CheckStates(const char* what, const ConstVectorRef& a, const ConstVectorRef& b,
                 int num_joints) {
  if (num_joints < 1) RequireInRange(std::string(what) + " num_joints", num_joints, 1, 1e9, true);
  const Eigen::Index n3 = 3 * static_cast<Eigen::Index>(num_joints);
  if (a.size() != n3) RequireSize(std::string(what) + " a", a.size(), n3);
  if (b.size() != n3) RequireSize(std::string(what) + " b", b.size(), n3);
}

void CheckSigma(const char* what, double sigma) {
  if (!(sigma >= 0.0)) {
    RequireInRange(std::string(what) + " sigma", sigma, 0.0, HUGE_VAL, true, true);
  }
}

double Dot(const double* a, const double* b, int n) {
  double s = 0.0;
  for (int i = 0; i < n; ++i) s += a[i] * b[i];
  return s;
}

// Everything PolKernel and PolKernelGravityFree need, with d/d log sigma in forward mode.
struct PolParts {
  double inertial_plus_coriolis;  // k_qdd + theta k_qdqd
  double psi_sigma;               // k_psi_sigma
  double c_psi;
  double d_inertial_plus_coriolis;
  double d_psi_sigma;
  double d_c_psi;
};

PolParts ComputePolParts(const ConstVectorRef& a, const ConstVectorRef& b, int n, double sigma) {
  const internal::PolShape s = internal::MakePolShapeFromSigma(sigma, n);
  const double d_theta = -s.theta * s.one_minus_theta;  // d theta / d log sigma
  const double qdd = Dot(a.data() + 2 * n, b.data() + 2 * n, n) / n;
  const double qd = Dot(a.data() + n, b.data() + n, n) / n;
  const double qdqd = qd * qd;
  // R = prod_n (1 + theta cos d_n) and dR/dtheta, accumulated together.
  double r = 1.0;
  double dr = 0.0;
  for (int j = 0; j < n; ++j) {
    const double c = std::cos(a[j] - b[j]);
    const double f = 1.0 + s.theta * c;
    dr = dr * f + r * c;
    r *= f;
  }
  PolParts p;
  p.inertial_plus_coriolis = qdd + s.theta * qdqd;
  p.psi_sigma = s.c_psi * r;
  p.c_psi = s.c_psi;
  p.d_inertial_plus_coriolis = d_theta * qdqd;
  p.d_c_psi = s.c_psi * s.dlog_c_psi;
  p.d_psi_sigma = p.d_c_psi * r + s.c_psi * dr * d_theta;
  return p;
}

}  // namespace

double QddKernel(const ConstVectorRef& a, const ConstVectorRef& b, int num_joints) {
  CheckStates("QddKernel", a, b, num_joints);
  const int n = num_joints;
  return Dot(a.data() + 2 * n, b.data() + 2 * n, n) / n;
}

double QdQdKernel(const ConstVectorRef& a, const ConstVectorRef& b, int num_joints) {
  CheckStates("QdQdKernel", a, b, num_joints);
  const int n = num_joints;
  const double d = Dot(a.data() + n, b.data() + n, n) / n;
  return d * d;
}

double PsiKernel(const ConstVectorRef& a, const ConstVectorRef& b, int num_joints) {
  CheckStates("PsiKernel", a, b, num_joints);
  double k = 1.0;
  for (int j = 0; j < num_joints; ++j) k *= std::cos(a[j] - b[j]) + 1.0;
  return k;
}

double PsiSigmaKernel(const ConstVectorRef& a, const ConstVectorRef& b, int num_joints,
                      double sigma) {
  CheckStates("PsiSigmaKernel", a, b, num_joints);
  CheckSigma("PsiSigmaKernel", sigma);
  return ComputePolParts(a, b, num_joints, sigma).psi_sigma;
}

double PolKernel(const ConstVectorRef& a, const ConstVectorRef& b, int num_joints, double sigma,
                 double* d_log_sigma) {
  CheckStates("PolKernel", a, b, num_joints);
  CheckSigma("PolKernel", sigma);
  const PolParts p = ComputePolParts(a, b, num_joints, sigma);
  const double psi2 = p.psi_sigma * p.psi_sigma;
  if (d_log_sigma != nullptr) {
    *d_log_sigma = p.d_inertial_plus_coriolis * psi2 +
                   p.inertial_plus_coriolis * 2.0 * p.psi_sigma * p.d_psi_sigma + p.d_psi_sigma -
                   p.d_c_psi;
  }
  return p.inertial_plus_coriolis * psi2 + p.psi_sigma - p.c_psi;
}

double PolKernelGravityFree(const ConstVectorRef& a, const ConstVectorRef& b, int num_joints,
                            double sigma, double* d_log_sigma) {
  CheckStates("PolKernelGravityFree", a, b, num_joints);
  CheckSigma("PolKernelGravityFree", sigma);
  const PolParts p = ComputePolParts(a, b, num_joints, sigma);
  const double psi2 = p.psi_sigma * p.psi_sigma;
  if (d_log_sigma != nullptr) {
    *d_log_sigma = p.d_inertial_plus_coriolis * psi2 +
                   p.inertial_plus_coriolis * 2.0 * p.psi_sigma * p.d_psi_sigma;
  }
  return p.inertial_plus_coriolis * psi2;
}

}  // namespace structgp
