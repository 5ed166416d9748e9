#ifndef STRUCTGP_FEATURE_EFFECT_FEATURE_MAP_H_
#define STRUCTGP_FEATURE_EFFECT_FEATURE_MAP_H_

/// @file
/// The feature map of one Effect applied to a set of joints.
///
/// Input: x = (q, qd, qdd) of N joints (input_dim 3N), or (q, qd, qdd, t) (input_dim 3N + 1)
/// when the effect uses time. Features: the effect's bases for each listed joint in order,
/// named "<name>@<j>" (one basis) or "<name>.<basis>@<j>" (j 1-based); a joint-independent
/// effect has one copy named "<name>". One block per joint, named "<name>@<j>" (or "<name>"),
/// so each joint's effect has its own prior scale. Prior: unit variance; no shape parameter.

#include <memory>
#include <string>
#include <vector>

#include "structgp/feature/effect.h"
#include "structgp/feature/feature_map.h"

namespace structgp {

class EffectFeatureMap : public FeatureMap {
 public:
  /// joints: 1-based joint numbers; empty means all N. with_time: input has a trailing t
  /// (forced when the effect uses time). Throws std::invalid_argument on a bad joint number,
  /// a duplicate joint or a null effect.
  EffectFeatureMap(int num_joints, std::shared_ptr<const Effect> effect,
                   std::vector<int> joints = {}, bool with_time = false);

  int input_dim() const override { return 3 * num_joints_ + (with_time_ ? 1 : 0); }
  int dim() const override { return dim_; }
  /// Allocation-free and thread-safe (as Effect::Evaluate); throws std::invalid_argument on a
  /// size mismatch.
  void Evaluate(const ConstVectorRef& x, VectorRef phi) const override;
  std::vector<FeatureBlock> blocks() const override;

  const Effect& effect() const { return *effect_; }
  /// The 1-based joints the effect is applied to.
  const std::vector<int>& joints() const { return joints_; }
  std::vector<std::string> feature_names() const;

 private:
  int num_joints_;
  std::shared_ptr<const Effect> effect_;
  std::vector<int> joints_;
  bool with_time_;
  int dim_;
};

/// A feature map that takes extra trailing inputs and ignores them: lets maps of the state
/// (input 3N) be summed with maps that also read the time (input 3N + 1).
class IgnoreTrailingInputs : public FeatureMap {
 public:
  IgnoreTrailingInputs(std::shared_ptr<const FeatureMap> map, int extra_inputs);

  int input_dim() const override { return map_->input_dim() + extra_; }
  int dim() const override { return map_->dim(); }
  void Evaluate(const ConstVectorRef& x, VectorRef phi) const override;
  std::vector<FeatureBlock> blocks() const override { return map_->blocks(); }
  int num_shape_parameters() const override { return map_->num_shape_parameters(); }
  std::vector<std::string> shape_parameter_names() const override {
    return map_->shape_parameter_names();
  }
  Vector default_shape_parameters() const override { return map_->default_shape_parameters(); }
  void PriorVariance(const ConstVectorRef& shape, VectorRef lambda,
                     Matrix* jacobian = nullptr) const override {
    map_->PriorVariance(shape, lambda, jacobian);
  }
  const FeatureMap& inner() const { return *map_; }

 private:
  std::shared_ptr<const FeatureMap> map_;
  int extra_;
};

}  // namespace structgp

#endif  // STRUCTGP_FEATURE_EFFECT_FEATURE_MAP_H_
