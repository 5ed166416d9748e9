#ifndef STRUCTGP_FEATURE_RIGID_BODY_REGRESSOR_MAP_H_
#define STRUCTGP_FEATURE_RIGID_BODY_REGRESSOR_MAP_H_

/// @file
/// The rigid-body regressor of a URDF chain as a RegressorMap, the base of the `rbd` models:
/// Y(q, qd, qdd) (rigid_body/rigid_body_chain.h; 10 inertial parameters per link and one
/// armature per joint, shared by every joint's torque), tau = Y(x) pi.
/// Prior: pi centred on the chain's own values (the URDF's), so that with no data the model is
/// the URDF's inverse dynamics, with a standard deviation per parameter from the link's mass m
/// and size r (radius of gyration about the link origin, at least kMinLinkSize): m for the
/// mass, m r for first moments, m r^2 for inertias and the armature, times the block scale of
/// "rigid_body". Block: "rigid_body". Components: "inertial" M(q)qdd, "coriolis" C(q,qd)qd,
/// "gravity" G(q) (the columns split by terms). Friction and effects: SemiParametricRegressorMap.

#include <memory>
#include <string>
#include <vector>

#include "structgp/feature/regressor_map.h"
#include "structgp/rigid_body/rigid_body_chain.h"

namespace structgp {

/// Smallest link size used for the prior scale of the first moments and inertias, m.
inline constexpr double kMinLinkSize = 0.05;

class RigidBodyRegressorMap final : public RegressorMap {
 public:
  explicit RigidBodyRegressorMap(RigidBodyChain chain);

  const RigidBodyChain& chain() const { return chain_; }

  int input_dim() const override { return 3 * chain_.num_joints(); }
  int num_outputs() const override { return chain_.num_joints(); }
  int dim() const override { return chain_.num_parameters(); }
  std::unique_ptr<Scratch> MakeScratch() const override;
  using RegressorMap::Evaluate;
  void Evaluate(const ConstVectorRef& x, MatrixRef psi, Scratch* scratch) const override;
  std::vector<FeatureBlock> blocks() const override { return {{"rigid_body", 0, dim()}}; }
  std::vector<std::string> parameter_names() const override { return chain_.parameter_names(); }
  Vector prior_mean() const override { return chain_.parameters(); }
  Vector prior_std() const override { return std_; }
  std::vector<std::string> component_names() const override;
  void EvaluateComponent(int component, const ConstVectorRef& x, MatrixRef psi,
                         Scratch* scratch) const override;

 private:
  RigidBodyChain chain_;
  Vector std_;
};

}  // namespace structgp

#endif  // STRUCTGP_FEATURE_RIGID_BODY_REGRESSOR_MAP_H_
