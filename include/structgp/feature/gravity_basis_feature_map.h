#ifndef STRUCTGP_FEATURE_GRAVITY_BASIS_FEATURE_MAP_H_
#define STRUCTGP_FEATURE_GRAVITY_BASIS_FEATURE_MAP_H_

/// @file
/// A parametric basis for the gravity torque G(q): the trigonometric products
/// U_alpha(q) = prod_n u_{alpha_n}(q_n), u(q) = (1, cos q, sin q), alpha in {0,1,2}^N, alpha != 0
/// (the "gravity" block of PolFeatureMap on its own). Combined with the gravity-free pol map
/// (PolOptions::include_gravity = false) it gives the model of eq. (55) of the paper.
///
/// Input x = (q, qd, qdd), input_dim() = 3N; only q is used. dim() = 3^N - 1; alpha is stored as
/// a base-3 number with joint 1 the most significant digit, alpha = 0 left out (a constant
/// belongs to an offset term, e.g. FrictionFeatureMap).

#include <string>
#include <vector>

#include "structgp/core/types.h"
#include "structgp/feature/feature_map.h"

namespace structgp {

/// Options of GravityBasisFeatureMap.
struct GravityBasisOptions {
  /// false (default): a broad parametric prior, unit prior variance for every feature (set its
  /// breadth with the block scale), no shape parameter.
  /// true: the prior of k_psi_sigma - c_psi (eq. 18), c_psi theta^#(alpha != 0), with shape
  /// parameter "log_sigma" exactly as in PolFeatureMap, so that the gravity-free pol map plus
  /// this map, at equal log_sigma, reproduce k_pol.
  bool pol_prior = false;
};

/// Immutable after construction; Evaluate is allocation-free and thread-safe.
class GravityBasisFeatureMap : public FeatureMap {
 public:
  /// Throws std::invalid_argument unless 1 <= num_joints <= kMaxGravityBasisJoints.
  explicit GravityBasisFeatureMap(int num_joints,
                                  const GravityBasisOptions& options = GravityBasisOptions());

  /// Largest supported number of joints (3^12 - 1 = 531440 features).
  static constexpr int kMaxGravityBasisJoints = 12;

  int num_joints() const { return num_joints_; }
  const GravityBasisOptions& options() const { return options_; }

  int input_dim() const override { return 3 * num_joints_; }
  int dim() const override { return dim_; }
  /// O(D) flops, 2N trigonometric calls. Throws std::invalid_argument on a size mismatch.
  void Evaluate(const ConstVectorRef& x, VectorRef phi) const override;
  /// One block, "gravity".
  std::vector<FeatureBlock> blocks() const override;

  int num_shape_parameters() const override { return options_.pol_prior ? 1 : 0; }
  std::vector<std::string> shape_parameter_names() const override;
  Vector default_shape_parameters() const override;
  void PriorVariance(const ConstVectorRef& shape, VectorRef lambda,
                     Matrix* jacobian = nullptr) const override;

  /// Name of feature k, e.g. "gravity[0,1,2]" for alpha = (0, 1, 2) (u_0 = 1, u_1 = cos,
  /// u_2 = sin of the joint angle).
  std::string feature_name(int k) const;

 private:
  int num_joints_;
  GravityBasisOptions options_;
  int dim_;
};

}  // namespace structgp

#endif  // STRUCTGP_FEATURE_GRAVITY_BASIS_FEATURE_MAP_H_
