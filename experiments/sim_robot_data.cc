// sim_robot_data: writes a simulated robot log as two robot CSV files that follow each other in
// time, train.csv (the first --train rows) and test.csv (the next --test rows): the
// three-joint KDL arm (sim::ThreeLinkArm) along a sum-of-sines excitation trajectory, with
// Coulomb and viscous friction on every joint and Gaussian torque noise. Used by
// experiments/sklearn_compare.py.
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

#include "experiment_program.h"
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

struct Flags {
  std::string out_dir;
  int train = 5000;
  int test = 2000;
  std::uint64_t seed = 1;
  double noise = 0.01;
};

void AddFlags(CLI::App* app, Flags* f) {
  app->add_option("--out-dir", f->out_dir, "directory of train.csv and test.csv")
      ->required()
      ->check(CLI::ExistingDirectory);
  AddFlag(app, "--train", &f->train, "rows of train.csv")->check(GreaterThan(0));
  AddFlag(app, "--test", &f->test, "rows of test.csv (the rows that follow)")
      ->check(GreaterThan(0));
  AddFlag(app, "--seed", &f->seed, "seed of the trajectory (the noise uses seed + 1)");
  AddFlag(app, "--noise", &f->noise, "noise std relative to the RMS of all noise-free torques")
      ->check(AtLeast(0));
}

RobotData Part(const sim::Dataset& d, int begin, int count) {
  RobotData r;
  r.num_joints = d.num_joints();
  r.X = d.X.middleRows(begin, count);
  r.Y = d.Y.middleRows(begin, count);
  r.t = d.t.segment(begin, count);
  return r;
}

int Run(const Flags& flags) {
  const std::string& out_dir = flags.out_dir;
  const int train = flags.train, test = flags.test;
  const std::uint64_t seed = flags.seed;
  const double noise = flags.noise;
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
  CLI::App app(
      "Writes a simulated three-joint robot log (KDL arm, friction, noise) as train.csv and "
      "test.csv.",
      "sim_robot_data");
  structgp::Flags f;
  structgp::AddFlags(&app, &f);
  return structgp::RunProgram(&app, argc, argv, [&]() { return structgp::Run(f); });
}
