#ifndef STRUCTGP_FEATURE_EFFECTS_H_
#define STRUCTGP_FEATURE_EFFECTS_H_

/// @file
/// The built-in effects and the registry that turns a name and parameters into an Effect.
/// This table is the one list of built-in effects: the registry is filled from it, and the
/// diagnosis tries every registered effect unless told otherwise.
///
/// | name     | bases of joint j                                   | parameters (default)            |
/// |----------|----------------------------------------------------|---------------------------------|
/// | viscous  | qd                                                 | —                               |
/// | coulomb  | tanh(qd / width)                                   | width = 0.01 rad/s              |
/// | stribeck | exp(-(qd / velocity)^2) tanh(qd / width)           | velocity = 0.1, width = 0.01 rad/s |
/// | offset   | 1 (one constant for all joints)                    | —                               |
/// | cogging  | sin(2 pi k q / period), cos(2 pi k q / period), k = 1..harmonics | period rad (required), harmonics = 1 |
/// | spring   | q                                                  | —                               |
/// | drift    | s tanh(qd / width), s qd, s;  s = (t - t0) / span  | t0 = 0 s, span = 1 s, width = 0.01 rad/s |
///
/// drift models friction and offset that change slowly (linearly) over the log; it needs the
/// time column. Parameters estimated from data by ProposeParameters: cogging's period (the
/// sinusoid in q that best explains the residual, then alternatives within +-15%), Stribeck's
/// velocity (2%, 5%, 10%, 20% of the joint's largest speed), drift's t0 and span (the log's).
/// viscous, coulomb and offset are spanned by the "friction" block ("+fri").

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "structgp/feature/effect.h"
#include "structgp/feature/effect_parameter.h"

namespace structgp {

/// Builds an effect from its complete, checked parameter set (ResolveEffectParameters: every
/// declared parameter present and valid).
using EffectFactory = std::function<std::unique_ptr<Effect>(const EffectParameters&)>;

/// Builds an effect by name. Throws std::invalid_argument naming the problem for an unknown
/// name (listing the known ones), an unknown parameter (listing the accepted ones), a missing
/// required parameter or an invalid value ("effect 'cogging': parameter 'period' expected in
/// [1e-06, 1e+06] rad, got -1").
std::unique_ptr<Effect> MakeEffect(const std::string& name, const EffectParameters& params = {});

/// The effect with every parameter at its default, a required one at its example value: the
/// object on which the diagnosis calls ProposeParameters, spanned_by, uses_time. Throws
/// std::invalid_argument for an unknown name.
std::unique_ptr<Effect> MakeEffectPrototype(const std::string& name);

/// The parameter descriptions a registered effect was registered with. Throws
/// std::invalid_argument for an unknown name.
std::vector<EffectParameter> EffectParameterInfo(const std::string& name);

/// Names of every registered effect, built-in ones first (in the order of the table above).
std::vector<std::string> EffectNames();

/// Adds a user effect to the registry (thread-unsafe; call at start-up). `parameters`
/// describes its parameters (MakeEffect checks and completes them before calling `factory`).
/// Builds the prototype once and throws std::invalid_argument when the name is taken or not a
/// valid name (no spaces or "@:,;=+/"), a parameter description is invalid (bad name,
/// duplicate, default outside the valid range), or the prototype disagrees with the
/// registration (its name(), parameter_info() names or parameters() keys differ), since the
/// diagnosis's suggestions must parse back into the same effect.
void RegisterEffect(const std::string& name, std::vector<EffectParameter> parameters,
                    EffectFactory factory);

/// RegisterEffect for a class E with `static std::vector<EffectParameter> Parameters()` and a
/// constructor from a complete EffectParameters:  RegisterEffect<BumpEffect>("bump");
template <class E>
void RegisterEffect(const std::string& name) {
  RegisterEffect(name, E::Parameters(),
                 [](const EffectParameters& p) { return std::unique_ptr<Effect>(new E(p)); });
}

}  // namespace structgp

#endif  // STRUCTGP_FEATURE_EFFECTS_H_
