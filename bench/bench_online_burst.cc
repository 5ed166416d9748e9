// The online learner at 7 outputs: how many samples per second it sustains when samples queue
// up (bursts applied in one pass over the factor, WeightSpaceGP::UpdateBatch), the control
// thread's predict-with-variance latency while the learner works, and the regressor form of
// rbd at 7 joints (P = 98).
//
//   build/bench/bench_online_burst --benchmark_counters_tabular=true
//
// - BM_LearnerThroughput/D/K: OnlineLearner without its thread (ProcessPending on this
//   thread); each iteration queues 256 samples and processes them with max_batch = K (K = 1:
//   one rank-one update per sample). items_per_second is the sustained rate in samples/s on
//   one core (CPU time). Features: RandomFeatureMap (21 inputs, D features); forgetting 0.9999.
// - BM_PredictWhileLearning7/D: the learner thread runs (max_batch 16, S published every 50
//   updates); the control thread submits a sample and calls PredictWithVariance in a loop
//   paced at 1 kHz, for 3000 steps per repetition; the prediction alone is timed (features
//   included). Counters p50_us, p99_us, max_us; allocs_per_step must be 0.
// - BM_RbdLearnerUpdate/K: the regressor form on a random 7-joint URDF chain with friction;
//   K samples queued then processed (max_batch K); Time is per iteration, us_per_sample per
//   sample. BM_RbdPredictWithVariance: the control thread's prediction (Psi(x) by KDL, mean
//   and the 7 variances), while no learner runs.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <memory>
#include <random>
#include <thread>
#include <vector>

#include "alloc_counter.h"
#include "structgp/feature/random_feature_map.h"
#include "structgp/feature/rigid_body_regressor_map.h"
#include "structgp/feature/semi_parametric_regressor_map.h"
#include "structgp/online/online_learner.h"
#include "structgp/rigid_body/rigid_body_chain.h"
#include "urdf_test_util.h"

namespace {

using structgp::Matrix;
using structgp::OnlineLearner;
using structgp::OnlineLearnerOptions;
using structgp::Vector;
using Clock = std::chrono::steady_clock;

constexpr int kOutputs = 7;
constexpr int kInputs = 21;
constexpr int kPool = 256;

struct Pool {
  Matrix X, Y;  // kPool x inputs, kPool x outputs
};

Pool MakePool(int inputs, unsigned seed, double torque = 1.0) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Pool p;
  p.X = Matrix::NullaryExpr(kPool, inputs, [&]() { return u(rng); });
  p.Y = Matrix::NullaryExpr(kPool, kOutputs, [&]() { return torque * u(rng); });
  return p;
}

OnlineLearnerOptions FeatureOptions(int D) {
  OnlineLearnerOptions o;
  o.feature_map = std::make_shared<const structgp::RandomFeatureMap>(kInputs, D, 1, 3);
  o.num_outputs = kOutputs;
  o.noise_variance = 0.01;
  o.forgetting = 0.9999;
  o.queue_capacity = kPool;
  return o;
}

