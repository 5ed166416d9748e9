#include "structgp/feature/rigid_body_regressor_map.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

#include "structgp/core/validate.h"

namespace structgp {
namespace {

// Largest number of bases of one effect (the stack buffer of an evaluation).
constexpr int kMaxEffectBases = 64;

class ChainScratch final : public RegressorMap::Scratch {
 public:
  explicit ChainScratch(RigidBodyChain::Workspace w) : workspace(std::move(w)) {}
  RigidBodyChain::Workspace workspace;
};

RigidBodyChain::Workspace& WorkspaceOf(RegressorMap::Scratch* scratch) {
  auto* chain = dynamic_cast<ChainScratch*>(scratch);
  if (chain == nullptr) {
    throw std::invalid_argument(
        "RigidBodyRegressorMap: the scratch was not made by this map's MakeScratch");
  }
  return chain->workspace;
}

}  // namespace

RigidBodyRegressorMap::RigidBodyRegressorMap(RigidBodyChain chain,
                                             RigidBodyRegressorOptions options)
    : chain_(std::move(chain)), options_(std::move(options)), num_joints_(chain_.num_joints()) {
  const int N = num_joints_;
  const int P = chain_.num_parameters();
  if (options_.friction) {
    RequireInRange("RigidBodyRegressorOptions.friction_width", options_.friction_width, 0.0, 1e9);
  }
  // The rigid-body prior: centred on the chain's values, scaled by each link's mass and size.
  const Vector pi = chain_.parameters();
  double mean_mass = 0.0;
  for (int k = 0; k < N; ++k) mean_mass += std::max(0.0, pi[10 * k]);
  mean_mass = mean_mass > 0.0 ? mean_mass / N : 1.0;
  std::vector<double> mean(pi.data(), pi.data() + P), std_dev(static_cast<size_t>(P));
  for (int k = 0; k < N; ++k) {
    const double m = pi[10 * k] > 0.0 ? pi[10 * k] : mean_mass;
    // Radius of gyration about the link origin: trace(I_origin) = 2 sum m r_i^2.
    const double trace = pi[10 * k + 4] + pi[10 * k + 7] + pi[10 * k + 9];
    const double r = std::max(kMinLinkSize, trace > 0.0 && pi[10 * k] > 0.0
                                                ? std::sqrt(trace / (2.0 * pi[10 * k]))
                                                : 0.0);
    std_dev[static_cast<size_t>(10 * k)] = m;
    for (int i = 1; i <= 3; ++i) std_dev[static_cast<size_t>(10 * k + i)] = m * r;
    for (int i = 4; i < 10; ++i) std_dev[static_cast<size_t>(10 * k + i)] = m * r * r;
    std_dev[static_cast<size_t>(10 * N + k)] = m * r * r;  // armature
  }
  names_ = chain_.parameter_names();
  blocks_.push_back(FeatureBlock{"rigid_body", 0, P});
  int column = P;
  if (options_.friction) {
    const int block = static_cast<int>(blocks_.size());
    for (int j = 0; j < N; ++j) {
      groups_.push_back(Group{j, -1, column, 3, block});
      for (const char* name : {"viscous@", "coulomb@", "offset@"}) {
        names_.push_back(name + std::to_string(j + 1));
      }
      column += 3;
    }
    blocks_.push_back(FeatureBlock{"friction", P, column - P});
  }
  for (size_t e = 0; e < options_.effects.size(); ++e) {
    const RegressorEffect& spec = options_.effects[e];
    if (!spec.effect) throw std::invalid_argument("RigidBodyRegressorMap: null effect");
    const Effect& effect = *spec.effect;
    const int k = effect.num_bases();
    if (k < 1 || k > kMaxEffectBases) {
      throw std::invalid_argument("RigidBodyRegressorMap: effect '" + effect.name() + "' has " +
                                  std::to_string(k) + " bases, expected 1.." +
                                  std::to_string(kMaxEffectBases));
    }
    if (effect.uses_time() && !options_.with_time) {
      throw std::invalid_argument("RigidBodyRegressorMap: effect '" + spec.name +
                                  "' uses the time: set RigidBodyRegressorOptions.with_time");
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
                                    ", but the chain has " + std::to_string(N) + " joints");
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
  mean.resize(static_cast<size_t>(dim_), 0.0);
  std_dev.resize(static_cast<size_t>(dim_), 1.0);
  mean_ = Eigen::Map<const Vector>(mean.data(), dim_);
  std_ = Eigen::Map<const Vector>(std_dev.data(), dim_);
}

std::unique_ptr<RegressorMap::Scratch> RigidBodyRegressorMap::MakeScratch() const {
  return std::make_unique<ChainScratch>(chain_.MakeWorkspace());
}

void RigidBodyRegressorMap::EvaluateGroups(const ConstVectorRef& x, MatrixRef psi,
                                           int only_block) const {
  const int N = num_joints_;
  const double t = options_.with_time ? x[3 * N] : 0.0;
  double buffer[kMaxEffectBases];
  for (const Group& g : groups_) {
    if (only_block >= 0 && g.block != only_block) continue;
    const int j = g.row;
    if (g.effect < 0) {
      psi(j, g.begin) = x[N + j];
      psi(j, g.begin + 1) = std::tanh(x[N + j] / options_.friction_width);
      psi(j, g.begin + 2) = 1.0;
    } else {
      options_.effects[static_cast<size_t>(g.effect)].effect->Evaluate(x[j], x[N + j],
                                                                        x[2 * N + j], t, buffer);
      for (int i = 0; i < g.size; ++i) psi(j, g.begin + i) = buffer[i];
    }
  }
}

void RigidBodyRegressorMap::Evaluate(const ConstVectorRef& x, MatrixRef psi,
                                     Scratch* scratch) const {
  const int N = num_joints_;
  const int P = chain_.num_parameters();
  psi.rightCols(dim_ - P).setZero();
  chain_.Regressor(x.segment(0, N), x.segment(N, N), x.segment(2 * N, N),
                   RigidBodyChain::Terms::kAll, psi.leftCols(P), WorkspaceOf(scratch));
  EvaluateGroups(x, psi, -1);
}

std::vector<std::string> RigidBodyRegressorMap::component_names() const {
  std::vector<std::string> names{"inertial", "coriolis", "gravity"};
  for (size_t b = 1; b < blocks_.size(); ++b) names.push_back(blocks_[b].name);
  return names;
}

void RigidBodyRegressorMap::EvaluateComponent(int component, const ConstVectorRef& x,
                                              MatrixRef psi, Scratch* scratch) const {
  const int num_components = static_cast<int>(blocks_.size()) + 2;
  if (component < 0 || component >= num_components) {
    throw std::invalid_argument("RigidBodyRegressorMap::EvaluateComponent: component " +
                                std::to_string(component) + " out of range [0, " +
                                std::to_string(num_components) + ")");
  }
  const int N = num_joints_;
  const int P = chain_.num_parameters();
  psi.setZero();
  if (component < 3) {
    static constexpr RigidBodyChain::Terms kTerms[] = {RigidBodyChain::Terms::kInertial,
                                                       RigidBodyChain::Terms::kCoriolis,
                                                       RigidBodyChain::Terms::kGravity};
    chain_.Regressor(x.segment(0, N), x.segment(N, N), x.segment(2 * N, N), kTerms[component],
                     psi.leftCols(P), WorkspaceOf(scratch));
    return;
  }
  EvaluateGroups(x, psi, component - 2);
}

}  // namespace structgp
