#ifndef STRUCTGP_SIM_HIDDEN_EFFECT_H_
#define STRUCTGP_SIM_HIDDEN_EFFECT_H_

/// @file
/// Data with a hidden physical effect, in the paper's extrapolation setting: train on a slow
/// trajectory, test on a fast one (the same path traversed `fast_speed / slow_speed` times
/// faster). The rigid-body torques come from KDL; one effect is added on one joint:
///
/// | effect   | hidden torque on joint j (times magnitude * torque scale of j)         |
/// |----------|-------------------------------------------------------------------------|
/// | coulomb  | tanh(qd / 0.01)                                                         |
/// | viscous  | qd / max |qd| (over both logs)                                          |
/// | stribeck | exp(-(qd / v_s)^2) tanh(qd / 0.01), v_s = 0.1 max |qd|                  |
/// | cogging  | sin(2 pi q / period)                                                    |
/// | drift    | (t / t_end) tanh(qd / 0.01): Coulomb friction growing over the log      |
/// | spring   | sin(q): a sinusoidal spring, which pol spans (a control: not missing)   |
/// | none     | nothing (the clean control)                                             |
///
/// Torques are divided per joint by the largest rigid-body torque over both logs, so the
/// effect's size and the noise are relative to it. Time runs on from train to test.

#include <cstdint>
#include <string>

#include "structgp/sim/dataset.h"
#include "structgp/sim/robot.h"

namespace structgp {
namespace sim {

enum class HiddenEffect { kNone, kCoulomb, kViscous, kStribeck, kCogging, kDrift, kSpring };

/// "none", "coulomb", "viscous", "stribeck", "cogging", "drift", "spring".
const char* ToString(HiddenEffect effect);
/// Inverse of ToString; throws std::invalid_argument listing the accepted names.
HiddenEffect ParseHiddenEffect(const std::string& name);

struct HiddenEffectOptions {
  HiddenEffect effect = HiddenEffect::kCoulomb;
  int joint = 1;               ///< 1-based
  double magnitude = 0.1;      ///< amplitude, relative to the joint's torque scale
  double cogging_period = 0.3; ///< rad
  double noise_std = 0.01;     ///< relative to each joint's torque scale
  double train_duration = 40.0;  ///< s
  double test_duration = 10.0;   ///< s
  double dt = 0.01;              ///< s
  int num_vias = 8;
  double q_range = 1.2;          ///< rad
  double slow_speed = 1.0;
  double fast_speed = 2.5;
  std::uint64_t seed = 1;
};

struct HiddenEffectScenario {
  Dataset train;  ///< slow trajectory
  Dataset test;   ///< fast trajectory, later in time
  Eigen::MatrixXd hidden_train, hidden_test;  ///< the hidden torque alone, in the units of Y
  std::string description;
};

/// Throws std::invalid_argument on a bad joint or option.
HiddenEffectScenario MakeHiddenEffectScenario(const Robot& robot,
                                              const HiddenEffectOptions& options);

}  // namespace sim
}  // namespace structgp

#endif  // STRUCTGP_SIM_HIDDEN_EFFECT_H_
