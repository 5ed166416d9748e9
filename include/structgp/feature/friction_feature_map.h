#ifndef STRUCTGP_FEATURE_FRICTION_FEATURE_MAP_H_
#define STRUCTGP_FEATURE_FRICTION_FEATURE_MAP_H_

/// @file
/// The friction bases of the semi-parametric model (paper eqs. 41-42): for every joint n,
/// viscous friction qd_n, Coulomb friction tanh(qd_n / sigma_f) and a constant offset.
///
/// Input x = (q, qd, qdd), input_dim() = 3N; only qd is used. The features, in order, are
///     viscous@1, coulomb@1, viscous@2, coulomb@2, ..., viscous@N, coulomb@N, offset
/// with the default shared offset, or, with FrictionOptions::shared_offset = false,
///     viscous@1, coulomb@1, offset@1, ..., viscous@N, coulomb@N, offset@N
/// (names are 1-based, as everywhere a user sees a joint). One block, "friction".
///
/// Prior: unit variance for every feature and no shape parameter. The broad prior of the
/// semi-parametric sum (eqs. 43-44, k = (1-delta)^-1 k_dyn + delta^-1 k_fri) is set with the
/// block scale of "friction"; the fitted weights are then the friction coefficients b_j of
/// eq. (47). sigma_f is a constructor constant, not a shape parameter, because changing it
/// changes the features (shape parameters may act only through the prior).
///
/// Why one shared offset by default: in a model whose outputs (the N joint torques) share one
/// feature vector, N per-joint constant features are N identical columns; only their sum is
/// identified and the posterior splits it equally among them. With one constant the offset of
/// joint j is simply the weight of "offset" for output j (see indices()).

#include <string>
#include <vector>

#include "structgp/core/types.h"
#include "structgp/feature/feature_map.h"

namespace structgp {

/// Options of FrictionFeatureMap.
struct FrictionOptions {
  /// Velocity scale of the Coulomb term tanh(qd / sigma_f), rad/s; must be > 0.
  double sigma_f = 0.01;
  /// One constant feature "offset" (default) instead of one "offset@n" per joint.
  bool shared_offset = true;
};

/// Positions of the friction coefficients of one joint in phi (0-based feature indices).
struct FrictionIndices {
  int viscous = -1;  ///< qd_n
  int coulomb = -1;  ///< tanh(qd_n / sigma_f)
  int offset = -1;   ///< the constant (the same index for every joint with a shared offset)
};

/// Immutable after construction; Evaluate is allocation-free and thread-safe.
class FrictionFeatureMap : public FeatureMap {
 public:
  /// Name of the one block (effects spanned by it name it in Effect::spanned_by).
  static constexpr const char* kBlockName = "friction";

  /// Throws std::invalid_argument unless num_joints >= 1 and sigma_f is finite and > 0.
  FrictionFeatureMap(int num_joints, const FrictionOptions& options);
  /// Shorthand for FrictionOptions{sigma_f, true}.
  FrictionFeatureMap(int num_joints, double sigma_f);

  int num_joints() const { return num_joints_; }
  double sigma_f() const { return options_.sigma_f; }
  const FrictionOptions& options() const { return options_; }

  int input_dim() const override { return 3 * num_joints_; }
  /// 2N + 1 with a shared offset, 3N otherwise.
  int dim() const override { return dim_; }
  /// N tanh calls. Throws std::invalid_argument on a size mismatch.
  void Evaluate(const ConstVectorRef& x, VectorRef phi) const override;
  /// One block, "friction".
  std::vector<FeatureBlock> blocks() const override;

  /// Where the coefficients of joint `joint` (0-based) are. Throws on a bad joint index.
  FrictionIndices indices(int joint) const;
  /// "viscous@1", "coulomb@1", ..., "offset" (or "offset@n"), in feature order.
  std::vector<std::string> feature_names() const;

 private:
  int num_joints_;
  FrictionOptions options_;
  int dim_;
};

}  // namespace structgp

#endif  // STRUCTGP_FEATURE_FRICTION_FEATURE_MAP_H_
