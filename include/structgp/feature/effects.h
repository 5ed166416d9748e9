#ifndef STRUCTGP_FEATURE_EFFECTS_H_
#define STRUCTGP_FEATURE_EFFECTS_H_

/// @file
/// The built-in effects and the registry that turns a name and parameters into an Effect.
///
/// | name     | bases of joint j                                   | parameters (default)            |
/// |----------|----------------------------------------------------|---------------------------------|
/// | viscous  | qd                                                 | —                               |
/// | coulomb  | tanh(qd / width)                                   | width = 0.01 rad/s              |
/// | stribeck | exp(-(qd / velocity)^2) tanh(qd / width)           | velocity = 0.1, width = 0.01    |
/// | offset   | 1 (one constant for all joints)                    | —                               |
/// | cogging  | sin(2 pi k q / period), cos(2 pi k q / period), k = 1..harmonics | period (required), harmonics = 1 |
/// | spring   | q                                                  | —                               |
/// | drift    | s tanh(qd / width), s qd, s;  s = (t - t0) / span  | t0 = 0, span = 1 s, width = 0.01 |
///
/// drift models friction and offset that change slowly (linearly) over the log; it needs the
/// time column. cogging needs a period: the diagnosis estimates it from the residuals.

#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "structgp/feature/effect.h"

namespace structgp {

using EffectParameters = std::map<std::string, double>;

/// Builds an effect by name. Throws std::invalid_argument naming the problem for an unknown
/// name (listing the known ones), an unknown parameter (listing the accepted ones), a missing
/// required parameter or an out-of-range value.
std::unique_ptr<Effect> MakeEffect(const std::string& name, const EffectParameters& params = {});

/// Names of every registered effect, built-in ones first.
std::vector<std::string> EffectNames();

/// Adds a user effect to the registry (thread-unsafe; call at start-up). The factory receives
/// the parameters and must throw std::invalid_argument on bad ones. Throws if the name exists.
void RegisterEffect(const std::string& name,
                    std::function<std::unique_ptr<Effect>(const EffectParameters&)> factory);

}  // namespace structgp

#endif  // STRUCTGP_FEATURE_EFFECTS_H_
