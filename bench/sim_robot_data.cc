// sim_robot_data: writes a simulated robot log as two robot CSV files that follow each other in
// time, train.csv (the first --train rows) and test.csv (the next --test rows): the
// three-joint KDL arm (sim::ThreeLinkArm) along a sum-of-sines excitation trajectory, with
// Coulomb and viscous friction on every joint and Gaussian torque noise. Used by
// bench/sklearn_compare.py.
//
//   sim_robot_data --out-dir=DIR [--train=5000] [--test=2000] [--seed=1] [--noise=0.01]
//
// Trajectory: q_n(t) = sum of 4 harmonics of 0.05 Hz, |q_n| <= 1.5 rad, sampled every 0.01 s.
// Friction per joint: Coulomb 0.3 N m (sign(qd), not smoothed), viscous 0.2 N m s/rad. Noise:
// standard deviation --noise times the RMS of all noise-free torques, N m.

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "bench_program.h"
#include "structgp/io/csv.h"
#include "structgp/io/data_error.h"
#include "structgp/io/robot_data.h"
#include "structgp/sim/dataset.h"
#include "structgp/sim/friction.h"
#include "structgp/sim/robot.h"
#include "structgp/sim/trajectory.h"

namespace structgp {
namespace {

constexpr double kDt = 0.01;  // s
constexpr int kHarmonics = 4;
constexpr double kBaseFrequency = 0.05;  // Hz
constexpr double kAmplitude = 1.5;       // rad
constexpr double kCoulomb = 0.3;         // N m
constexpr double kViscous = 0.2;         // N m s / rad

const char kUsage[] =
    "usage: sim_robot_data --out-dir=DIR [--train=5000] [--test=2000] [--seed=1] "
    "[--noise=0.01]\n";

RobotData Part(const sim::Dataset& d, int begin, int count) {
  RobotData r;
  r.num_joints = d.num_joints();
  r.X = d.X.middleRows(begin, count);
  r.Y = d.Y.middleRows(begin, count);
  r.t = d.t.segment(begin, count);
  return r;
}

int Run(int argc, char** argv) {
  std::string out_dir;
  int train = 5000, test = 2000;
  std::uint64_t seed = 1;
  double noise = 0.01;
  ForEachFlag(argc, argv, [&](const Flag& flag) {
    const std::string& name = flag.name();
    if (name == "--out-dir") {
      out_dir = flag.Value();
    } else if (name == "--train") {
      train = flag.Int();
    } else if (name == "--test") {
      test = flag.Int();
    } else if (name == "--seed") {
      seed = flag.Uint64();
    } else if (name == "--noise") {
      noise = flag.Number();
    } else {
      return false;
    }
    return true;
  });
  if (out_dir.empty()) throw std::invalid_argument("--out-dir is required");
  if (train < 1 || test < 1 || !(noise >= 0.0)) {
    throw std::invalid_argument("expected --train >= 1, --test >= 1 and --noise >= 0");
  }
  if (!std::filesystem::is_directory(out_dir)) {
    throw std::invalid_argument("--out-dir '" + out_dir + "' is not a directory");
  }
  const sim::Robot robot = sim::ThreeLinkArm();
  const int n = robot.num_joints();
  const double duration = (train + test) * kDt;
  sim::Trajectory path =
      sim::SumOfSines(n, duration, kDt, kHarmonics, kBaseFrequency, kAmplitude, seed);
  std::vector<sim::JointFriction> joints(static_cast<size_t>(n));
  for (auto& j : joints) {
    j.coulomb = kCoulomb;
    j.viscous = kViscous;
  }
  sim::SimulationOptions options;
  options.friction = sim::FrictionModel(joints);
  const sim::Dataset clean = sim::Simulate(robot, path, options);
  const double rms = std::sqrt(clean.Y.squaredNorm() / static_cast<double>(clean.Y.size()));
  options.noise_std = noise * rms;
  options.seed = seed + 1;
  const sim::Dataset noisy = sim::Simulate(robot, path, options);
  const int rows = static_cast<int>(noisy.num_samples());
  if (rows < train + test) throw std::runtime_error("trajectory shorter than expected");
  WriteRobotCsv(out_dir + "/train.csv", Part(noisy, 0, train));
  WriteRobotCsv(out_dir + "/test.csv", Part(noisy, train, test));
  std::printf("wrote %s/train.csv (%d rows) and test.csv (%d rows): %s, noise std %.4g N m\n",
              out_dir.c_str(), train, test, robot.name().c_str(), options.noise_std);
  return 0;
}

}  // namespace
}  // namespace structgp

int main(int argc, char** argv) {
  return structgp::RunProgram("sim_robot_data", structgp::kUsage, structgp::Run, argc, argv);
}
