#include "structgp/feature/semi_parametric_regressor_map.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

#include "structgp/core/validate.h"

namespace structgp {
namespace {

// Largest number of bases of one effect, and of joints with friction (the stack buffers of an
// evaluation).
constexpr int kMaxEffectBases = 64;
constexpr int kMaxFrictionJoints = 64;

}  // namespace

SemiParametricRegressorMap::SemiParametricRegressorMap(std::shared_ptr<const RegressorMap> base,
                                                       SemiParametricOptions options)
    : base_(std::move(base)), options_(std::move(options)) {
  if (!base_) throw std::invalid_argument("SemiParametricRegressorMap: null base regressor");
  num_joints_ = base_->num_outputs();
  const int N = num_joints_;
  if (N < 1 || base_->input_dim() != 3 * N) {
    throw std::invalid_argument("SemiParametricRegressorMap: the base regressor must take the "
                                "state (3N inputs) of its N outputs, got " +
                                std::to_string(base_->input_dim()) + " inputs and " +
                                std::to_string(N) + " outputs");
  }
  if (options_.friction) {
    RequireInRange("SemiParametricOptions.friction_width", options_.friction_width, 0.0, 1e9);
    if (N > kMaxFrictionJoints) {
      throw std::invalid_argument("SemiParametricRegressorMap: friction for at most " +
                                  std::to_string(kMaxFrictionJoints) + " joints, got " +
                                  std::to_string(N));
    }
    // The paper's bases, one viscous, Coulomb and offset triple per joint (FrictionFeatureMap).
    friction_ = std::make_shared<const FrictionFeatureMap>(
        N, FrictionOptions{options_.friction_width, /*shared_offset=*/false});
  }
  const int P = base_->dim();
  names_ = base_->parameter_names();
  blocks_ = base_->blocks();
  num_base_blocks_ = static_cast<int>(blocks_.size());
  num_base_components_ = static_cast<int>(base_->component_names().size());
  const Vector base_mean = base_->prior_mean(), base_std = base_->prior_std();
  int column = P;
  if (friction_) {
    const int block = static_cast<int>(blocks_.size());
    const std::vector<std::string> friction_names = friction_->feature_names();
    for (int j = 0; j < N; ++j) {
      const FrictionIndices ix = friction_->indices(j);
      friction_indices_.push_back(ix);
      groups_.push_back(Group{j, -1, column, 3, block});
      for (int k : {ix.viscous, ix.coulomb, ix.offset}) {
        names_.push_back(friction_names[static_cast<size_t>(k)]);
      }
      column += 3;
    }
    blocks_.push_back(FeatureBlock{"friction", P, column - P});
  }
  for (size_t e = 0; e < options_.effects.size(); ++e) {
    const RegressorEffect& spec = options_.effects[e];
    if (!spec.effect) throw std::invalid_argument("SemiParametricRegressorMap: null effect");
    const Effect& effect = *spec.effect;
    const int k = effect.num_bases();
    if (k < 1 || k > kMaxEffectBases) {
      throw std::invalid_argument("SemiParametricRegressorMap: effect '" + effect.name() +
                                  "' has " + std::to_string(k) + " bases, expected 1.." +
                                  std::to_string(kMaxEffectBases));
    }
    if (effect.uses_time() && !options_.with_time) {
      throw std::invalid_argument("SemiParametricRegressorMap: effect '" + spec.name +
                                  "' uses the time: set SemiParametricOptions.with_time");
    }
    std::vector<int> joints = spec.joints;
    if (joints.empty()) {
      for (int j = 1; j <= N; ++j) joints.push_back(j);
    }
    const int block = static_cast<int>(blocks_.size());
    const int begin = column;
    const std::vector<std::string> bases = effect.basis_names();
    for (int j : joints) {
      if (j < 1 || j > N) {
        throw std::invalid_argument("effect '" + spec.name + "' names joint " + std::to_string(j) +
                                    ", but the robot has " + std::to_string(N) + " joints");
      }
      if (std::count(joints.begin(), joints.end(), j) > 1) {
        throw std::invalid_argument("effect '" + spec.name + "': joint " + std::to_string(j) +
                                    " listed twice");
      }
      groups_.push_back(Group{j - 1, static_cast<int>(e), column, k, block});
      for (const std::string& basis : bases) {
        names_.push_back((k == 1 ? effect.name() : effect.name() + "." + basis) + "@" +
                         std::to_string(j));
      }
      column += k;
    }
    blocks_.push_back(FeatureBlock{spec.name, begin, column - begin});
  }
  dim_ = column;
  mean_ = Vector::Zero(dim_);
  std_ = Vector::Ones(dim_);
  mean_.head(P) = base_mean;
  std_.head(P) = base_std;
}

void SemiParametricRegressorMap::EvaluateGroups(const ConstVectorRef& x, MatrixRef psi,
                                                int only_block) const {
  const int N = num_joints_;
  const double t = options_.with_time ? x[3 * N] : 0.0;
  double buffer[kMaxEffectBases];
  double friction[3 * kMaxFrictionJoints];
  if (friction_) friction_->Evaluate(x.head(3 * N), Eigen::Map<Vector>(friction, 3 * N));
  for (const Group& g : groups_) {
    if (only_block >= 0 && g.block != only_block) continue;
    const int j = g.row;
    if (g.effect < 0) {
      const FrictionIndices& ix = friction_indices_[static_cast<size_t>(j)];
      psi(j, g.begin) = friction[ix.viscous];
      psi(j, g.begin + 1) = friction[ix.coulomb];
      psi(j, g.begin + 2) = friction[ix.offset];
    } else {
      options_.effects[static_cast<size_t>(g.effect)].effect->Evaluate(x[j], x[N + j],
                                                                        x[2 * N + j], t, buffer);
      for (int i = 0; i < g.size; ++i) psi(j, g.begin + i) = buffer[i];
    }
  }
}

void SemiParametricRegressorMap::Evaluate(const ConstVectorRef& x, MatrixRef psi,
                                          Scratch* scratch) const {
  const int P = base_->dim();
  psi.rightCols(dim_ - P).setZero();
  base_->Evaluate(x.head(3 * num_joints_), psi.leftCols(P), scratch);
  EvaluateGroups(x, psi, -1);
}

std::vector<std::string> SemiParametricRegressorMap::component_names() const {
  std::vector<std::string> names = base_->component_names();
  for (size_t b = static_cast<size_t>(num_base_blocks_); b < blocks_.size(); ++b) {
    names.push_back(blocks_[b].name);
  }
  return names;
}

void SemiParametricRegressorMap::EvaluateComponent(int component, const ConstVectorRef& x,
                                                   MatrixRef psi, Scratch* scratch) const {
  const int num_components =
      num_base_components_ + static_cast<int>(blocks_.size()) - num_base_blocks_;
  if (component < 0 || component >= num_components) {
    throw std::invalid_argument("SemiParametricRegressorMap::EvaluateComponent: component " +
                                std::to_string(component) + " out of range [0, " +
                                std::to_string(num_components) + ")");
  }
  const int P = base_->dim();
  psi.setZero();
  if (component < num_base_components_) {
    base_->EvaluateComponent(component, x.head(3 * num_joints_), psi.leftCols(P), scratch);
    return;
  }
  EvaluateGroups(x, psi, component - num_base_components_ + num_base_blocks_);
}

}  // namespace structgp
