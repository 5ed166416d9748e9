#ifndef STRUCTGP_FEATURE_EFFECT_RESIDUAL_H_
#define STRUCTGP_FEATURE_EFFECT_RESIDUAL_H_

/// @file
/// What an effect sees when it is asked to propose its own parameters from data
/// (Effect::ProposeParameters): the rows of one joint, the time, the residual that a refit of
/// the model leaves on that joint's torque, the search range of each parameter and a score
/// function for choices made by evidence. Filled in by the diagnosis (Diagnose); only core
/// types, so that effects (feature/) need nothing above them.

#include <functional>
#include <map>
#include <string>

#include "structgp/core/types.h"
#include "structgp/feature/effect_parameter.h"

namespace structgp {

struct ResidualContext {
  /// Gain in log evidence of the joint's torque, nats, when the effect with `params` (as
  /// MakeEffect takes them: missing ones at their defaults) is added on this joint to the
  /// model as it is; -infinity for parameters the effect rejects or that cannot be scored.
  /// Each call evaluates the effect on every row and solves against the model's factor:
  /// O(m k D + D^2 k) for k bases, D model features, m rows.
  using Score = std::function<double(const EffectParameters& params)>;

  /// All vectors of size m (t: m or 0). They are views: the data must outlive the context.
  ResidualContext(int joint_number, ConstVectorRef q_rows, ConstVectorRef qd_rows,
                  ConstVectorRef qdd_rows, ConstVectorRef t_rows, ConstVectorRef residual_rows)
      : joint(joint_number), q(q_rows), qd(qd_rows), qdd(qdd_rows), t(t_rows),
        residual(residual_rows) {}

  int joint;              ///< 1-based joint the effect would be added to
  ConstVectorRef q;       ///< the joint's position on every row, rad
  ConstVectorRef qd;      ///< velocity, rad/s
  ConstVectorRef qdd;     ///< acceleration, rad/s^2
  ConstVectorRef t;       ///< time of every row, s (rows in time order); empty when none
  ConstVectorRef residual;  ///< torque minus a refit of the model on these rows, N m
  /// Where to search each parameter, by name (EffectParameter::search, or the valid range,
  /// unless DiagnosisOptions::search_ranges says otherwise).
  std::map<std::string, ParameterRange> search_ranges;
  /// Empty when the caller offers no scoring.
  Score score;

  /// search_ranges[parameter], or the whole real line when it has no entry.
  ParameterRange SearchRange(const std::string& parameter) const {
    const auto it = search_ranges.find(parameter);
    return it == search_ranges.end() ? ParameterRange{} : it->second;
  }
};

}  // namespace structgp

#endif  // STRUCTGP_FEATURE_EFFECT_RESIDUAL_H_
