#include "structgp/sim/hidden_effect.h"

#include <cmath>
#include <random>
#include <sstream>
#include <stdexcept>

#include "structgp/sim/trajectory.h"

namespace structgp {
namespace sim {
namespace {

constexpr double kTwoPi = 6.283185307179586;
constexpr double kSignWidth = 0.01;  // rad/s, width of the tanh that stands for sign(qd)

}  // namespace

const char* ToString(HiddenEffect effect) {
  switch (effect) {
    case HiddenEffect::kNone: return "none";
    case HiddenEffect::kCoulomb: return "coulomb";
    case HiddenEffect::kViscous: return "viscous";
    case HiddenEffect::kStribeck: return "stribeck";
    case HiddenEffect::kCogging: return "cogging";
    case HiddenEffect::kDrift: return "drift";
    case HiddenEffect::kSpring: return "spring";
  }
  return "unknown";
}

HiddenEffect ParseHiddenEffect(const std::string& name) {
  for (HiddenEffect e : {HiddenEffect::kNone, HiddenEffect::kCoulomb, HiddenEffect::kViscous,
                         HiddenEffect::kStribeck, HiddenEffect::kCogging, HiddenEffect::kDrift,
                         HiddenEffect::kSpring}) {
    if (name == ToString(e)) return e;
  }
  throw std::invalid_argument("unknown hidden effect '" + name +
                              "' (expected none, coulomb, viscous, stribeck, cogging, drift or "
                              "spring)");
}

HiddenEffectScenario MakeHiddenEffectScenario(const Robot& robot,
                                              const HiddenEffectOptions& options) {
  const int N = robot.num_joints();
  if (options.joint < 1 || options.joint > N) {
    throw std::invalid_argument("hidden effect joint " + std::to_string(options.joint) +
                                " out of range 1.." + std::to_string(N));
  }
  if (!(options.magnitude >= 0) || !(options.noise_std >= 0) || !(options.cogging_period > 0)) {
    throw std::invalid_argument("hidden effect: magnitude and noise_std must be >= 0, "
                                "cogging_period > 0");
  }
  // The same closed path, slow for training and fast for testing.
  const Trajectory slow = ViaPoints(N, options.train_duration, options.dt, options.num_vias,
                                    options.slow_speed,
                                    options.q_range, options.seed, ViaVelocity::kContinuous);
  Trajectory fast = ViaPoints(N, options.test_duration, options.dt, options.num_vias,
                              options.fast_speed * options.test_duration / options.train_duration, options.q_range,
                              options.seed, ViaVelocity::kContinuous);
  fast.t.array() += options.train_duration;

  SimulationOptions clean;
  const Dataset train = Simulate(robot, slow, clean);
  const Dataset test = Simulate(robot, fast, clean);
  Eigen::VectorXd scale(N);
  for (int j = 0; j < N; ++j) {
    scale[j] = std::max(train.Y.col(j).cwiseAbs().maxCoeff(), test.Y.col(j).cwiseAbs().maxCoeff());
    if (!(scale[j] > 0)) scale[j] = 1.0;
  }
  const int j = options.joint - 1;
  const double qd_max = std::max(train.X.col(N + j).cwiseAbs().maxCoeff(),
                                 test.X.col(N + j).cwiseAbs().maxCoeff());
  const double t_end = options.train_duration + options.test_duration;
  auto hidden = [&](const Dataset& d) {
    Eigen::MatrixXd h = Eigen::MatrixXd::Zero(d.X.rows(), N);
    for (Eigen::Index i = 0; i < d.X.rows(); ++i) {
      const double q = d.X(i, j), qd = d.X(i, N + j), t = d.t[i];
      double shape = 0.0;
      switch (options.effect) {
        case HiddenEffect::kNone: shape = 0.0; break;
        case HiddenEffect::kCoulomb: shape = std::tanh(qd / kSignWidth); break;
        case HiddenEffect::kViscous: shape = qd / std::max(qd_max, 1e-9); break;
        case HiddenEffect::kStribeck: {
          const double r = qd / (0.1 * std::max(qd_max, 1e-9));
          shape = std::exp(-r * r) * std::tanh(qd / kSignWidth);
          break;
        }
        case HiddenEffect::kCogging: shape = std::sin(kTwoPi * q / options.cogging_period); break;
        case HiddenEffect::kDrift: shape = (t / t_end) * std::tanh(qd / kSignWidth); break;
        case HiddenEffect::kSpring: shape = std::sin(q); break;
      }
      h(i, j) = options.magnitude * shape;  // in units of the torque scale
    }
    return h;
  };
  HiddenEffectScenario s;
  s.hidden_train = hidden(train);
  s.hidden_test = hidden(test);
  std::mt19937_64 rng(options.seed ^ 0x5eedULL);
  std::normal_distribution<double> normal(0.0, 1.0);
  auto finish = [&](Dataset d, const Eigen::MatrixXd& h) {
    for (int k = 0; k < N; ++k) d.Y.col(k) /= scale[k];
    d.Y += h;
    for (Eigen::Index i = 0; i < d.Y.rows(); ++i) {
      for (int k = 0; k < N; ++k) d.Y(i, k) += options.noise_std * normal(rng);
    }
    d.torque_scale = scale;
    return d;
  };
  s.train = finish(train, s.hidden_train);
  s.test = finish(test, s.hidden_test);
  std::ostringstream os;
  os << robot.name() << ", hidden " << ToString(options.effect) << " on joint " << options.joint
     << " (" << 100.0 * options.magnitude << "% of the torque scale), noise "
     << 100.0 * options.noise_std << "%; train " << s.train.X.rows() << " slow samples, test "
     << s.test.X.rows() << " samples " << options.fast_speed / options.slow_speed
     << "x faster";
  s.description = os.str();
  return s;
}

}  // namespace sim
}  // namespace structgp