void BM_LearnerThroughput(benchmark::State& state) {
  const int D = static_cast<int>(state.range(0));
  OnlineLearnerOptions o = FeatureOptions(D);
  o.max_batch = static_cast<int>(state.range(1));
  o.start_thread = false;
  OnlineLearner learner(o);
  const Pool pool = MakePool(kInputs, 5);
  std::vector<Vector> xs, ys;
  for (int i = 0; i < kPool; ++i) {
    xs.emplace_back(pool.X.row(i).transpose());
    ys.emplace_back(pool.Y.row(i).transpose());
  }
  for (auto _ : state) {
    state.PauseTiming();
    for (int i = 0; i < kPool; ++i) learner.Submit(xs[i], ys[i]);
    state.ResumeTiming();
    benchmark::DoNotOptimize(learner.ProcessPending());
  }
  state.SetItemsProcessed(state.iterations() * kPool);
  state.counters["D"] = D;
  state.counters["failures"] = static_cast<double>(learner.summary().status_failures());
}
BENCHMARK(BM_LearnerThroughput)
    ->ArgsProduct({{256, 512, 1024, 2048}, {1, 16, 32}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->MeasureProcessCPUTime();

void Percentiles(benchmark::State& state, std::vector<double>& us) {
  std::sort(us.begin(), us.end());
  const auto at = [&](double q) { return us[static_cast<size_t>(q * (us.size() - 1))]; };
  state.counters["p50_us"] = at(0.5);
  state.counters["p99_us"] = at(0.99);
  state.counters["max_us"] = us.back();
}

// Paced control loop beside the learner thread: submit, then predict with variance (timed).
void RunPacedLoop(benchmark::State& state, const OnlineLearnerOptions& o, const Pool& pool) {
  const int steps = 3000;
  std::vector<double> us;
  us.reserve(static_cast<size_t>(steps) * 8);
  std::vector<Vector> xs, ys;
  for (int i = 0; i < kPool; ++i) {
    xs.emplace_back(pool.X.row(i).transpose());
    ys.emplace_back(pool.Y.row(i).transpose());
  }
  OnlineLearner learner(o);
  Vector mean(kOutputs), var(kOutputs);
  std::size_t allocations = 0;
  long total = 0;
  for (auto _ : state) {
    const std::size_t before = structgp::testing::TotalAllocations();
    auto next = Clock::now();
    for (int i = 0; i < steps; ++i) {
      next += std::chrono::microseconds(1000);
      learner.Submit(xs[i % kPool], ys[i % kPool]);
      const auto t0 = Clock::now();
      learner.PredictWithVariance(xs[(i + 1) % kPool], mean, var);
      const auto t1 = Clock::now();
      benchmark::DoNotOptimize(var.data());
      us.push_back(std::chrono::duration<double, std::micro>(t1 - t0).count());
      std::this_thread::sleep_until(next);
    }
    allocations += structgp::testing::TotalAllocations() - before;
    total += steps;
    state.SetIterationTime(1e-6 * steps * 1000);
  }
  Percentiles(state, us);
  state.counters["allocs_per_step"] = static_cast<double>(allocations) / total;
  const auto s = learner.summary();
  state.counters["dropped"] = static_cast<double>(s.dropped_queue_full);
  state.counters["passes_per_sample"] =
      s.processed > 0 ? static_cast<double>(s.batches) / s.processed : 0.0;
}

void BM_PredictWhileLearning7(benchmark::State& state) {
  const int D = static_cast<int>(state.range(0));
  OnlineLearnerOptions o = FeatureOptions(D);
  o.max_batch = 16;
  o.covariance_publish_period = 50;
  o.queue_capacity = 4096;
  RunPacedLoop(state, o, MakePool(kInputs, 6));
  state.counters["D"] = D;
}
BENCHMARK(BM_PredictWhileLearning7)
    ->Arg(512)
    ->Arg(1024)
    ->Arg(2048)
    ->Iterations(1)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);

std::shared_ptr<const structgp::RegressorMap> Rbd7() {
  structgp::testing::RandomUrdfOptions u;
  u.num_joints = kOutputs;
  u.seed = 3;
  auto chain = std::make_shared<const structgp::RigidBodyRegressorMap>(
      structgp::RigidBodyChain::FromUrdfString(structgp::testing::RandomUrdf(u)));
  structgp::SemiParametricOptions sp;
  sp.friction = true;
  return std::make_shared<const structgp::SemiParametricRegressorMap>(chain, sp);
}

OnlineLearnerOptions RbdOptions() {
  OnlineLearnerOptions o;
  o.regressor_map = Rbd7();
  o.noise_variance = 0.0025;
  o.forgetting = 0.9999;
  o.queue_capacity = kPool;
  o.covariance_publish_period = 1;
  return o;
}

void BM_RbdLearnerUpdate(benchmark::State& state) {
  const int K = static_cast<int>(state.range(0));
  OnlineLearnerOptions o = RbdOptions();
  o.max_batch = K;
  o.covariance_publish_period = 0;
  o.start_thread = false;
  OnlineLearner learner(o);
  const Pool pool = MakePool(kInputs, 7, 10.0);
  std::vector<Vector> xs, ys;
  for (int i = 0; i < kPool; ++i) {
    xs.emplace_back(pool.X.row(i).transpose());
    ys.emplace_back(pool.Y.row(i).transpose());
  }
  int i = 0;
  for (auto _ : state) {
    state.PauseTiming();
    for (int k = 0; k < K; ++k, i = (i + 1) % kPool) learner.Submit(xs[i], ys[i]);
    state.ResumeTiming();
    benchmark::DoNotOptimize(learner.ProcessPending());
  }
  state.SetItemsProcessed(state.iterations() * K);
  state.counters["us_per_sample"] = benchmark::Counter(
      static_cast<double>(state.iterations() * K),
      benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
  state.counters["P"] = learner.num_features();
}
BENCHMARK(BM_RbdLearnerUpdate)->Arg(1)->Arg(16)->Unit(benchmark::kMicrosecond);

void BM_RbdPredictWithVariance(benchmark::State& state) {
  OnlineLearnerOptions o = RbdOptions();
  o.start_thread = false;
  OnlineLearner learner(o);
  const Pool pool = MakePool(kInputs, 8, 10.0);
  for (int i = 0; i < kPool; ++i) learner.Submit(pool.X.row(i).transpose(), pool.Y.row(i).transpose());
  learner.WaitUntilIdle();
  std::vector<Vector> xs;
  for (int i = 0; i < kPool; ++i) xs.emplace_back(pool.X.row(i).transpose());
  Vector mean(kOutputs), var(kOutputs);
  int i = 0;
  const std::size_t before = structgp::testing::TotalAllocations();
  for (auto _ : state) {
    benchmark::DoNotOptimize(learner.PredictWithVariance(xs[i], mean, var));
    i = (i + 1) % kPool;
  }
  state.counters["allocs_per_call"] =
      static_cast<double>(structgp::testing::TotalAllocations() - before) / state.iterations();
}
BENCHMARK(BM_RbdPredictWithVariance)->Unit(benchmark::kMicrosecond);

// rbd predict-with-variance latency while the regressor learner's thread works (paced 1 kHz).
void BM_RbdPredictWhileLearning(benchmark::State& state) {
  OnlineLearnerOptions o = RbdOptions();
  o.max_batch = 16;
  o.covariance_publish_period = 10;
  RunPacedLoop(state, o, MakePool(kInputs, 9, 10.0));
}
BENCHMARK(BM_RbdPredictWhileLearning)
    ->Iterations(1)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
