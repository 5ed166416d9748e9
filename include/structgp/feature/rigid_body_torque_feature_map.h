#ifndef STRUCTGP_FEATURE_RIGID_BODY_TORQUE_FEATURE_MAP_H_
#define STRUCTGP_FEATURE_RIGID_BODY_TORQUE_FEATURE_MAP_H_

/// @file
/// The torques of a known rigid-body model, term by term: phi(x) = (M(q) qdd, C(q, qd) qd,
/// G(q)) of a RigidBodyChain at its own inertial parameters (the URDF's), 3N values in three
/// blocks "urdf inertial", "urdf coriolis", "urdf gravity", and their sum (Torque).
///
/// RobotModel uses it as the fixed prior mean of `rbd+pol` (ModelSpec::rigid_body_features):
/// the base learns what the URDF model gets wrong. As a FeatureMap it serves any model that
/// wants the URDF's terms as features.
///
/// Cost: RigidBodyChain::Regressor evaluations (~70 us each at N = 7; three for Evaluate, one
/// for Torque) and N x 11N products. Both keep the chain's scratch per thread: the first call
/// on a thread allocates it, later calls on that thread do not.

#include <cstdint>
#include <vector>

#include "structgp/feature/feature_map.h"
#include "structgp/rigid_body/rigid_body_chain.h"

namespace structgp {

class RigidBodyTorqueFeatureMap final : public FeatureMap {
 public:
  explicit RigidBodyTorqueFeatureMap(RigidBodyChain chain);

  const RigidBodyChain& chain() const { return chain_; }
  int num_joints() const { return chain_.num_joints(); }
  int input_dim() const override { return 3 * chain_.num_joints(); }
  int dim() const override { return 3 * chain_.num_joints(); }
  /// (M(q) qdd, C(q, qd) qd, G(q)) at x = (q, qd, qdd). Throws std::invalid_argument on a
  /// wrong size.
  void Evaluate(const ConstVectorRef& x, VectorRef phi) const override;
  std::vector<FeatureBlock> blocks() const override;
  /// tau = M(q) qdd + C(q, qd) qd + G(q) (size N) at the state x (3N).
  void Torque(const ConstVectorRef& x, VectorRef tau) const;

 private:
  RigidBodyChain chain_;
  std::uint64_t id_;  // tells this map's per-thread scratch from another's
};

}  // namespace structgp

#endif  // STRUCTGP_FEATURE_RIGID_BODY_TORQUE_FEATURE_MAP_H_
