#include "structgp/feature/rigid_body_torque_feature_map.h"

#include <memory>
#include <utility>

#include "per_thread_scratch.h"
#include "structgp/core/validate.h"

namespace structgp {
namespace {

struct ChainScratch {
  std::unique_ptr<RigidBodyChain::Workspace> workspace;
  Matrix regressor;
};

ChainScratch& LocalScratch(const RigidBodyChain& chain, std::uint64_t id) {
  return internal::PerThreadScratch<ChainScratch>(id, [&chain] {
    return ChainScratch{std::make_unique<RigidBodyChain::Workspace>(chain.MakeWorkspace()),
                        Matrix(chain.num_joints(), chain.num_parameters())};
  });
}

}  // namespace

RigidBodyTorqueFeatureMap::RigidBodyTorqueFeatureMap(RigidBodyChain chain)
    : chain_(std::move(chain)), id_(internal::NewScratchOwner()) {}

void RigidBodyTorqueFeatureMap::Evaluate(const ConstVectorRef& x, VectorRef phi) const {
  if (x.size() != input_dim()) {
    RequireSize("RigidBodyTorqueFeatureMap::Evaluate x", x.size(), input_dim());
  }
  if (phi.size() != dim()) RequireSize("RigidBodyTorqueFeatureMap::Evaluate phi", phi.size(), dim());
  const int n = chain_.num_joints();
  ChainScratch& local = LocalScratch(chain_, id_);
  const auto q = x.segment(0, n), qd = x.segment(n, n), qdd = x.segment(2 * n, n);
  const RigidBodyChain::Terms terms[3] = {RigidBodyChain::Terms::kInertial,
                                          RigidBodyChain::Terms::kCoriolis,
                                          RigidBodyChain::Terms::kGravity};
  for (int t = 0; t < 3; ++t) {
    chain_.Regressor(q, qd, qdd, terms[t], local.regressor, *local.workspace);
    phi.segment(t * n, n).noalias() = local.regressor * chain_.parameters();
  }
}

void RigidBodyTorqueFeatureMap::Torque(const ConstVectorRef& x, VectorRef tau) const {
  if (x.size() != input_dim()) RequireSize("RigidBodyTorqueFeatureMap::Torque x", x.size(), input_dim());
  const int n = chain_.num_joints();
  if (tau.size() != n) RequireSize("RigidBodyTorqueFeatureMap::Torque tau", tau.size(), n);
  ChainScratch& local = LocalScratch(chain_, id_);
  chain_.Regressor(x.segment(0, n), x.segment(n, n), x.segment(2 * n, n),
                   RigidBodyChain::Terms::kAll, local.regressor, *local.workspace);
  tau.noalias() = local.regressor * chain_.parameters();
}

std::vector<FeatureBlock> RigidBodyTorqueFeatureMap::blocks() const {
  const int n = chain_.num_joints();
  return {{"urdf inertial", 0, n}, {"urdf coriolis", n, n}, {"urdf gravity", 2 * n, n}};
}

}  // namespace structgp
