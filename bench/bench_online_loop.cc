// Online learning inside a control loop: latency distribution of one control step, and of the
// control thread's prediction while a learner thread updates concurrently.
//
//   taskset -c 0,1 build/bench/bench_online_loop
//
// Every benchmark runs a fixed number of steps (1e5; STRUCTGP_BENCH_STEPS overrides it for a
// quick look), times each step on its own with std::chrono::steady_clock into a preallocated
// array and reports, as counters in microseconds, the median (p50_us), the 99th and 99.9th
// percentiles (p99_us, p999_us), the largest step (max_us) and the mean (mean_us; also the
// "Time" column, through manual timing). allocs_per_step counts every malloc/operator new of
// the process during the steps (allocation counter from tests/, as in bench_online): it must be 0.
//
// Data: a 6-joint simulated robot (sim::RandomRobot(6, 1), KDL dynamics), a sum-of-sines
// trajectory sampled at 1 kHz, torques normalised per joint: 6 outputs. Features: Nystrom
// features of k_pol (PolFormulaKernel(6)) with D = M inducing states (random subset, seed 3).
//
// - BM_ModelStep/D: WeightSpaceGP::UpdateAndPredict alone (features precomputed): rank-one
//   update, weights kept current, mean and variance at the next state, forgetting 0.9999.
// - BM_ControlStep/D: what a single-threaded learner costs per control tick: Nystrom features of
//   the measured state and of the next reference state, then the same UpdateAndPredict.
// - BM_PredictWhileLearning/D/V: OnlineLearner with its learner thread; the control thread
//   submits a sample and predicts in a tight loop (no pacing: the learner is kept busy all the
//   time, the worst case for interference); only the prediction is timed: Predict (mean, V = 0)
//   or PredictWithVariance (V = 1), features included. S is published every 100 updates.
//   Counters also give the fraction of samples dropped because the learner could not keep up
//   with the unpaced loop (dropped_frac) and the learner's updates.
// - BM_PublishCovariance/D: the learner's cost of publishing S (copying its upper triangle into
//   the triple buffer's slot, as OnlineLearner does), per publish.

#include <benchmark/benchmark.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <memory>
#include <mutex>
#include <random>
#include <vector>

#include "alloc_counter.h"
#include "structgp/kernel/nystrom_feature_map.h"
#include "structgp/kernel/pol_kernel.h"
#include "structgp/model/weight_space_gp.h"
#include "structgp/online/online_learner.h"
#include "structgp/sim/dataset.h"
#include "structgp/sim/robot.h"
#include "structgp/sim/trajectory.h"

