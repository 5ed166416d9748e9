#ifndef STRUCTGP_FEATURE_EFFECT_H_
#define STRUCTGP_FEATURE_EFFECT_H_

/// @file
/// A physical effect that a rigid-body model may miss (friction, cogging, a spring, drift...),
/// written as a few basis functions of one joint's state. Added to a model with a broad prior,
/// exactly as the paper adds friction (eqs. 41-44): the structured kernel keeps the rigid-body
/// part, the effect's coefficients are fitted almost freely and reported as physical
/// parameters.
///
/// To add an effect of your own, derive from Effect, then give it to EffectFeatureMap (and
/// from there to any model), or register it with RegisterEffect (feature/effects.h) so that
/// effect lists such as "myeffect@2:gain=3" can name it. docs/effects.md has an example.

#include <map>
#include <memory>
#include <string>
#include <vector>

namespace structgp {

class Effect {
 public:
  virtual ~Effect() = default;

  /// The name users write, lower case ("coulomb").
  virtual std::string name() const = 0;
  /// Number of basis functions per joint (>= 1).
  virtual int num_bases() const = 0;
  /// Names of the bases, size num_bases() (e.g. {"sin", "cos"}); used as "name.basis@j".
  /// Default: {name()} for one basis, else name() with ".1", ".2", ...
  virtual std::vector<std::string> basis_names() const;
  /// True when the bases need the time t in seconds (the data must have a `t` column).
  virtual bool uses_time() const { return false; }
  /// True when the bases do not depend on the joint (a constant): one copy serves all joints.
  virtual bool joint_independent() const { return false; }
  /// The bases of one joint at position q (rad), velocity qd (rad/s), acceleration qdd
  /// (rad/s^2) and time t (s) into out[0..num_bases()). Must not allocate; thread-safe.
  virtual void Evaluate(double q, double qd, double qdd, double t, double* out) const = 0;
  /// Parameters as name -> value (e.g. {"period", 0.3}), for reports and model files.
  virtual std::map<std::string, double> parameters() const { return {}; }
  /// An independent copy.
  virtual std::unique_ptr<Effect> Clone() const = 0;
};

}  // namespace structgp

#endif  // STRUCTGP_FEATURE_EFFECT_H_
