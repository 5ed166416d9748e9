// Accuracy and cost of Nystrom features against the exact kernel-form model, on a simulated
// 6-joint robot (KDL dynamics): normalised mean squared error of the torque predictions as a
// function of the number of features D = M, and the online step time at each D.
//
//   build/experiments/nystrom_accuracy --out-dir docs
//
// writes <out-dir>/nystrom_accuracy.md and <out-dir>/nystrom_accuracy.csv and prints the table.
// Options: --train <m> (3000; m / 3 held-out states), --test <n> (1000, new-path states),
// --steps <timed online steps per D> (2000).
//
// Protocol. Robot sim::RandomRobot(6, 1). A smooth via-point trajectory (sim::ViaPoints,
// continuous velocities, 40 random via points, |q| <= 1.2 rad) sampled at 50 Hz; of every four
// consecutive samples three are training states and the fourth a held-out state ("held-out"
// test: states between training states). An independent trajectory from the same generator
// (another seed) gives the "new path" test: generalisation. Torques from KDL's inverse
// dynamics, divided per joint by the largest training torque, plus Gaussian noise of standard
// deviation 0.01. nMSE_j = mean squared error / variance of the test torques of joint j,
// averaged over the joints.
//
// Models. Exact: KernelGP with PolFormulaKernel(6) (k_pol, eq. 17, default sigma and block
// scales) on all training samples. Nystrom: WeightSpaceGP with unit prior on
// NystromFeatureMap(k_pol, Z), |Z| = M, Z chosen among the training states by greedy maximum
// residual variance and, for comparison, at random; the same noise and output scales as the
// exact model. The noise level is chosen by the exact model's evidence on a small grid, with the
// per-joint output scales at their closed-form optimum s_j^2 = y_j^T (K + sigma^2 I)^{-1} y_j / m.
//
// Online step: features of the measured state and of the next reference state, then
// WeightSpaceGP::UpdateAndPredict (rank-one update, weights kept current, mean and variance at
// the next state), 6 outputs; median and 99th percentile of steady_clock times per step.

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "experiment_program.h"
#include "structgp/kernel/nystrom_feature_map.h"
#include "structgp/kernel/pol_kernel.h"
#include "structgp/model/kernel_gp.h"
#include "structgp/model/weight_space_gp.h"
#include "structgp/sim/dataset.h"
#include "structgp/sim/robot.h"
#include "structgp/sim/trajectory.h"

