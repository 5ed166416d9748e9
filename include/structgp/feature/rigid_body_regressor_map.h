#ifndef STRUCTGP_FEATURE_RIGID_BODY_REGRESSOR_MAP_H_
#define STRUCTGP_FEATURE_RIGID_BODY_REGRESSOR_MAP_H_

/// @file
/// The regressor of the `rbd` models: the rigid-body regressor Y(q, qd, qdd) of a chain
/// (rigid_body/rigid_body_chain.h; 10 inertial parameters per link and one armature per
/// joint, shared by every joint's torque), then, when asked, the paper's friction per joint
/// (viscous qd_j, Coulomb tanh(qd_j / sigma_f), offset 1 in row j only) and effects (each
/// effect's bases for joint j in row j only):
///     tau = Y(x) pi + F(x) f + E(x) e.
/// Prior: pi centred on the chain's own values (the URDF's), so that with no data the model is
/// the URDF's inverse dynamics, with a standard deviation per parameter from the link's mass m
/// and size r (radius of gyration about the link origin, at least kMinLinkSize): m for the
/// mass, m r for first moments, m r^2 for inertias and the armature, times the block scale of
/// "rigid_body". Friction and effect coefficients: centred on zero, unit standard deviation
/// times their block's scale (a broad prior, as the paper adds friction).
///
/// Blocks: "rigid_body", "friction", then one per effect (its spec text). Components:
/// "inertial" M(q)qdd, "coriolis" C(q,qd)qd, "gravity" G(q) (the rigid-body columns split
/// by terms), "friction", then one per effect.

#include <memory>
#include <string>
#include <vector>

#include "structgp/feature/effect.h"
#include "structgp/feature/regressor_map.h"
#include "structgp/rigid_body/rigid_body_chain.h"

namespace structgp {

/// Smallest link size used for the prior scale of the first moments and inertias, m.
inline constexpr double kMinLinkSize = 0.05;

/// An effect on some joints of a regressor.
struct RegressorEffect {
  std::string name;                      ///< block and component name (the effect's spec text)
  std::shared_ptr<const Effect> effect;  ///< not null
  std::vector<int> joints;               ///< 1-based; empty: every joint
};

struct RigidBodyRegressorOptions {
  /// Add the friction columns.
  bool friction = false;
  /// sigma_f of the Coulomb basis, rad/s (> 0).
  double friction_width = 0.01;
  std::vector<RegressorEffect> effects;
  /// The input has the time t after the state (3N + 1 entries): set when an effect uses it.
  bool with_time = false;
};

class RigidBodyRegressorMap final : public RegressorMap {
 public:
  /// Throws std::invalid_argument on a bad friction width, a null effect, or an effect joint
  /// out of range or listed twice.
  RigidBodyRegressorMap(RigidBodyChain chain, RigidBodyRegressorOptions options = {});

  const RigidBodyChain& chain() const { return chain_; }
  const RigidBodyRegressorOptions& options() const { return options_; }
  int num_rigid_body_parameters() const { return chain_.num_parameters(); }

  int input_dim() const override { return 3 * num_joints_ + (options_.with_time ? 1 : 0); }
  int num_outputs() const override { return num_joints_; }
  int dim() const override { return dim_; }
  std::unique_ptr<Scratch> MakeScratch() const override;
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
  // Columns after the rigid-body ones, one group per joint and part, in order: the friction
  // triple of a joint, or the bases of an effect on a joint (all in row `row`).
  struct Group {
    int row;     // joint, 0-based
    int effect;  // index into options_.effects, -1 for friction
    int begin;   // first column
    int size;
    int block;   // index into blocks_
  };
  void EvaluateGroups(const ConstVectorRef& x, MatrixRef psi, int only_block) const;

  RigidBodyChain chain_;
  RigidBodyRegressorOptions options_;
  int num_joints_;
  int dim_;
  std::vector<FeatureBlock> blocks_;
  std::vector<std::string> names_;
  std::vector<Group> groups_;
  Vector mean_, std_;
};

}  // namespace structgp

#endif  // STRUCTGP_FEATURE_RIGID_BODY_REGRESSOR_MAP_H_
