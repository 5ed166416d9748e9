#ifndef STRUCTGP_KERNEL_POL_CHAIN_KERNEL_H_
#define STRUCTGP_KERNEL_POL_CHAIN_KERNEL_H_

/// @file
/// k_pol restricted to what a serial chain of revolute joints on a fixed base can produce on
/// one joint's torque: the kernel of one output joint J, without kinematic parameters.
///
/// The facts used (docs/generalisation.md): M_jk(q) depends only on q_l for l > min(j, k)
/// (the kinetic energy is unchanged when the links up to min(j, k) turn together), so torque J's
/// inertial term M_Jk qdd_k depends on q_{min(J,k)+1..N}, and its Coriolis term in qd_k qd_l
/// (Christoffel symbols, derivatives of M) on q_{min(J,k,l)+1..N}; every entry is of degree
/// <= 2 in each cos q, sin q. The gravity term is k_pol's (it may depend on every angle).
///
/// Input x = (q_1..q_N, qd_1..qd_N, qdd_1..qdd_N), input_dim() = 3N. With theta = 1/(1+sigma),
/// f_l = (1 + theta cos(q_l - q'_l)) / (1 + theta), S_m = prod_{l >= m} f_l^2 (S_{N+1} = 1),
/// a_k = qd_k qd'_k, b_k = qdd_k qdd'_k (1-based joints):
///
///     k_J(x, x') = s_I^2 (1/N) sum_k b_k S_{min(J,k)+1}                               inertial
///                + s_C^2 (theta/N^2) sum_k sum_l a_k a_l S_{min(J,k,l)+1}             coriolis
///                + s_G^2 (prod_l f_l - (1 + theta)^-N)                                gravity
///
/// Each term is a sum of products of positive definite kernels, so k_J is positive
/// semi-definite; its span is the part of k_pol's span (eq. 17) that a chain can produce on
/// joint J: the Coriolis and inertial terms lose every function of the proximal angles they
/// cannot depend on (q_1 always; for the last joint, all but the angles distal to each
/// acceleration). At x = x' each term equals k_pol's term with the same parameters.
///
/// Parameters, as PolFormulaKernel's: "log_sigma", "log_scale_inertial",
/// "log_scale_coriolis", "log_scale_gravity" (all 0 by default). Evaluate and Gradient cost N
/// cosines and O(N) flops, allocate nothing and keep no scratch (safe for concurrent readers).

#include <memory>
#include <string>
#include <vector>

#include "structgp/core/types.h"
#include "structgp/internal/pol_constants.h"
#include "structgp/kernel/kernel.h"
#include "structgp/kernel/pol_kernel.h"

namespace structgp {

class PolChainKernel : public Kernel {
 public:
  static constexpr int kLogSigma = 0;
  static constexpr int kLogScaleInertial = 1;
  static constexpr int kLogScaleCoriolis = 2;
  static constexpr int kLogScaleGravity = 3;

  /// num_joints >= 1 and output_joint in [1, num_joints] (1-based, as at the command line).
  /// Throws std::invalid_argument otherwise.
  PolChainKernel(int num_joints, int output_joint);

  int num_joints() const { return num_joints_; }
  int output_joint() const { return output_joint_; }

  int input_dim() const override { return 3 * num_joints_; }
  double Evaluate(const ConstVectorRef& a, const ConstVectorRef& b) const override;
  int num_parameters() const override { return 4; }
  std::vector<std::string> parameter_names() const override;
  Vector parameters() const override { return parameters_; }
  std::unique_ptr<Kernel> WithParameters(const ConstVectorRef& theta) const override;
  void Gradient(const ConstVectorRef& a, const ConstVectorRef& b, VectorRef dk) const override;
  std::unique_ptr<Kernel> Clone() const override;

  /// The three terms separately, block scales applied (their sum is Evaluate).
  PolKernelTerms EvaluateTerms(const ConstVectorRef& a, const ConstVectorRef& b) const;

 private:
  PolKernelTerms Compute(const ConstVectorRef& a, const ConstVectorRef& b,
                         double* d_log_sigma) const;
  void UpdateCache();

  int num_joints_;
  int output_joint_;  // 1-based
  Vector parameters_;
  internal::PolConstants k_;  // cached from the parameters
};

}  // namespace structgp

#endif  // STRUCTGP_KERNEL_POL_CHAIN_KERNEL_H_
