#ifndef STRUCTGP_FEATURE_EFFECT_PARAMETER_H_
#define STRUCTGP_FEATURE_EFFECT_PARAMETER_H_

/// @file
/// The typed description of one parameter of an Effect ("period" of cogging: rad, required,
/// valid in [1e-06, 1e+06], searched in [0.02, 3] by the diagnosis). The registry
/// (feature/effects.h) checks what users write against it, fills in defaults, and words its
/// messages with it: "effect 'cogging': parameter 'period' expected in [1e-06, 1e+06] rad,
/// got -1".

#include <cmath>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace structgp {

/// Parameter values by name, as users write them ("cogging@3:period=0.3" gives
/// {"period", 0.3}) and as effects report them (Effect::parameters()).
using EffectParameters = std::map<std::string, double>;

/// A closed interval [min, max] of real values; an infinite end is open-ended.
struct ParameterRange {
  double min = -HUGE_VAL;
  double max = HUGE_VAL;
  bool Contains(double v) const { return v >= min && v <= max; }
};

struct EffectParameter {
  /// The name users write, lower case, no spaces or any of "@:,;=+/" ("period").
  std::string name;
  /// Unit of the value, as printed in messages ("rad", "rad/s", "s"; empty: a pure number).
  std::string unit;
  /// Value taken when the parameter is not given. For a required parameter: the example
  /// value shown in the "is required" message and given to the prototype effect on which the
  /// diagnosis calls ProposeParameters (MakeEffectPrototype).
  double default_value = 0.0;
  /// Valid values; anything outside is rejected with std::invalid_argument.
  ParameterRange valid;
  /// The user must give it (no meaningful default).
  bool required = false;
  /// Only whole numbers are valid (e.g. a number of harmonics).
  bool integer = false;
  /// Where an estimate from data should look (Effect::ProposeParameters reads it through
  /// ResidualContext::SearchRange); DiagnosisOptions::search_ranges overrides it. Unset: the
  /// valid range.
  std::optional<ParameterRange> search;
  /// One line for messages and documentation.
  std::string description;

  /// "in [1e-06, 1e+06] rad", ">= 1e-09 rad/s", "an integer in [1, 20]", "any finite s".
  std::string ExpectedText() const;
  /// Throws std::invalid_argument "effect '<effect>': parameter '<name>' expected <ExpectedText>,
  /// got <value>" unless value is finite, in the valid range and (if integer) whole.
  void Check(const std::string& effect, double value) const;
};

/// The complete parameter set of an effect: every parameter of `info`, given ones checked
/// (EffectParameter::Check), missing ones at their default. Throws std::invalid_argument on a
/// key not in `info` (listing the accepted ones) or a missing required parameter (with an
/// example, "e.g. cogging@1:period=0.5").
EffectParameters ResolveEffectParameters(const std::string& effect,
                                         const std::vector<EffectParameter>& info,
                                         const EffectParameters& given);

}  // namespace structgp

#endif  // STRUCTGP_FEATURE_EFFECT_PARAMETER_H_
