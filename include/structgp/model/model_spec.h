#ifndef STRUCTGP_MODEL_MODEL_SPEC_H_
#define STRUCTGP_MODEL_MODEL_SPEC_H_

/// @file
/// What a robot model is made of, parsed once from the text users write at the command line
/// ("pol+fri" and "coulomb@2,viscous,cogging@3:period=0.3") into typed values.
///
/// Model grammar:  ["rbd+"] base ["+fri"]   with base one of pol, rbf, rbfs, motor, rbd, lag, lagk;
///                 "rbd+" only before pol, rbf, rbfs or motor (a URDF's torques beside it).
/// Effect grammar: item ("," item)*,  item = name ["@" joints] [":" key "=" value (";" key "=" value)*]
///                 joints = j ("/" j)*  (1-based; no "@" means every joint)
/// e.g. "coulomb@2", "viscous", "cogging@3:period=0.3;harmonics=2", "stribeck@1/2:velocity=0.05".

#include <map>
#include <string>
#include <vector>

namespace structgp {

enum class BaseModel {
  kPol,    ///< the structured kernel k_pol (paper eq. 17)
  kRbf,    ///< squared-exponential kernel on (q, qd, qdd) (eq. 30)
  kRbfs,   ///< squared-exponential kernel on (cos q, sin q, qd, qdd) (eq. 33)
  kMotor,  ///< the linear motor model c1 qdd + c2 qd per joint (eq. 54)
  kRbd,    ///< the rigid-body regressor of a known chain (URDF), inertial parameters identified
  kLag,    ///< the Lagrangian regressor of a serial chain, kinematics unknown (one M(q), V(q))
  kLagk,   ///< one GP of all joints on the Euler-Lagrange kernel (a prior on each link's energies)
};

/// "pol", "rbf", "rbfs", "motor", "rbd", "lag", "lagk".
const char* ToString(BaseModel base);
/// Every base model, in the order above: the one list that parsers, messages and help texts
/// take their names from.
const std::vector<BaseModel>& BaseModels();
/// One line on what the base model is, for help texts ("the structured kernel k_pol ...").
const char* Describe(BaseModel base);

/// An effect as written: MakeEffect(name, params) builds it (feature/effects.h), checking the
/// parameters against the effect's typed descriptions (EffectParameter) and filling in the
/// defaults; ToString(EffectSpec) is text that parses back into the same spec.
struct EffectSpec {
  std::string name;                      ///< as in EffectNames()
  std::vector<int> joints;               ///< 1-based; empty = every joint
  std::map<std::string, double> params;  ///< as written, e.g. {"period", 0.3}
};

struct ModelSpec {
  BaseModel base = BaseModel::kPol;
  /// The paper's semi-parametric friction (eq. 41): viscous, Coulomb and offset bases.
  bool friction = false;
  /// "rbd+pol" (or rbd+rbf, rbd+rbfs, rbd+motor): the torques of a known chain (URDF) as
  /// features beside the base, with a broad prior (feature/rigid_body_torque_feature_map.h).
  bool rigid_body_features = false;
  std::vector<EffectSpec> effects;
};

/// Parses "pol", "pol+fri", ... Throws std::invalid_argument naming the bad part and listing
/// what is accepted.
ModelSpec ParseModelSpec(const std::string& model);
/// Parses an effect list. Effect names are checked against the registry, parameters against
/// the effect's parameter descriptions (MakeEffect). Errors name the item and its character
/// position (1-based), e.g. "effect list 'cogging@1:period=-1', character 1: effect 'cogging':
/// parameter 'period' expected in [1e-06, 1e+06] rad, got -1".
std::vector<EffectSpec> ParseEffectList(const std::string& text);

/// A model with its effects in one text, as ModelLabel writes it: "pol+fri + coulomb@2,viscous@1",
/// "pol+coulomb@2", "lag+fri+cogging@1:period=0.3". The base and "+fri" as ParseModelSpec
/// reads them, then, after the next '+', the rest as one effect list (ParseEffectList; an
/// effect name never contains '+', so the effect list may hold numbers such as 1e+3). Throws
/// std::invalid_argument as the two parsers do.
ModelSpec ParseModelLabel(const std::string& text);
/// "pol+fri", or "pol+fri + coulomb@2,viscous@1" with effects; ParseModelLabel reads it back.
std::string ModelLabel(const ModelSpec& spec);

/// Canonical text of a model ("pol+fri") and of an effect list (round-trips through the
/// parsers).
std::string ToString(const ModelSpec& spec);
std::string ToString(const std::vector<EffectSpec>& effects);
std::string ToString(const EffectSpec& effect);

}  // namespace structgp

#endif  // STRUCTGP_MODEL_MODEL_SPEC_H_