namespace {

using structgp::Matrix;
using structgp::Vector;
using Clock = std::chrono::steady_clock;

constexpr int kJoints = 6;
constexpr std::uint64_t kRobotSeed = 1;
constexpr std::uint64_t kTrainSeed = 11;
constexpr std::uint64_t kTestSeed = 12;
constexpr std::uint64_t kNoiseSeed = 13;
constexpr std::uint64_t kRandomSubsetSeed = 14;
constexpr double kNoiseStd = 0.01;
const std::vector<int> kFeatureCounts = {64, 128, 256, 512, 1024};

struct Args {
  std::string out_dir = ".";
  int train = 3000;
  int test = 1000;
  int steps = 2000;
};

void AddFlags(CLI::App* app, Args* a) {
  structgp::AddFlag(app, "--out-dir", &a->out_dir, "where nystrom_accuracy.{md,csv} go");
  structgp::AddFlag(app, "--train", &a->train, "training states (m / 3 more are held out)")
      ->check(structgp::AtLeast(100));
  structgp::AddFlag(app, "--test", &a->test, "states of the new path")
      ->check(structgp::AtLeast(10));
  structgp::AddFlag(app, "--steps", &a->steps, "timed online steps per D")
      ->check(structgp::AtLeast(10));
}

struct Data {
  Matrix X;  // m x 18
  Matrix Y;  // m x 6
};

Data Simulate(const structgp::sim::Robot& robot, int m, std::uint64_t seed) {
  const double dt = 0.02;  // 50 Hz
  const structgp::sim::Trajectory traj = structgp::sim::ViaPoints(
      kJoints, m * dt, dt, 40, 1.0, 1.2, seed, structgp::sim::ViaVelocity::kContinuous);
  const structgp::sim::Dataset d = structgp::sim::Simulate(robot, traj);
  return {d.X.topRows(m), d.Y.topRows(m)};
}

double Nmse(const Matrix& prediction, const Matrix& truth) {
  double sum = 0.0;
  for (int j = 0; j < truth.cols(); ++j) {
    const double mean = truth.col(j).mean();
    const double var = (truth.col(j).array() - mean).square().mean();
    sum += (prediction.col(j) - truth.col(j)).squaredNorm() / truth.rows() / var;
  }
  return sum / truth.cols();
}

Matrix PredictExact(const structgp::KernelGP& gp, const Matrix& X) {
  Matrix out(X.rows(), gp.num_outputs());
  Vector mean(gp.num_outputs());
  structgp::KernelGP::Workspace workspace = gp.MakeWorkspace();
  for (int i = 0; i < X.rows(); ++i) {
    gp.Predict(X.row(i).transpose(), mean, workspace);
    out.row(i) = mean.transpose();
  }
  return out;
}

Matrix PredictWeightSpace(const structgp::WeightSpaceGP& gp, const structgp::FeatureMap& map,
                          const Matrix& X) {
  Matrix out(X.rows(), gp.num_outputs());
  Vector mean(gp.num_outputs()), phi(map.dim());
  structgp::WeightSpaceGP::Workspace workspace = gp.MakeWorkspace();
  for (int i = 0; i < X.rows(); ++i) {
    map.Evaluate(X.row(i).transpose(), phi);
    gp.Predict(phi, mean, workspace);
    out.row(i) = mean.transpose();
  }
  return out;
}

double Seconds(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double>(b - a).count();
}

double Percentile(std::vector<double> v, double p) {
  std::sort(v.begin(), v.end());
  const std::size_t k = std::min(v.size() - 1, static_cast<std::size_t>(p * (v.size() - 1) + 0.5));
  return v[k];
}

// Rows with i % 4 == 3 (held-out) or the others (training).
Data Split(const Data& d, bool held_out) {
  std::vector<int> rows;
  for (int i = 0; i < d.X.rows(); ++i) {
    if ((i % 4 == 3) == held_out) rows.push_back(i);
  }
  Data out{Matrix(static_cast<Eigen::Index>(rows.size()), d.X.cols()),
           Matrix(static_cast<Eigen::Index>(rows.size()), d.Y.cols())};
  for (std::size_t k = 0; k < rows.size(); ++k) {
    out.X.row(static_cast<Eigen::Index>(k)) = d.X.row(rows[k]);
    out.Y.row(static_cast<Eigen::Index>(k)) = d.Y.row(rows[k]);
  }
  return out;
}

struct Row {
  int requested = 0;
  int M = 0;
  int M_random = 0;
  double nmse_held_out = 0.0;  // greedy Z
  double nmse_greedy = 0.0;    // new path
  double nmse_random = 0.0;    // new path
  double gap_greedy = 0.0;     // nMSE of the Nystrom predictions against the exact model's
  double select_s = 0.0;
  double fit_s = 0.0;
  double features_us = 0.0;
  double step_p50_us = 0.0;
  double step_p99_us = 0.0;
};

int Run(const Args& args) {
  const structgp::sim::Robot robot = structgp::sim::RandomRobot(kJoints, kRobotSeed);
  const Data path = Simulate(robot, args.train + args.train / 3, kTrainSeed);
  Data train = Split(path, /*held_out=*/false);
  Data held_out = Split(path, /*held_out=*/true);
  Data test = Simulate(robot, args.test, kTestSeed);
  const Vector scale = train.Y.cwiseAbs().colwise().maxCoeff().transpose();
  std::mt19937_64 rng(kNoiseSeed);
  std::normal_distribution<double> normal(0.0, kNoiseStd);
  for (Data* d : {&train, &held_out, &test}) {
    for (int j = 0; j < kJoints; ++j) d->Y.col(j) /= scale[j];
    d->Y += Matrix::NullaryExpr(d->Y.rows(), d->Y.cols(), [&]() { return normal(rng); });
  }
  const int m = static_cast<int>(train.X.rows());
  std::printf("robot %s, %d training, %d held-out and %d new-path samples, torque scales (N m):",
              robot.name().c_str(), m, static_cast<int>(held_out.X.rows()),
              static_cast<int>(test.X.rows()));
  for (int j = 0; j < kJoints; ++j) std::printf(" %.2f", scale[j]);
  std::printf("\n");

  // ---- exact model: noise level by evidence, output scales in closed form --------------------
  const structgp::PolFormulaKernel kernel(kJoints);
  double best_lml = -HUGE_VAL, best_noise_std = 0.0;
  Vector best_scales;
  std::ostringstream grid;
  for (double noise_std : {0.003, 0.01, 0.03, 0.1}) {
    structgp::KernelGP gp(kernel, noise_std * noise_std, kJoints);
    if (gp.Fit(train.X, train.Y) != structgp::Status::kOk) continue;
    Vector d_scale;
    const double lml1 = gp.LogMarginalLikelihood(nullptr, nullptr, &d_scale);
    // At s = 1, d lml / d log s_j = q_j - m with q_j = y_j^T (K + sigma^2 I)^{-1} y_j; the
    // optimum is s_j^2 = q_j / m and raises the evidence by sum_j (q_j - m - m log(q_j / m)) / 2.
    Vector scales(kJoints);
    double lml = lml1;
    for (int j = 0; j < kJoints; ++j) {
      const double q = d_scale[j] + m;
      scales[j] = std::sqrt(q / m);
      lml += 0.5 * (q - m - m * std::log(q / m));
    }
    char line[96];
    std::snprintf(line, sizeof(line), "sigma_n/s = %g: log evidence %.1f\n", noise_std, lml);
    grid << line;
    if (lml > best_lml) {
      best_lml = lml;
      best_noise_std = noise_std;
      best_scales = scales;
    }
  }
  std::printf("%s", grid.str().c_str());
  const double noise_variance = best_noise_std * best_noise_std;
  structgp::KernelGP exact(kernel, noise_variance, kJoints, best_scales);
  auto t0 = Clock::now();
  if (exact.Fit(train.X, train.Y) != structgp::Status::kOk) {
    std::fprintf(stderr, "nystrom_accuracy: exact fit failed\n");
    return 1;
  }
  const double exact_fit_s = Seconds(t0, Clock::now());
  t0 = Clock::now();
  const Matrix exact_prediction = PredictExact(exact, test.X);
  const double exact_predict_us = 1e6 * Seconds(t0, Clock::now()) / test.X.rows();
  const double exact_nmse = Nmse(exact_prediction, test.Y);
  const double exact_nmse_held_out = Nmse(PredictExact(exact, held_out.X), held_out.Y);
  std::printf(
      "exact: sigma_n/s = %.3g, nMSE held-out %.5f, new path %.5f, fit %.2f s, "
      "predict %.0f us per state\n",
      best_noise_std, exact_nmse_held_out, exact_nmse, exact_fit_s, exact_predict_us);

  // ---- Nystrom models ----------------------------------------------------------------------
  std::vector<Row> rows;
  for (const int M : kFeatureCounts) {
    if (M > m) break;
    Row r;
    r.requested = M;
    r.M = M;
    for (const structgp::InducingSelection sel : {structgp::InducingSelection::kGreedyVariance,
                                                  structgp::InducingSelection::kRandomSubset}) {
      structgp::InducingOptions io;
      io.selection = sel;
      io.seed = kRandomSubsetSeed;
      t0 = Clock::now();
      const Matrix Z = structgp::SelectInducingStates(kernel, train.X, M, io);
      const double select_s = Seconds(t0, Clock::now());
      const structgp::NystromFeatureMap map(kernel, Z);
      t0 = Clock::now();
      Matrix Phi;
      map.EvaluateRows(train.X, &Phi);
      structgp::WeightSpaceGP model(Vector::Ones(map.dim()), noise_variance, kJoints, best_scales);
      if (model.Fit(Phi, train.Y) != structgp::Status::kOk) {
        std::fprintf(stderr, "nystrom_accuracy: weight-space fit failed at M = %d\n", M);
        return 1;
      }
      const double fit_s = Seconds(t0, Clock::now());
      const Matrix prediction = PredictWeightSpace(model, map, test.X);
      if (sel == structgp::InducingSelection::kRandomSubset) {
        r.nmse_random = Nmse(prediction, test.Y);
        r.M_random = map.dim();
        continue;
      }
      r.M = map.dim();
      r.nmse_greedy = Nmse(prediction, test.Y);
      r.nmse_held_out = Nmse(PredictWeightSpace(model, map, held_out.X), held_out.Y);
      r.gap_greedy = Nmse(prediction, exact_prediction);
      r.select_s = select_s;
      r.fit_s = fit_s;
      // Online step timing, on the fitted model: measured state i, next reference state i + 1.
      const int D = map.dim();
      Vector phi_u(D), phi_p(D), y(kJoints), mean(kJoints), latent(kJoints), noisy(kJoints);
      std::vector<double> steps(static_cast<std::size_t>(args.steps));
      std::vector<double> features(static_cast<std::size_t>(args.steps));
      for (int s = 0; s < args.steps; ++s) {
        const int i = s % (m - 1);
        const Vector x_u = train.X.row(i).transpose();
        const Vector x_p = train.X.row(i + 1).transpose();
        y = train.Y.row(i).transpose();
        const auto a = Clock::now();
        map.Evaluate(x_u, phi_u);
        map.Evaluate(x_p, phi_p);
        const auto b = Clock::now();
        model.UpdateAndPredict(phi_u, y, phi_p, mean, latent, noisy, 0.9999);
        const auto c = Clock::now();
        features[static_cast<std::size_t>(s)] = 1e6 * Seconds(a, b) / 2.0;
        steps[static_cast<std::size_t>(s)] = 1e6 * Seconds(a, c);
      }
      r.features_us = Percentile(features, 0.5);
      r.step_p50_us = Percentile(steps, 0.5);
      r.step_p99_us = Percentile(steps, 0.99);
    }
    std::printf(
        "M = %4d: nMSE held-out %.5f, new path %.5f (random Z %.5f), vs exact %.5f; "
        "select %.2f s, fit %.2f s; features %.1f us, step p50 %.1f us, p99 %.1f us\n",
        r.M, r.nmse_held_out, r.nmse_greedy, r.nmse_random, r.gap_greedy, r.select_s, r.fit_s,
        r.features_us, r.step_p50_us, r.step_p99_us);
    rows.push_back(r);
  }

  // ---- files -----------------------------------------------------------------------------------
  const std::string csv_path = args.out_dir + "/nystrom_accuracy.csv";
  const std::string md_path = args.out_dir + "/nystrom_accuracy.md";
  {
    std::ofstream csv(csv_path);
    if (!csv) {
      std::fprintf(stderr, "nystrom_accuracy: cannot write %s\n", csv_path.c_str());
      return 1;
    }
    csv << "model,D,nmse_held_out,nmse_new_path,nmse_new_path_random_subset,nmse_vs_exact,"
           "select_s,fit_s,features_us,step_p50_us,step_p99_us\n";
    csv << "exact," << m << "," << exact_nmse_held_out << "," << exact_nmse << ",,0,0,"
        << exact_fit_s << ",,,\n";
    for (const Row& r : rows) {
      csv << "nystrom," << r.M << "," << r.nmse_held_out << "," << r.nmse_greedy << ","
          << r.nmse_random << "," << r.gap_greedy << "," << r.select_s << "," << r.fit_s << ","
          << r.features_us << "," << r.step_p50_us << "," << r.step_p99_us << "\n";
    }
  }
  std::ofstream md(md_path);
  if (!md) {
    std::fprintf(stderr, "nystrom_accuracy: cannot write %s\n", md_path.c_str());
    return 1;
  }
  md << std::fixed;
  md << "# Nystrom features on a 6-joint robot: accuracy and online cost vs D\n\n"
     << "Generated by `experiments/nystrom_accuracy.cc`:\n\n"
     << "    build/experiments/nystrom_accuracy --out-dir docs --train " << args.train << " --test "
     << args.test << " --steps " << args.steps << "\n\n"
     << "Robot `" << robot.name()
     << "` (KDL dynamics). A smooth via-point trajectory at 50 Hz: " << m << " training states and "
     << held_out.X.rows()
     << " held-out states (every fourth sample: states between training states); " << test.X.rows()
     << " states of an independent trajectory (new path: generalisation). Torques divided per "
        "joint by the largest training torque, noise std "
     << std::setprecision(2) << kNoiseStd
     << ". nMSE = test MSE / test variance, averaged over the 6 joints. "
        "Exact model: KernelGP with k_pol (`PolFormulaKernel(6)`, O(m^3) fit, O(m^2) per online "
        "step). Nystrom: `NystromFeatureMap` with D = M inducing states chosen among the "
        "training states, `WeightSpaceGP` with unit prior, the same noise (sigma_n / s = "
     << std::setprecision(3) << best_noise_std
     << ", chosen by the exact model's evidence) and output scales.\n\n"
     << "Online step = features of two states (measured, next reference) + `UpdateAndPredict` "
        "(rank-one update, weights current, mean and variance), 6 outputs, "
     << args.steps
     << " steps per D; times in microseconds on the machine of "
        "docs/performance.md.\n\n";
  md << "| model | D | nMSE held-out | nMSE new path | new path, random Z | new path, vs exact "
        "model | features / state (us) | online step p50 (us) | p99 (us) |\n"
     << "|---|---|---|---|---|---|---|---|---|\n";
  md << std::setprecision(4) << "| exact k_pol (KernelGP) | m = " << m << " | "
     << exact_nmse_held_out << " | " << exact_nmse << " | | 0 | | | |\n";
  for (const Row& r : rows) {
    md << "| Nystrom | " << r.M;
    if (r.M != r.requested) md << " (asked " << r.requested << ")";
    md << " | " << std::setprecision(4) << r.nmse_held_out << " | " << r.nmse_greedy << " | "
       << r.nmse_random << " | " << r.gap_greedy << " | " << std::setprecision(1) << r.features_us
       << " | " << r.step_p50_us << " | " << r.step_p99_us << " |\n";
  }
  md << "\nExact model: fit " << std::setprecision(2) << exact_fit_s << " s, prediction "
     << std::setprecision(0) << exact_predict_us << " us per state (mean only, m = " << m
     << "). Noise grid (log evidence of the exact model):\n\n";
  std::istringstream lines(grid.str());
  for (std::string line; std::getline(lines, line);) md << "    " << line << "\n";
  md << "\nBoth forms generalise alike to a new path: that error is set by the data (one 60 s "
        "path through an 18-dimensional state space) and by k_pol's default shape parameters, "
        "not by the approximation; on held-out states of the training path both are at the "
        "noise level.\n";
  md << "\nA D marked \"(asked M)\" is where greedy selection stopped early: every remaining "
        "training state was explained by the chosen ones to a residual variance below 1e-12 of "
        "the largest k(x, x), i.e. D is the numerical rank of K on the training states. From "
        "there on the Nystrom model is the exact model to rounding (nMSE vs exact ~0), at a "
        "fixed O(D^2) online cost instead of O(m^2) growing with m. The random-subset column "
        "uses D = M states whatever their redundancy.\n\n"
        "Columns of the CSV (`nystrom_accuracy.csv`): model, D, nmse_held_out, nmse_new_path, "
        "nmse_new_path_random_subset, nmse_vs_exact, select_s, fit_s, features_us, step_p50_us, "
        "step_p99_us (times in seconds and microseconds).\n";
  // The machine is shared: say how busy it was, since the tail latencies depend on it.
  std::ifstream loadavg("/proc/loadavg");
  double load1 = 0.0;
  if (loadavg >> load1) {
    md << "\nLoad average (1 min) at the end of this run: " << std::setprecision(2) << load1
       << " (on 2 vCPUs); p99 step times above ~1 ms are preemptions by other processes.\n";
  }
  std::printf("wrote %s and %s\n", md_path.c_str(), csv_path.c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app(
      "Accuracy and online cost of Nystrom features against the exact kernel-form model on a "
      "simulated 6-joint robot; writes nystrom_accuracy.{md,csv}.",
      "nystrom_accuracy");
  Args args;
  AddFlags(&app, &args);
  return structgp::RunProgram(&app, argc, argv, [&]() { return Run(args); });
}
