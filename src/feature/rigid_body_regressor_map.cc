#include "structgp/feature/rigid_body_regressor_map.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

namespace structgp {
namespace {

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

RigidBodyRegressorMap::RigidBodyRegressorMap(RigidBodyChain chain) : chain_(std::move(chain)) {
  const int N = chain_.num_joints();
  const Vector pi = chain_.parameters();
  double mean_mass = 0.0;
  for (int k = 0; k < N; ++k) mean_mass += std::max(0.0, pi[10 * k]);
  mean_mass = mean_mass > 0.0 ? mean_mass / N : 1.0;
  std_.resize(chain_.num_parameters());
  for (int k = 0; k < N; ++k) {
    const double m = pi[10 * k] > 0.0 ? pi[10 * k] : mean_mass;
    // Radius of gyration about the link origin: trace(I_origin) = 2 sum m r_i^2.
    const double trace = pi[10 * k + 4] + pi[10 * k + 7] + pi[10 * k + 9];
    const double r = std::max(kMinLinkSize, trace > 0.0 && pi[10 * k] > 0.0
                                                ? std::sqrt(trace / (2.0 * pi[10 * k]))
                                                : 0.0);
    std_[10 * k] = m;
    for (int i = 1; i <= 3; ++i) std_[10 * k + i] = m * r;
    for (int i = 4; i < 10; ++i) std_[10 * k + i] = m * r * r;
    std_[10 * N + k] = m * r * r;  // armature
  }
}

std::unique_ptr<RegressorMap::Scratch> RigidBodyRegressorMap::MakeScratch() const {
  return std::make_unique<ChainScratch>(chain_.MakeWorkspace());
}

void RigidBodyRegressorMap::Evaluate(const ConstVectorRef& x, MatrixRef psi,
                                     Scratch* scratch) const {
  const int N = chain_.num_joints();
  chain_.Regressor(x.segment(0, N), x.segment(N, N), x.segment(2 * N, N),
                   RigidBodyChain::Terms::kAll, psi, WorkspaceOf(scratch));
}

std::vector<std::string> RigidBodyRegressorMap::component_names() const {
  return {"inertial", "coriolis", "gravity"};
}

void RigidBodyRegressorMap::EvaluateComponent(int component, const ConstVectorRef& x,
                                              MatrixRef psi, Scratch* scratch) const {
  static constexpr RigidBodyChain::Terms kTerms[] = {RigidBodyChain::Terms::kInertial,
                                                     RigidBodyChain::Terms::kCoriolis,
                                                     RigidBodyChain::Terms::kGravity};
  if (component < 0 || component >= 3) {
    throw std::invalid_argument("RigidBodyRegressorMap::EvaluateComponent: component " +
                                std::to_string(component) + " out of range [0, 3)");
  }
  const int N = chain_.num_joints();
  chain_.Regressor(x.segment(0, N), x.segment(N, N), x.segment(2 * N, N), kTerms[component], psi,
                   WorkspaceOf(scratch));
}

}  // namespace structgp
