#ifndef STRUCTGP_FEATURE_LAGRANGIAN_REGRESSOR_MAP_H_
#define STRUCTGP_FEATURE_LAGRANGIAN_REGRESSOR_MAP_H_

/// @file
/// The Lagrangian regressor of an N-joint serial chain of revolute joints, without its
/// kinematics: the base of the `lag` models. The torques follow from a Lagrangian
///     L(q, qd) = 1/2 qd^T M(q) qd - V(q)
/// by the Euler-Lagrange equations,
///     tau_i = sum_k M_ik qdd_k + sum_jk (dM_ij/dq_k - 1/2 dM_jk/dq_i) qd_j qd_k + dV/dq_i,
/// with M(q) symmetric by construction and every entry, and V, linear in parameters theta shared
/// by all joints: one parameter vector explains every joint, and the Coriolis and centrifugal
/// torques, which slow motion hardly shows, follow from the same parameters as the inertia.
///
/// The spaces are those of a serial chain of revolute joints (facts of rigid-body mechanics):
/// M_jk (j <= k, 1-based) depends only on the joints after j: a link L's share is
/// J_j^T D J_k, with D its inertia in its own frame and J_j the column of its Jacobian for joint
/// j there, which turns with the angles j+1..L (degree 1 in each); J_k turns only with k+1..L.
/// So the angles j+1..k enter at degree 1 (basis 1, cos q, sin q) and the angles after k at
/// degree 2 (1, cos q, sin q, cos 2q, sin 2q): M_jk has 3^(k - j) 5^(N - k) basis functions; the
/// armature is part of M_jj's constant. V (gravity) is a trigonometric polynomial of degree 1 in
/// every angle: 3^N - 1 basis functions (the constant does not act). P = sum_{j <= k}
/// 3^(k - j) 5^(N - k) + 3^N - 1 = 3, 17, 84, 410, 2013, 9947, 49374 for N = 1..7
/// (LagrangianDimension; with degree 2 in every angle after j, 3, 19, 112, 666, 3953, 23189,
/// 134022); parameters are named like
/// "M1,2[cos q2 sin2 q3]" and "V[cos q1 sin q2]". Compare pol's 12, 133, 1151, 8830 features per
/// joint for N = 1..4, each joint with its own weights.
///
/// Blocks: "kinetic L" and "potential L" (L = 1..N) hold the terms of M and of V that only links
/// L..N can produce (a term that varies with q_l needs a link at or after l; any term of M_ab a
/// link at or after max(a, b)), each with its own prior scale, so that a light wrist is not
/// given the base's; the parameters are ordered by block. Unit prior standard deviations.
/// Components: "inertial" (M qdd), "coriolis" (the qd terms), "gravity" (dV/dq).

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "structgp/feature/regressor_map.h"

namespace structgp {

/// Largest number of joints of a LagrangianRegressorMap (its stack arrays).
inline constexpr int kMaxLagrangianJoints = 7;

/// Number of parameters of the Lagrangian regressor of N joints (1 <= N <= kMaxLagrangianJoints).
int LagrangianDimension(int num_joints);

class LagrangianRegressorMap final : public RegressorMap {
 public:
  /// Throws std::invalid_argument unless 1 <= num_joints <= kMaxLagrangianJoints.
  explicit LagrangianRegressorMap(int num_joints);

  int input_dim() const override { return 3 * num_joints_; }
  int num_outputs() const override { return num_joints_; }
  int dim() const override { return static_cast<int>(params_.size()); }
  int num_kinetic() const { return num_kinetic_; }
  using RegressorMap::Evaluate;
  void Evaluate(const ConstVectorRef& x, MatrixRef psi, Scratch* scratch) const override;
  std::vector<FeatureBlock> blocks() const override;
  std::vector<std::string> parameter_names() const override;
  std::vector<std::string> component_names() const override;
  void EvaluateComponent(int component, const ConstVectorRef& x, MatrixRef psi,
                         Scratch* scratch) const override;

  /// The prior variances (one per parameter) that make this regressor the weight-space form of
  /// EulerLagrangeKernel(num_joints, sigma) with the given part weights (kinetic 1..N, then
  /// potential 1..N; >= 0): Psi(x) diag(v) Psi(x')^T = K(x, x'). A parameter whose earliest
  /// link is L gets sum_{L' >= L} w_L' prod c, the product over its angles of the Fourier
  /// coefficients of link L''s factors: for g = f^2, (1 + theta^2/2, 2 theta, 2 theta,
  /// theta^2/2, theta^2/2) / (1 + theta)^2 for the bases 1, cos, sin, cos 2, sin 2; for f,
  /// (1, theta, theta) / (1 + theta). Throws std::invalid_argument on a bad size, a negative
  /// weight or sigma <= 0.
  Vector KernelPriorVariance(double sigma, const ConstVectorRef& part_weights) const;

 private:
  struct Param {
    int a = 0, b = 0;  // M_ab (a <= b, 0-based), or a = b = -1 for V
    std::array<std::int8_t, kMaxLagrangianJoints> index{};  // basis per angle (0: constant)
  };
  // parts: bit 0 inertial, bit 1 coriolis, bit 2 gravity.
  void Fill(const ConstVectorRef& x, MatrixRef psi, int parts) const;

  int num_joints_;
  int num_kinetic_ = 0;
  std::vector<Param> params_;
  std::vector<int> link_;  // per parameter: the earliest link (0-based) that can produce it
};

}  // namespace structgp

#endif  // STRUCTGP_FEATURE_LAGRANGIAN_REGRESSOR_MAP_H_
