#ifndef STRUCTGP_KERNEL_POL_KERNEL_H_
#define STRUCTGP_KERNEL_POL_KERNEL_H_

/// @file
/// The structured kernel k_pol (paper eq. 17) as a Kernel for the function-space model,
/// evaluated from its formula in O(N) per pair: the exact kernel form when the explicit map
/// is too large (D = 8,830 features at N = 4, 422,603 at N = 6; see docs/feature_maps.md).
///
/// Input x = (q_1..q_N, qd_1..qd_N, qdd_1..qdd_N) (rad, rad/s, rad/s^2), input_dim() = 3N.
/// With theta = 1 / (1 + sigma), c = c_psi = (1 + theta)^-N and
/// k_psi_sigma = c prod_n (1 + theta cos(q_n - q'_n)) (eq. 18),
///
///     k(x, x') = s_I^2 k_qdd k_psi_sigma^2               ("inertial",  M(q) qdd)
///              + s_C^2 theta k_qdqd k_psi_sigma^2        ("coriolis",  C(q, qd) qd)
///              + s_G^2 (k_psi_sigma - c)                 ("gravity",   G(q))
///
/// with k_qdd = <qdd, qdd'> / N (eq. 7), k_qdqd = <qd, qd'>^2 / N^2 (eq. 8) and block scales
/// s_b = exp(log_scale_b). At unit block scales this is k_pol (eq. 17); with
/// PolOptions::include_gravity = false the gravity term is left out (eq. 55).
///
/// Parameters, in this order (the layout of FeatureKernel(PolFeatureMap(N, options), hyper),
/// whose kernel this is, term by term):
///     "log_sigma", "log_scale_inertial", "log_scale_coriolis" [, "log_scale_gravity"].
/// Defaults: all 0 (sigma = 1, unit block scales).
///
/// Evaluate costs N cosines and O(N) flops; Gradient the same (d / d log sigma in forward mode,
/// without dividing by 1 + theta cos, which vanishes at sigma = 0). The gravity term is
/// accumulated as c (R - 1), R = prod_n (1 + theta cos), by R_n - 1 = e + t + e t with
/// e = R_{n-1} - 1, t = theta cos: no cancellation when R is close to 1. Neither allocates,
/// and both are const and use no scratch, so one kernel may be shared by concurrent readers.
///
/// The class is named after the formula it evaluates (pol_kernel_formula.h) to keep the name
/// PolKernel for the free function of that header.

#include <memory>
#include <string>
#include <vector>

#include "structgp/core/types.h"
#include "structgp/feature/pol_feature_map.h"
#include "structgp/internal/pol_constants.h"
#include "structgp/kernel/kernel.h"

namespace structgp {

/// The three terms of k_pol at one pair of states, each with its block scale applied. Their
/// sum is PolFormulaKernel::Evaluate (and PolChainKernel::Evaluate). gravity is 0 without the
/// gravity block.
struct PolKernelTerms {
  double inertial = 0.0;
  double coriolis = 0.0;
  double gravity = 0.0;
};

class PolFormulaKernel : public Kernel {
 public:
  /// Parameter positions in parameters() / Gradient.
  static constexpr int kLogSigma = 0;
  static constexpr int kLogScaleInertial = 1;
  static constexpr int kLogScaleCoriolis = 2;
  static constexpr int kLogScaleGravity = 3;  ///< only with include_gravity

  /// num_joints >= 1 (any N: the formula has no size limit). Throws std::invalid_argument
  /// otherwise.
  explicit PolFormulaKernel(int num_joints, const PolOptions& options = PolOptions());

  int num_joints() const { return num_joints_; }
  const PolOptions& options() const { return options_; }

  int input_dim() const override { return 3 * num_joints_; }
  double Evaluate(const ConstVectorRef& a, const ConstVectorRef& b) const override;

  /// 4 with the gravity block, 3 without.
  int num_parameters() const override { return options_.include_gravity ? 4 : 3; }
  std::vector<std::string> parameter_names() const override;
  Vector parameters() const override;
  std::unique_ptr<Kernel> WithParameters(const ConstVectorRef& theta) const override;
  /// d k / d (log sigma, log block scales) into dk (size num_parameters()).
  void Gradient(const ConstVectorRef& a, const ConstVectorRef& b, VectorRef dk) const override;
  std::unique_ptr<Kernel> Clone() const override;

  /// The three terms of k(a, b) separately: the kernels of the physical components, e.g. for
  /// the component means k_b(x, X) (K + sigma_n^2 I)^{-1} y of the function-space model.
  /// Same cost as Evaluate.
  PolKernelTerms EvaluateTerms(const ConstVectorRef& a, const ConstVectorRef& b) const;

  /// The block names, "inertial", "coriolis" [, "gravity"], in parameter order.
  std::vector<std::string> block_names() const;

 private:
  // Sets the parameters of a kernel not yet shared (WithParameters' copy).
  void AssignParameters(const ConstVectorRef& theta);
  // Terms and, when d_log_sigma is not null, d (sum of terms) / d log sigma.
  PolKernelTerms Compute(const ConstVectorRef& a, const ConstVectorRef& b,
                         double* d_log_sigma) const;
  // Recomputes the constants that depend on the parameters only.
  void UpdateCache();

  int num_joints_;
  PolOptions options_;
  Vector parameters_;  // num_parameters()

  internal::PolConstants k_;  // cached from the parameters
};

}  // namespace structgp

#endif  // STRUCTGP_KERNEL_POL_KERNEL_H_
