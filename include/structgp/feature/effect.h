#ifndef STRUCTGP_FEATURE_EFFECT_H_
#define STRUCTGP_FEATURE_EFFECT_H_

/// @file
/// A physical effect that a rigid-body model may miss (friction, cogging, a spring, drift...),
/// written as a few basis functions of one joint's state. Added to a model with a broad prior,
/// exactly as the paper adds friction (eqs. 41-44): the structured kernel keeps the rigid-body
/// part, the effect's coefficients are fitted almost freely and reported as physical
/// parameters.
///
/// An effect is an object that knows its parameters (typed descriptions, EffectParameter),
/// proposes them from a residual (ProposeParameters, used by the diagnosis), describes itself
/// for a report (Describe) and says which feature blocks already span it (spanned_by).
///
/// To add an effect of your own, derive from Effect, then give it to EffectFeatureMap (and
/// from there to any model), or register it (RegisterEffect, feature/effects.h) so that effect
/// lists such as "myeffect@2:gain=3" can name it and the diagnosis tries it.
/// docs/effects.md has an example.

#include <memory>
#include <string>
#include <vector>

#include "structgp/feature/effect_parameter.h"
#include "structgp/feature/effect_residual.h"

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

  /// Descriptions of the parameters, in the order users see them; the same for every object
  /// of the type (and the same list the effect is registered with). Default: none.
  virtual std::vector<EffectParameter> parameter_info() const { return {}; }
  /// Values of every parameter of parameter_info(), by name: MakeEffect(name(), parameters())
  /// gives back an equal effect. Default: none.
  virtual EffectParameters parameters() const { return {}; }

  /// One phrase for a report: "Coulomb friction", "cogging (period 0.3 rad)". Default: name().
  virtual std::string Describe() const { return name(); }

  /// Names of feature blocks (FeatureBlock::name) that contain this effect on every joint: a
  /// model with one of these blocks already has the effect, and the diagnosis does not offer
  /// it (viscous, coulomb and offset: FrictionFeatureMap's block "friction", which "+fri"
  /// adds). Default: none.
  virtual std::vector<std::string> spanned_by() const { return {}; }

  /// Parameter sets worth trying on context.joint, from what the model leaves unexplained
  /// there; each as MakeEffect takes it (missing parameters at their defaults). The diagnosis
  /// scores every alternative by evidence and held-out error, like any candidate, and suggests
  /// the best, so a short list of alternatives is itself a choice by evidence; for a wider
  /// search use context.score. Empty: nothing to try on these data. Called on any object of
  /// the type (the diagnosis uses MakeEffectPrototype); must not depend on its parameters
  /// unless that is documented. Default: {{}} (the defaults), or {} when a parameter is
  /// required.
  virtual std::vector<EffectParameters> ProposeParameters(const ResidualContext& context) const;

  /// An independent copy.
  virtual std::unique_ptr<Effect> Clone() const = 0;
};

}  // namespace structgp

#endif  // STRUCTGP_FEATURE_EFFECT_H_
