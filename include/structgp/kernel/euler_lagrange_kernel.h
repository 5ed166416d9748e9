#ifndef STRUCTGP_KERNEL_EULER_LAGRANGE_KERNEL_H_
#define STRUCTGP_KERNEL_EULER_LAGRANGE_KERNEL_H_

/// @file
/// The matrix-valued kernel of the joint torques of an N-joint serial chain of revolute joints
/// under a Gaussian-process prior on its Lagrangian, without kinematic parameters: the kernel
/// form of LagrangianRegressorMap, and the form for chains whose regressor is too large to be
/// explicit (6-7 joints).
///
/// Prior, per link L (1-based; 0-based in the code): the link's kinetic energy
/// 1/2 qd^T M^L(q) qd with independent entries M^L_jk (j <= k <= L) of covariance
///     Cov(M^L_jk(q), M^L_jk(q')) = w_kin,L prod_{j < l <= k} f_l prod_{k < l <= L} g_l,
/// g_l = f_l^2 (the angles between j and k turn only joint j's column of the link's Jacobian:
/// degree 1; those after k turn both: degree 2; LagrangianRegressorMap),
/// and its potential energy V^L(q) with Cov = w_pot,L prod_{l <= L} f_l, where
///     f_l = (1 + theta cos(q_l - q'_l)) / (1 + theta),   theta = 1 / (1 + sigma).
/// These are the spaces of a serial chain (link L's energy depends on qd_1..qd_L and on
/// q_2..q_L for its kinetic part, q_1..q_L for its potential part; docs/feature_maps.md
/// section 5a): f_l spans 1, cos q_l, sin q_l, and g_l the trigonometric polynomials of degree
/// 2. The torques are linear in the energies (Euler-Lagrange equations),
///     tau_i = sum_k M_ik qdd_k + sum_jk (d_k M_ij - 1/2 d_i M_jk) qd_j qd_k + d_i V,
/// so the torque kernel K(x, x') (N x N, K_ii' = Cov(tau_i(x), tau_i'(x'))) is the
/// Euler-Lagrange operator applied to both arguments of those covariances, summed over links:
///     K = sum_L (w_kin,L K^kin_L + w_pot,L K^pot_L).
/// One GP thus explains every joint, M is symmetric by construction, and link L's parts only
/// act on joints 1..L. With only link N weighted, K is the prior of one kinetic and one
/// potential energy for the whole chain.
///
/// Weight-space twin: LagrangianRegressorMap(N) with prior variances
/// LagrangianRegressorMap::KernelPriorVariance(sigma, weights) gives
/// Psi(x) diag(v) Psi(x')^T = K(x, x') exactly (tests/test_euler_lagrange_kernel.cc).
///
/// Input x = (q_1..q_N, qd_1..qd_N, qdd_1..qdd_N). Part weights are ordered kinetic 1..N,
/// then potential 1..N (part_names(): "kinetic L", "potential L", as the regressor's blocks).
/// Evaluation costs N cosines and O(N^4) flops per link, allocates nothing, keeps no scratch
/// (safe for concurrent readers).

#include <string>
#include <vector>

#include "structgp/core/types.h"

namespace structgp {

/// Largest number of joints of an EulerLagrangeKernel (its stack arrays).
inline constexpr int kMaxEulerLagrangeJoints = 32;

class EulerLagrangeKernel {
 public:
  /// Throws std::invalid_argument unless 1 <= num_joints <= kMaxEulerLagrangeJoints and
  /// sigma > 0 (finite).
  EulerLagrangeKernel(int num_joints, double sigma);

  int num_joints() const { return num_joints_; }
  int input_dim() const { return 3 * num_joints_; }
  double sigma() const { return sigma_; }
  double theta() const { return theta_; }

  /// 2N: the kinetic parts of links 1..N, then their potential parts.
  int num_parts() const { return 2 * num_joints_; }
  std::vector<std::string> part_names() const;

  /// Link `link`'s (0-based) parts at (a, b) with unit weights: kinetic and potential are
  /// N x N (rows and columns past `link` are zero). Sizes are preconditions (asserted).
  void EvaluateLink(const ConstVectorRef& a, const ConstVectorRef& b, int link,
                    MatrixRef kinetic, MatrixRef potential) const;

  /// K(a, b) = sum_p part_weights[p] part_p(a, b), N x N; part_weights has num_parts() entries.
  void Evaluate(const ConstVectorRef& a, const ConstVectorRef& b,
                const ConstVectorRef& part_weights, MatrixRef block) const;

 private:
  int num_joints_;
  double sigma_;
  double theta_;
};

}  // namespace structgp

#endif  // STRUCTGP_KERNEL_EULER_LAGRANGE_KERNEL_H_
