#ifndef STRUCTGP_KERNEL_RBF_KERNEL_H_
#define STRUCTGP_KERNEL_RBF_KERNEL_H_

/// @file
/// Squared-exponential ("rbf") kernels: the paper's rbf (eq. 30) on the raw input, and rbfs
/// (eq. 33), the rbf on the robot state with each joint angle q replaced by (cos q, sin q).
/// Both carry a signal variance, which the paper's form omits (sf = 1 recovers it; the
/// paper's width sigma is l^2 here).

#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "structgp/core/types.h"
#include "structgp/kernel/kernel.h"

namespace structgp {

/// k(a, b) = sf^2 exp(-r^2 / 2),  r^2 = sum_i (a_i - b_i)^2 / l_i^2,
/// with one length scale l for every input (isotropic) or one per input (ARD).
///
/// Parameters, in this order: log l (1 entry, or input_dim() entries with ARD), log sf.
/// Names: "log_length_scale" (isotropic) or "log_length_scale_<i>" with i = 1..input_dim()
/// (ARD), then "log_signal_std". Evaluate and Gradient never allocate.
class RbfKernel : public Kernel {
 public:
  /// input_dim >= 1; length_scale > 0 (the initial value of every length scale) and
  /// signal_std > 0, in the units of the input and of the output. Throws
  /// std::invalid_argument on bad values.
  explicit RbfKernel(int input_dim, bool ard = false, double length_scale = 1.0,
                     double signal_std = 1.0);

  int input_dim() const override { return input_dim_; }
  bool ard() const { return ard_; }
  double Evaluate(const ConstVectorRef& a, const ConstVectorRef& b) const override;

  int num_parameters() const override { return static_cast<int>(log_length_scale_.size()) + 1; }
  std::vector<std::string> parameter_names() const override;
  Vector parameters() const override;
  std::unique_ptr<Kernel> WithParameters(const ConstVectorRef& theta) const override;
  void Gradient(const ConstVectorRef& a, const ConstVectorRef& b, VectorRef dk) const override;
  std::unique_ptr<Kernel> Clone() const override;

  /// Length scale of every input (size input_dim(); all equal unless ARD).
  Vector length_scales() const;
  double signal_std() const { return std::exp(log_signal_std_); }

 protected:
  /// The first num_angles inputs are angles (radians): they enter through (cos, sin), i.e.
  /// with the chordal difference 2 sin((a_i - b_i) / 2) in place of a_i - b_i.
  RbfKernel(int input_dim, int num_angles, bool ard, double length_scale, double signal_std);

 private:
  // Sets the parameters of a kernel not yet shared (WithParameters' copy).
  void AssignParameters(const ConstVectorRef& theta);
  // Difference of input i as it enters r^2.
  double Difference(int i, double a, double b) const;
  void UpdateCache();

  int input_dim_;
  int num_angles_;
  bool ard_;
  Vector log_length_scale_;  // 1 or input_dim_
  double log_signal_std_;
  // Cached from the parameters: 1 / l_i^2 for every input (input_dim_), sf^2.
  Vector inverse_squared_length_;
  double signal_variance_ = 1.0;
};

/// rbfs (paper eq. 33): the rbf on z(x) = (cos q, sin q, qd, qdd) for a robot state
/// x = (q, qd, qdd) of N joints (input_dim 3N, angles in radians). Since
/// (cos a - cos b)^2 + (sin a - sin b)^2 = 4 sin^2((a - b) / 2), the angle terms are evaluated
/// in that form (accurate for close angles), and cos q_n and sin q_n share one length scale:
///     r^2 = sum_n 4 sin^2((q_n - q'_n) / 2) / l_qn^2 + sum_n (qd_n - qd'_n)^2 / l_qdn^2
///         + sum_n (qdd_n - qdd'_n)^2 / l_qddn^2.
/// With ARD there is one length scale per entry of x (3N), named "log_length_scale_q<n>",
/// "log_length_scale_qd<n>", "log_length_scale_qdd<n>" (n = 1..N); isotropic: one,
/// "log_length_scale". Then "log_signal_std".
class RbfsKernel : public RbfKernel {
 public:
  /// num_joints >= 1. Throws std::invalid_argument on bad values.
  explicit RbfsKernel(int num_joints, bool ard = false, double length_scale = 1.0,
                      double signal_std = 1.0);

  int num_joints() const { return num_joints_; }
  std::vector<std::string> parameter_names() const override;
  std::unique_ptr<Kernel> Clone() const override;

 private:
  int num_joints_;
};

}  // namespace structgp

#endif  // STRUCTGP_KERNEL_RBF_KERNEL_H_