namespace {

using structgp::Matrix;
using structgp::Vector;
using Clock = std::chrono::steady_clock;

constexpr int kJoints = 6;
constexpr int kPool = 4096;  // states cycled through
constexpr double kForgetting = 0.9999;
constexpr double kNoiseVariance = 1e-4;

// STRUCTGP_BENCH_STEPS, or 1e5; at least 100. A value that is not all an integer ("5x") stops
// the program with a message instead of being read as its leading digits.
long Steps() {
  const char* env = std::getenv("STRUCTGP_BENCH_STEPS");
  if (env == nullptr) return 100000;
  char* end = nullptr;
  errno = 0;
  const long steps = std::strtol(env, &end, 10);
  if (end == env || *end != '\0' || errno == ERANGE) {
    std::fprintf(stderr, "bench_online_loop: STRUCTGP_BENCH_STEPS: expected an integer, got '%s'\n",
                 env);
    std::exit(2);
  }
  return std::max(100L, steps);
}

struct Data {
  Matrix X;  // kPool x 18, rows = states at 1 kHz
  Matrix Y;  // kPool x 6
};

const Data& GetData() {
  static const Data data = []() {
    const structgp::sim::Robot robot = structgp::sim::RandomRobot(kJoints, 1);
    const structgp::sim::Trajectory traj =
        structgp::sim::SumOfSines(kJoints, kPool * 1e-3, 1e-3, 4, 0.25, 1.0, 2);
    structgp::sim::SimulationOptions options;
    options.normalization = structgp::sim::TorqueNormalization::kPerJoint;
    options.noise_std = 0.01;
    const structgp::sim::Dataset d = structgp::sim::Simulate(robot, traj, options);
    return Data{d.X.topRows(kPool), d.Y.topRows(kPool)};
  }();
  return data;
}

std::shared_ptr<const structgp::NystromFeatureMap> GetMap(int D) {
  static std::map<int, std::shared_ptr<const structgp::NystromFeatureMap>> maps;
  static std::mutex mutex;
  std::lock_guard<std::mutex> lock(mutex);
  auto it = maps.find(D);
  if (it != maps.end()) return it->second;
  const structgp::PolFormulaKernel kernel(kJoints);
  structgp::InducingOptions io;
  io.selection = structgp::InducingSelection::kRandomSubset;
  io.seed = 3;
  auto map = std::make_shared<const structgp::NystromFeatureMap>(
      kernel, structgp::SelectInducingStates(kernel, GetData().X, D, io));
  maps[D] = map;
  return map;
}

// Percentiles and mean of the step times (seconds) as counters in microseconds.
void Report(benchmark::State& state, std::vector<double>& seconds, std::size_t allocations) {
  const double n = static_cast<double>(seconds.size());
  double sum = 0.0;
  for (double s : seconds) sum += s;
  std::sort(seconds.begin(), seconds.end());
  const auto at = [&](double p) {
    return 1e6 * seconds[std::min(seconds.size() - 1, static_cast<std::size_t>(p * (n - 1)))];
  };
  state.counters["p50_us"] = at(0.5);
  state.counters["p99_us"] = at(0.99);
  state.counters["p999_us"] = at(0.999);
  state.counters["max_us"] = 1e6 * seconds.back();
  state.counters["mean_us"] = 1e6 * sum / n;
  state.counters["allocs_per_step"] = static_cast<double>(allocations) / n;
  state.counters["steps"] = n;
  state.SetIterationTime(sum / n);
}

// A model warmed up on the first 1000 states (a realistic posterior, not the prior).
structgp::WeightSpaceGP WarmModel(const Matrix& Phi, const Matrix& Y) {
  structgp::WeightSpaceGP model(Vector::Ones(Phi.cols()), kNoiseVariance, kJoints);
  for (int i = 0; i < 1000; ++i) {
    model.Update(Phi.row(i).transpose(), Y.row(i).transpose(), kForgetting);
  }
  return model;
}

void BM_ModelStep(benchmark::State& state) {
  const int D = static_cast<int>(state.range(0));
  const Data& data = GetData();
  const auto map = GetMap(D);
  Matrix Phi;
  map->EvaluateRows(data.X, &Phi);
  structgp::WeightSpaceGP model = WarmModel(Phi, data.Y);
  const long steps = Steps();
  std::vector<double> seconds(static_cast<std::size_t>(steps));
  // Column-major copies so that each state's features are contiguous.
  const Matrix PhiT = Phi.transpose();
  const Matrix YT = data.Y.transpose();
  Vector mean(kJoints), latent(kJoints), noisy(kJoints);
  std::size_t allocations = 0;
  for (auto _ : state) {
    const std::size_t before = structgp::testing::TotalAllocations();
    for (long s = 0; s < steps; ++s) {
      const int i = static_cast<int>(s % (kPool - 1));
      const auto a = Clock::now();
      model.UpdateAndPredict(PhiT.col(i), YT.col(i), PhiT.col(i + 1), mean, latent, noisy,
                             kForgetting);
      const auto b = Clock::now();
      benchmark::DoNotOptimize(mean.data());
      seconds[static_cast<std::size_t>(s)] = std::chrono::duration<double>(b - a).count();
    }
    allocations = structgp::testing::TotalAllocations() - before;
  }
  state.counters["D"] = D;
  Report(state, seconds, allocations);
}

void BM_ControlStep(benchmark::State& state) {
  const int D = static_cast<int>(state.range(0));
  const Data& data = GetData();
  const auto map = GetMap(D);
  Matrix Phi;
  map->EvaluateRows(data.X, &Phi);
  structgp::WeightSpaceGP model = WarmModel(Phi, data.Y);
  const long steps = Steps();
  std::vector<double> seconds(static_cast<std::size_t>(steps));
  const Matrix XT = data.X.transpose();
  const Matrix YT = data.Y.transpose();
  Vector phi_u(D), phi_p(D), mean(kJoints), latent(kJoints), noisy(kJoints);
  std::size_t allocations = 0;
  for (auto _ : state) {
    const std::size_t before = structgp::testing::TotalAllocations();
    for (long s = 0; s < steps; ++s) {
      const int i = static_cast<int>(s % (kPool - 1));
      const auto a = Clock::now();
      map->Evaluate(XT.col(i), phi_u);
      map->Evaluate(XT.col(i + 1), phi_p);
      model.UpdateAndPredict(phi_u, YT.col(i), phi_p, mean, latent, noisy, kForgetting);
      const auto b = Clock::now();
      benchmark::DoNotOptimize(mean.data());
      seconds[static_cast<std::size_t>(s)] = std::chrono::duration<double>(b - a).count();
    }
    allocations = structgp::testing::TotalAllocations() - before;
  }
  state.counters["D"] = D;
  Report(state, seconds, allocations);
}

void BM_PredictWhileLearning(benchmark::State& state) {
  const int D = static_cast<int>(state.range(0));
  const bool variance = state.range(1) != 0;
  const Data& data = GetData();
  structgp::OnlineLearnerOptions options;
  options.feature_map = GetMap(D);
  options.num_outputs = kJoints;
  options.noise_variance = kNoiseVariance;
  options.forgetting = kForgetting;
  options.covariance_publish_period = 100;
  options.queue_capacity = 1024;
  structgp::OnlineLearner learner(options);
  const long steps = Steps();
  std::vector<double> seconds(static_cast<std::size_t>(steps));
  const Matrix XT = data.X.transpose();
  const Matrix YT = data.Y.transpose();
  Vector mean(kJoints), latent(kJoints);
  // Warm up: the learner absorbs a first batch, so that the timed loop starts with the learner
  // busy on a realistic posterior.
  for (int i = 0; i < 1000; ++i) learner.Submit(XT.col(i), YT.col(i));
  learner.WaitUntilIdle();
  std::size_t allocations = 0;
  for (auto _ : state) {
    const std::size_t before = structgp::testing::TotalAllocations();
    for (long s = 0; s < steps; ++s) {
      const int i = static_cast<int>(s % (kPool - 1));
      learner.Submit(XT.col(i), YT.col(i));
      const auto a = Clock::now();
      if (variance) {
        learner.PredictWithVariance(XT.col(i + 1), mean, latent);
      } else {
        learner.Predict(XT.col(i + 1), mean);
      }
      const auto b = Clock::now();
      benchmark::DoNotOptimize(mean.data());
      seconds[static_cast<std::size_t>(s)] = std::chrono::duration<double>(b - a).count();
    }
    allocations = structgp::testing::TotalAllocations() - before;
  }
  learner.WaitUntilIdle();
  const structgp::OnlineLearnerSummary summary = learner.summary();
  learner.Stop();
  state.counters["D"] = D;
  state.counters["learner_updates"] = static_cast<double>(summary.updates);
  state.counters["dropped_frac"] =
      static_cast<double>(summary.dropped_queue_full) / static_cast<double>(summary.submitted);
  state.counters["failures"] =
      static_cast<double>(summary.prediction_failures + summary.status_failures());
  Report(state, seconds, allocations);
}

// The copy of OnlineLearner's publish, in a function of its own as there (written inline in the
// benchmark loop, GCC 12 compiles the same statement into a loop several times slower).
__attribute__((noinline)) void CopyUpperTriangle(const Matrix& S, Matrix* slot) {
  for (int j = 0; j < S.cols(); ++j) slot->col(j).head(j + 1) = S.col(j).head(j + 1);
}

void BM_PublishCovariance(benchmark::State& state) {
  const int D = static_cast<int>(state.range(0));
  Matrix S = Matrix::Random(D, D);
  S.triangularView<Eigen::StrictlyLower>().setZero();
  Matrix slot = Matrix::Zero(D, D);
  for (auto _ : state) {
    CopyUpperTriangle(S, &slot);
    benchmark::DoNotOptimize(slot.data());
    benchmark::ClobberMemory();
  }
  state.counters["D"] = D;
  state.counters["MB"] = 8.0 * D * (D + 1) / 2 / 1e6;
}

void Sizes(benchmark::internal::Benchmark* b) {
  for (int D : {128, 256, 512, 1024}) b->Arg(D);
  b->Iterations(1)->UseManualTime()->Unit(benchmark::kMicrosecond);
}

void SizesAndVariance(benchmark::internal::Benchmark* b) {
  for (int variance : {0, 1}) {
    for (int D : {128, 256, 512, 1024}) b->Args({D, variance});
  }
  b->Iterations(1)->UseManualTime()->Unit(benchmark::kMicrosecond);
}

BENCHMARK(BM_ModelStep)->Apply(Sizes);
BENCHMARK(BM_ControlStep)->Apply(Sizes);
BENCHMARK(BM_PredictWhileLearning)->Apply(SizesAndVariance);
BENCHMARK(BM_PublishCovariance)
    ->Arg(128)
    ->Arg(256)
    ->Arg(512)
    ->Arg(1024)
    ->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
