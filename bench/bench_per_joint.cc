// One set of hyper-parameters for all joints against one set per joint (FitOptions::per_joint):
// the batch fit, the prediction with variance and the online addition of one sample, for pol+fri
// at 3 joints in weight space (D = 1,160) and at 2 joints (D = 139). The per-joint model holds one
// posterior factor per joint, so prediction and addition cost about N times the shared ones.
//
//   build/bench/bench_per_joint --benchmark_repetitions=3 --benchmark_report_aggregates_only=true
//
// Counters: allocs_per_call must be 0 for predict and add (allocation counter linked in from
// tests/).

#include <random>
#include <stdexcept>
#include <vector>

#include <benchmark/benchmark.h>

#include "alloc_counter.h"
#include "structgp/model/robot_model.h"

namespace {

using structgp::Hyperparameters;
using structgp::Matrix;
using structgp::RobotModel;
using structgp::Vector;

struct Problem {
  Matrix X, Y;
};

// Random states and torques: the costs do not depend on what the torques are.
Problem MakeProblem(int joints, int rows) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Problem p{Matrix(rows, 3 * joints), Matrix(rows, joints)};
  for (Eigen::Index i = 0; i < p.X.size(); ++i) p.X.data()[i] = 2.0 * u(rng);
  for (Eigen::Index i = 0; i < p.Y.size(); ++i) p.Y.data()[i] = u(rng);
  return p;
}

// The model's default set, shared or copied once per joint.
Hyperparameters Hyper(const RobotModel& model, const Matrix& Y, bool per_joint) {
  Hyperparameters h = model.DefaultHyperparameters(Y);
  if (per_joint) {
    std::vector<Hyperparameters> sets;
    for (int j = 0; j < model.num_joints(); ++j) {
      sets.push_back(h.Output(j));
      sets.back().log_noise_std += 0.1 * j;
    }
    h.per_output = sets;
  }
  return h;
}

RobotModel Fitted(int joints, bool per_joint, const Problem& p) {
  RobotModel model(structgp::ParseModelSpec("pol+fri"), joints);
  if (model.Fit(p.X, p.Y, Hyper(model, p.Y, per_joint)) != structgp::Status::kOk) {
    throw std::runtime_error("fit failed");
  }
  return model;
}

// args: joints, per_joint (0/1)
void BM_Fit(benchmark::State& state) {
  const int joints = static_cast<int>(state.range(0));
  const bool per_joint = state.range(1) != 0;
  const Problem p = MakeProblem(joints, 3000);
  RobotModel model(structgp::ParseModelSpec("pol+fri"), joints);
  const Hyperparameters h = Hyper(model, p.Y, per_joint);
  for (auto _ : state) {
    benchmark::DoNotOptimize(model.Fit(p.X, p.Y, h));
  }
  state.counters["D"] = model.feature_map()->dim();
}
BENCHMARK(BM_Fit)->Args({2, 0})->Args({2, 1})->Args({3, 0})->Args({3, 1})
    ->Unit(benchmark::kMillisecond);

void BM_PredictWithVariance(benchmark::State& state) {
  const int joints = static_cast<int>(state.range(0));
  const Problem p = MakeProblem(joints, 3000);
  RobotModel model = Fitted(joints, state.range(1) != 0, p);
  // Third argument 1: calibrated bands (a latent variance scale on every joint).
  if (state.range(2) != 0) model.SetLatentVarianceScale(Vector::Constant(joints, 2.0));
  RobotModel::Workspace workspace = model.MakeWorkspace();
  Vector x(3 * joints), mean(joints), latent(joints), noisy(joints);
  int i = 0;
  const std::size_t allocs_before = structgp::testing::TotalAllocations();
  for (auto _ : state) {
    x = p.X.row(i).transpose();
    benchmark::DoNotOptimize(model.PredictWithVariance(x, mean, latent, noisy, workspace));
    i = (i + 1) % static_cast<int>(p.X.rows());
  }
  state.counters["allocs_per_call"] = benchmark::Counter(
      static_cast<double>(structgp::testing::TotalAllocations() - allocs_before) /
      static_cast<double>(state.iterations()));
}
BENCHMARK(BM_PredictWithVariance)
    ->Args({2, 0, 0})->Args({2, 1, 0})->Args({3, 0, 0})->Args({3, 1, 0})
    ->Args({2, 0, 1})->Args({3, 0, 1})
    ->Unit(benchmark::kMicrosecond);

void BM_Add(benchmark::State& state) {
  const int joints = static_cast<int>(state.range(0));
  const Problem p = MakeProblem(joints, 3000);
  RobotModel model = Fitted(joints, state.range(1) != 0, p);
  Vector x(3 * joints), y(joints);
  int i = 0;
  const std::size_t allocs_before = structgp::testing::TotalAllocations();
  for (auto _ : state) {
    x = p.X.row(i).transpose();
    y = p.Y.row(i).transpose();
    benchmark::DoNotOptimize(model.mutable_gp().Add(x, y));
    i = (i + 1) % static_cast<int>(p.X.rows());
  }
  state.counters["allocs_per_call"] = benchmark::Counter(
      static_cast<double>(structgp::testing::TotalAllocations() - allocs_before) /
      static_cast<double>(state.iterations()));
}
BENCHMARK(BM_Add)->Args({2, 0})->Args({2, 1})->Args({3, 0})->Args({3, 1})
    ->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
