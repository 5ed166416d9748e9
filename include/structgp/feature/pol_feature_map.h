#ifndef STRUCTGP_FEATURE_POL_FEATURE_MAP_H_
#define STRUCTGP_FEATURE_POL_FEATURE_MAP_H_

/// @file
/// The explicit feature map of the structured kernel k_pol (paper eq. 17), and of its
/// gravity-free variant (eq. 55). Derivation: docs/feature_maps.md.
///
/// Input x = (q_1..q_N, qd_1..qd_N, qdd_1..qdd_N) (rad, rad/s, rad/s^2), input_dim() = 3N.
/// With the per-joint trigonometric maps u(q) = (1, cos q, sin q) and
/// v(q) = (1, cos q, sin q, cos 2q, sin 2q) and their tensor products over the joints,
/// U_alpha(q) = prod_n u_{alpha_n}(q_n) (alpha in {0,1,2}^N) and
/// V_beta(q) = prod_n v_{beta_n}(q_n) (beta in {0..4}^N), the features are, in this order:
///
/// | block      | features                          | count            | prior variance            |
/// |------------|-----------------------------------|------------------|---------------------------|
/// | "inertial" | qdd_a V_beta, a = 1..N            | N 5^N            | c^2 w_beta / N            |
/// | "coriolis" | qd_a qd_b V_beta, a <= b          | N(N+1)/2 5^N     | theta c^2 w_beta m_ab/N^2 |
/// | "gravity"  | U_alpha, alpha != 0               | 3^N - 1          | c theta^#(alpha != 0)     |
///
/// where theta = 1 / (1 + sigma), c = c_psi = (1 + theta)^-N, m_ab = 1 if a = b else 2, and
/// w_beta = prod_n w_{beta_n} with per-joint weights (1 + theta^2/2, 2 theta, 2 theta,
/// theta^2/2, theta^2/2). Inside a block, index a (or the pair (a, b) in lexicographic order)
/// is the slow index and beta the fast one; beta and alpha are stored as base-5 / base-3
/// numbers with joint 1 the most significant digit. With these,
///     sum_k lambda_k phi_k(x) phi_k(x') = k_pol(x, x')     (exactly, up to rounding),
/// and dim() = (N + N(N+1)/2) 5^N + 3^N - 1, the bound (38) of the paper with equality.
///
/// One shape parameter, "log_sigma" = log sigma (default 0, i.e. sigma = 1, theta = 1/2). It
/// acts only through the prior variances: the features do not depend on sigma.

#include <string>
#include <vector>

#include "structgp/core/types.h"
#include "structgp/feature/feature_map.h"

namespace structgp {

/// Largest number of joints of the explicit pol map. D grows like 5^N N^2/2; at N = 7 it is
/// already 2.7 million features, one evaluation writes 22 MB.
inline constexpr int kMaxPolJoints = 7;

/// Options of PolFeatureMap.
struct PolOptions {
  /// When false, the "gravity" block is left out: the map of k~_pol (eq. 55), to be combined
  /// with a parametric gravity basis (GravityBasisFeatureMap).
  bool include_gravity = true;
};

/// phi(x) of k_pol. Immutable after construction; Evaluate is allocation-free and thread-safe.
class PolFeatureMap : public FeatureMap {
 public:
  /// Throws std::invalid_argument unless 1 <= num_joints <= kMaxPolJoints.
  explicit PolFeatureMap(int num_joints, const PolOptions& options = PolOptions());

  int num_joints() const { return num_joints_; }
  const PolOptions& options() const { return options_; }

  int input_dim() const override { return 3 * num_joints_; }
  int dim() const override { return dim_; }
  /// O(D) flops, 2N trigonometric calls. Throws std::invalid_argument on a size mismatch
  /// (x: 3N entries, phi: dim() entries), without allocating otherwise.
  void Evaluate(const ConstVectorRef& x, VectorRef phi) const override;

  /// "inertial", "coriolis" and, with include_gravity, "gravity".
  std::vector<FeatureBlock> blocks() const override;

  int num_shape_parameters() const override { return 1; }
  std::vector<std::string> shape_parameter_names() const override { return {"log_sigma"}; }
  /// (0): sigma = 1.
  Vector default_shape_parameters() const override { return Vector::Zero(1); }
  /// lambda(log sigma) as in the table above; jacobian (dim() x 1), when not null, receives
  /// d lambda / d log sigma in closed form.
  void PriorVariance(const ConstVectorRef& shape, VectorRef lambda,
                     Matrix* jacobian = nullptr) const override;

  /// Number of V products, 5^N (size of one inertial or Coriolis sub-block).
  int num_v() const { return num_v_; }
  /// Number of U products, 3^N (the gravity block holds 3^N - 1 of them).
  int num_u() const { return num_u_; }

 private:
  int num_joints_;
  PolOptions options_;
  int num_v_;
  int num_u_;
  int num_velocity_pairs_;  // N(N+1)/2
  int gravity_begin_;
  int dim_;
};

/// Number of features of PolFeatureMap(num_joints) with gravity: (N + N(N+1)/2) 5^N + 3^N - 1.
/// Valid for 1 <= num_joints <= kMaxPolJoints.
int PolFeatureDimension(int num_joints);

}  // namespace structgp

#endif  // STRUCTGP_FEATURE_POL_FEATURE_MAP_H_
