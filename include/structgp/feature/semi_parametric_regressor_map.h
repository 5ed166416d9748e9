#ifndef STRUCTGP_FEATURE_SEMI_PARAMETRIC_REGRESSOR_MAP_H_
#define STRUCTGP_FEATURE_SEMI_PARAMETRIC_REGRESSOR_MAP_H_

/// @file
/// A regressor of the robot's whole dynamics (RegressorMap, N x P) from a base regressor of
/// its rigid-body part (the URDF chain's, RigidBodyRegressorMap; or the Lagrangian one,
/// LagrangianRegressorMap) and, when asked, the paper's friction per joint (viscous qd_j,
/// Coulomb tanh(qd_j / sigma_f), offset 1, in row j only) and effects (each effect's bases for
/// joint j in row j only):
///     tau = Y(x) theta + F(x) f + E(x) e.
/// The base keeps its own prior (mean and standard deviations); friction and effect
/// coefficients are centred on zero with unit standard deviation times their block's scale (a
/// broad prior, as the paper adds friction).
///
/// Blocks: the base's, then "friction", then one per effect (its spec text). Components: the
/// base's ("inertial", "coriolis", "gravity"), then "friction", then one per effect.

#include <memory>
#include <string>
#include <vector>

#include "structgp/feature/effect.h"
#include "structgp/feature/friction_feature_map.h"
#include "structgp/feature/regressor_map.h"

namespace structgp {

/// An effect on some joints of a regressor.
struct RegressorEffect {
  std::string name;                      ///< block and component name (the effect's spec text)
  std::shared_ptr<const Effect> effect;  ///< not null
  std::vector<int> joints;               ///< 1-based; empty: every joint
};

struct SemiParametricOptions {
  /// Add the friction columns.
  bool friction = false;
  /// sigma_f of the Coulomb basis, rad/s (> 0).
  double friction_width = 0.01;
  std::vector<RegressorEffect> effects;
  /// The input has the time t after the state (3N + 1 entries): set when an effect uses it.
  bool with_time = false;
};

class SemiParametricRegressorMap final : public RegressorMap {
 public:
  /// base: a regressor of the state (q, qd, qdd) of N joints (input_dim 3N, N outputs).
  /// Throws std::invalid_argument on a null or ill-shaped base, a bad friction width, a null
  /// effect, an effect joint out of range or listed twice, or a time effect without with_time.
  SemiParametricRegressorMap(std::shared_ptr<const RegressorMap> base,
                             SemiParametricOptions options = {});

  const RegressorMap& base() const { return *base_; }
  const std::shared_ptr<const RegressorMap>& base_ptr() const { return base_; }
  const SemiParametricOptions& options() const { return options_; }

  int input_dim() const override { return 3 * num_joints_ + (options_.with_time ? 1 : 0); }
  int num_outputs() const override { return num_joints_; }
  int dim() const override { return dim_; }
  std::unique_ptr<Scratch> MakeScratch() const override { return base_->MakeScratch(); }
  using RegressorMap::Evaluate;
  void Evaluate(const ConstVectorRef& x, MatrixRef psi, Scratch* scratch) const override;
  std::vector<FeatureBlock> blocks() const override { return blocks_; }
  std::vector<std::string> parameter_names() const override { return names_; }
  Vector prior_mean() const override { return mean_; }
  Vector prior_std() const override { return std_; }
  std::vector<std::string> component_names() const override;
  void EvaluateComponent(int component, const ConstVectorRef& x, MatrixRef psi,
                         Scratch* scratch) const override;

 private:
  // Columns after the base's, one group per joint and part, in order: the friction triple of a
  // joint, or the bases of an effect on a joint (all in row `row`).
  struct Group {
    int row;     // joint, 0-based
    int effect;  // index into options_.effects, -1 for friction
    int begin;   // first column
    int size;
    int block;   // index into blocks_
  };
  void EvaluateGroups(const ConstVectorRef& x, MatrixRef psi, int only_block) const;

  std::shared_ptr<const RegressorMap> base_;
  SemiParametricOptions options_;
  std::shared_ptr<const FrictionFeatureMap> friction_;  // null without friction
  std::vector<FrictionIndices> friction_indices_;        // per joint, into friction_'s phi
  int num_joints_;
  int num_base_components_;
  int num_base_blocks_;
  int dim_;
  std::vector<FeatureBlock> blocks_;
  std::vector<std::string> names_;
  std::vector<Group> groups_;
  Vector mean_, std_;
};

}  // namespace structgp

#endif  // STRUCTGP_FEATURE_SEMI_PARAMETRIC_REGRESSOR_MAP_H_
