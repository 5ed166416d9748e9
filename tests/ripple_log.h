// A two-link log with a torque no chain makes, shared by the tests of the identification and of
// the diagnosis loop that identifies a chain again.
#ifndef STRUCTGP_TESTS_RIPPLE_LOG_H_
#define STRUCTGP_TESTS_RIPPLE_LOG_H_

#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "structgp/core/types.h"
#include "structgp/sim/dataset.h"
#include "structgp/sim/friction.h"
#include "structgp/sim/robot.h"
#include "structgp/sim/trajectory.h"

namespace structgp {
namespace testing {

// The two-link arm (planar, vertical) along `trajectory`, with viscous and Coulomb friction on
// both joints, a cogging ripple on joint 2 of `ripple` times its RMS torque (period 0.3 rad)
// and noise of 1% of each joint's RMS torque (drawn from noise_seed).
struct RippleLog {
  Matrix X, Y;
  Vector t, noise;
  // X with t as its last column, as IdentifyChain takes it.
  Matrix XT() const {
    Matrix xt(X.rows(), X.cols() + 1);
    xt << X, t;
    return xt;
  }
};

inline RippleLog TwoLinkRippleLog(const sim::Trajectory& trajectory, std::uint64_t noise_seed,
                                  double ripple = 0.1) {
  std::vector<sim::JointFriction> joints(2);
  for (auto& j : joints) {
    j.coulomb = 0.2;
    j.viscous = 0.1;
    j.smoothing_velocity = 0.01;
  }
  sim::SimulationOptions options;
  options.friction = sim::FrictionModel(joints);
  const sim::Dataset d = sim::Simulate(sim::TwoLinkArm(), trajectory, options);
  RippleLog log{d.X, d.Y, d.t, Vector()};
  const Vector rms = (d.Y.colwise().squaredNorm() / d.Y.rows()).cwiseSqrt().transpose();
  log.noise = 0.01 * rms;
  std::mt19937_64 rng(noise_seed);
  std::normal_distribution<double> normal;
  for (Eigen::Index i = 0; i < log.Y.rows(); ++i) {
    log.Y(i, 1) += ripple * rms[1] * std::sin(2.0 * M_PI * d.X(i, 1) / 0.3 + 0.4);
    for (int j = 0; j < 2; ++j) log.Y(i, j) += log.noise[j] * normal(rng);
  }
  return log;
}

}  // namespace testing
}  // namespace structgp

#endif  // STRUCTGP_TESTS_RIPPLE_LOG_H_
