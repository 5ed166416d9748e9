#include "structgp/feature/effect_feature_map.h"

#include <algorithm>
#include <stdexcept>

#include "structgp/core/validate.h"

namespace structgp {

EffectFeatureMap::EffectFeatureMap(int num_joints, std::shared_ptr<const Effect> effect,
                                   std::vector<int> joints, bool with_time)
    : num_joints_(num_joints), effect_(std::move(effect)), joints_(std::move(joints)),
      with_time_(with_time) {
  if (!effect_) throw std::invalid_argument("EffectFeatureMap: null effect");
  if (num_joints_ < 1) {
    throw std::invalid_argument("EffectFeatureMap: num_joints must be >= 1, got " +
                                std::to_string(num_joints_));
  }
  if (effect_->num_bases() < 1) {
    throw std::invalid_argument("EffectFeatureMap: effect '" + effect_->name() +
                                "' has no basis functions");
  }
  with_time_ = with_time_ || effect_->uses_time();
  if (joints_.empty()) {
    for (int j = 1; j <= num_joints_; ++j) joints_.push_back(j);
  }
  for (size_t i = 0; i < joints_.size(); ++i) {
    if (joints_[i] < 1 || joints_[i] > num_joints_) {
      throw std::invalid_argument("effect '" + effect_->name() + "': joint " +
                                  std::to_string(joints_[i]) + " out of range 1.." +
                                  std::to_string(num_joints_));
    }
    if (std::count(joints_.begin(), joints_.end(), joints_[i]) > 1) {
      throw std::invalid_argument("effect '" + effect_->name() + "': joint " +
                                  std::to_string(joints_[i]) + " listed twice");
    }
  }
  if (effect_->joint_independent()) joints_.resize(1);
  dim_ = static_cast<int>(joints_.size()) * effect_->num_bases();
}

void EffectFeatureMap::Evaluate(const ConstVectorRef& x, VectorRef phi) const {
  if (x.size() != input_dim()) RequireSize("EffectFeatureMap::Evaluate x", x.size(), input_dim());
  if (phi.size() != dim_) RequireSize("EffectFeatureMap::Evaluate phi", phi.size(), dim_);
  const int N = num_joints_;
  const double t = with_time_ ? x[3 * N] : 0.0;
  const int k = effect_->num_bases();
  for (size_t i = 0; i < joints_.size(); ++i) {
    const int j = joints_[i] - 1;
    effect_->Evaluate(x[j], x[N + j], x[2 * N + j], t, phi.data() + i * k);
  }
}

std::vector<FeatureBlock> EffectFeatureMap::blocks() const {
  std::vector<FeatureBlock> blocks;
  const int k = effect_->num_bases();
  for (size_t i = 0; i < joints_.size(); ++i) {
    const std::string name = effect_->joint_independent()
                                 ? effect_->name()
                                 : effect_->name() + "@" + std::to_string(joints_[i]);
    blocks.push_back(FeatureBlock{name, static_cast<int>(i) * k, k});
  }
  return blocks;
}

std::vector<std::string> EffectFeatureMap::feature_names() const {
  std::vector<std::string> names;
  const auto bases = effect_->basis_names();
  for (int joint : joints_) {
    for (const auto& basis : bases) {
      std::string n = effect_->num_bases() == 1 ? effect_->name()
                                                : effect_->name() + "." + basis;
      if (!effect_->joint_independent()) n += "@" + std::to_string(joint);
      names.push_back(n);
    }
  }
  return names;
}

IgnoreTrailingInputs::IgnoreTrailingInputs(std::shared_ptr<const FeatureMap> map,
                                           int extra_inputs)
    : map_(std::move(map)), extra_(extra_inputs) {
  if (!map_) throw std::invalid_argument("IgnoreTrailingInputs: null map");
  if (extra_ < 0) throw std::invalid_argument("IgnoreTrailingInputs: negative extra inputs");
}

void IgnoreTrailingInputs::Evaluate(const ConstVectorRef& x, VectorRef phi) const {
  if (x.size() != input_dim()) {
    RequireSize("IgnoreTrailingInputs::Evaluate x", x.size(), input_dim());
  }
  map_->Evaluate(x.head(map_->input_dim()), phi);
}

}  // namespace structgp
