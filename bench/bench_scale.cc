// Batch training on 10^4..10^6 samples: time and peak memory of a weight-space fit (streamed,
// multi-threaded accumulation of Phi^T Phi, then one O(D^3) factorisation) for D = 133 (the
// 2-joint k_pol map) and D = 512 (random features on the same 6 inputs), 1 and 2 threads.
//
// Peak memory: the kernel's peak resident set size is reset before each fit (writing 5 to
// /proc/self/clear_refs) and read after it (VmHWM in /proc/self/status); the counter
// extra_MiB is that peak minus the resident size before the fit, i.e. what the fit itself
// needed on top of the data (the data, m x 8 doubles, are made before and not counted;
// main fixes glibc's mmap threshold so that released blocks leave the resident set).
// bound_MiB is the design bound threads x (D^2 + chunk x D) doubles plus the D^2 factor
// and the Cholesky work of WeightSpaceGP::Fit.
//
// BM_EulerLagrangeDtc: the lagk posterior (EulerLagrangeGP::Condition) of a 6-joint arm on m
// states through p inducing states (DTC), 1 and 2 workers: time and peak memory, against the
// (p N) x (m N) cross-covariance that the whole-matrix form held at once (whole_V_MiB).
//
// BM_EulerLagrangeRestoreDtc: the same posterior restored from the factors of that Condition
// (EulerLagrangeGP::RestoreDtc, what loading a model file with its posterior file does: only
// K_ZZ formed and factorised again), against BM_EulerLagrangeDtc's time.
//
// BM_EulerLagrangeEvidence: one evaluation of lagk's evidence and its gradient
// (EulerLagrangeEvidence::Evaluate, what each step of its hyper-parameter search costs) for a
// 6-joint arm on m rows (m N values: 400 rows are the CLI's default at six joints, 342 at
// seven), every part searched, on 1 and 2 threads.
//
//   build/bench/bench_scale --benchmark_counters_tabular=true

#include <benchmark/benchmark.h>
#include <malloc.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <map>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "structgp/feature/pol_feature_map.h"
#include "structgp/feature/random_feature_map.h"
#include "structgp/model/euler_lagrange_gp.h"
#include "structgp/model/gaussian_process.h"

namespace structgp {
namespace {

constexpr int kJoints = 2;
constexpr int kInputs = 3 * kJoints;
constexpr int kOutputs = kJoints;

struct Data {
  Matrix X, Y;
};

// One data set per m, made once (uniform states, random torques; only the cost matters).
const Data& DataOfSize(Eigen::Index m) {
  static std::map<Eigen::Index, Data> cache;
  auto it = cache.find(m);
  if (it != cache.end()) return it->second;
  std::mt19937_64 rng(12345);
  std::uniform_real_distribution<double> uniform(-2.0, 2.0);
  Data d;
  d.X = Matrix::NullaryExpr(m, kInputs, [&]() { return uniform(rng); });
  d.Y = Matrix::NullaryExpr(m, kOutputs, [&]() { return uniform(rng); });
  return cache.emplace(m, std::move(d)).first->second;
}

// Reads a "Name:   123 kB" line of /proc/self/status [MiB]; -1 when unavailable.
double StatusMiB(const char* name) {
  std::ifstream in("/proc/self/status");
  std::string line;
  const std::size_t n = std::strlen(name);
  while (std::getline(in, line)) {
    if (line.compare(0, n, name) == 0 && line.size() > n && line[n] == ':') {
      return std::stod(line.substr(n + 1)) / 1024.0;
    }
  }
  return -1.0;
}

// Resets the peak resident set size (Linux >= 4.0); false when not permitted.
bool ResetPeak() {
  std::ofstream out("/proc/self/clear_refs");
  out << "5";
  out.flush();
  return static_cast<bool>(out);
}

std::shared_ptr<const FeatureMap> MapOfSize(int d) {
  if (d == 133) return std::make_shared<PolFeatureMap>(kJoints);
  return std::make_shared<RandomFeatureMap>(kInputs, d, 1, 7);
}

// Args: m, D (133 = pol, else random features), threads.
void BM_BatchFitLarge(benchmark::State& state) {
  const Eigen::Index m = state.range(0);
  const int d = static_cast<int>(state.range(1));
  const int threads = static_cast<int>(state.range(2));
  const Data& data = DataOfSize(m);
  const auto map = MapOfSize(d);
  const Hyperparameters h = DefaultHyperparameters(*map, kOutputs);
  BatchFitOptions batch;
  batch.num_threads = threads;
  double extra = 0.0;
  for (auto _ : state) {
    GaussianProcess gp(map, h, kOutputs, Form::kWeightSpace, batch);
    const bool reset = ResetPeak();
    const double before = StatusMiB("VmRSS");
    if (gp.Fit(data.X, data.Y) != Status::kOk) state.SkipWithError("fit failed");
    extra = reset ? StatusMiB("VmHWM") - before : -1.0;
    benchmark::DoNotOptimize(gp.weight_space()->weights().data());
  }
  const double D = map->dim();
  const double mib = 8.0 / (1024.0 * 1024.0);
  state.counters["D"] = D;
  state.counters["extra_MiB"] = extra;
  // Per worker a D x D sum and a D x chunk block; with several workers also the total; then
  // WeightSpaceGP::Fit's factor and work matrices (about 3 D x D).
  state.counters["bound_MiB"] = (threads * (D * D + static_cast<double>(batch.chunk_rows) * D) +
                                 (threads > 1 ? D * D : 0.0) + 3.0 * D * D) *
                                mib;
  state.counters["data_MiB"] = static_cast<double>(m) * (kInputs + kOutputs) * mib;
  state.counters["samples_per_s"] =
      benchmark::Counter(static_cast<double>(m), benchmark::Counter::kIsIterationInvariantRate);
}

// The statistics alone, new path (features written column by column into D x chunk, one
// thread) against the earlier one (FeatureMap::EvaluateRows into a chunk x D matrix, then
// SufficientStatistics::Accumulate). Args: m, D, 0 = earlier path / 1 = new path.
void BM_Statistics(benchmark::State& state) {
  const Eigen::Index m = state.range(0);
  const auto map = MapOfSize(static_cast<int>(state.range(1)));
  const Data& data = DataOfSize(m);
  for (auto _ : state) {
    if (state.range(2) == 1) {
      const SufficientStatistics s = AccumulateStatistics(*map, data.X, data.Y);
      benchmark::DoNotOptimize(s.gram.data());
    } else {
      SufficientStatistics s(map->dim(), kOutputs);
      Matrix Phi;
      for (Eigen::Index begin = 0; begin < m; begin += kDefaultChunkRows) {
        const Eigen::Index rows = std::min(kDefaultChunkRows, m - begin);
        map->EvaluateRows(data.X.middleRows(begin, rows), &Phi);
        s.Accumulate(Phi, data.Y.middleRows(begin, rows));
      }
      benchmark::DoNotOptimize(s.gram.data());
    }
  }
}

// Random states and torques of a 6-joint arm on m rows, the first p the inducing states, and
// the hyper-parameters of the DTC benchmarks (only the cost matters).
struct DtcProblem {
  static constexpr int n = 6;
  Matrix X, Y, Z;
  EulerLagrangeGPHyperparameters h;
  DtcProblem(Eigen::Index m, Eigen::Index p) {
    std::mt19937_64 rng(12345);
    std::uniform_real_distribution<double> uniform(-2.0, 2.0);
    X = Matrix::NullaryExpr(m, 3 * n, [&]() { return uniform(rng); });
    Y = Matrix::NullaryExpr(m, n, [&]() { return uniform(rng); });
    Z = X.topRows(p);
    h.sigma = 3.0;
    h.part_weights = Vector::Ones(2 * n);
    h.noise_std = Vector::Constant(n, 0.1);
  }
};

// Args: m, p, workers.
void BM_EulerLagrangeDtc(benchmark::State& state) {
  const Eigen::Index m = state.range(0), p = state.range(1);
  const int workers = static_cast<int>(state.range(2));
  const DtcProblem problem(m, p);
  const int n = DtcProblem::n;
  const Matrix &X = problem.X, &Y = problem.Y, &Z = problem.Z;
  const EulerLagrangeGPHyperparameters& h = problem.h;
  double extra = 0.0;
  for (auto _ : state) {
    EulerLagrangeGP gp(h);
    const bool reset = ResetPeak();
    const double before = StatusMiB("VmRSS");
    if (gp.Condition(X, Y, Z, workers) != Status::kOk) state.SkipWithError("condition failed");
    extra = reset ? StatusMiB("VmHWM") - before : -1.0;
    benchmark::DoNotOptimize(gp.LogMarginalLikelihood());
  }
  const double mib = 8.0 / (1024.0 * 1024.0);
  state.counters["extra_MiB"] = extra;
  state.counters["whole_V_MiB"] = static_cast<double>(p * n) * static_cast<double>(m * n) * mib;
}

// Args: m, p. The data of BM_EulerLagrangeDtc; its Condition runs once, before the timing.
void BM_EulerLagrangeRestoreDtc(benchmark::State& state) {
  const DtcProblem problem(state.range(0), state.range(1));
  const Matrix &X = problem.X, &Y = problem.Y, &Z = problem.Z;
  const EulerLagrangeGPHyperparameters& h = problem.h;
  EulerLagrangeGP conditioned(h);
  if (conditioned.Condition(X, Y, Z, 2) != Status::kOk) {
    state.SkipWithError("condition failed");
    return;
  }
  const EulerLagrangeGP::DtcFactors factors{conditioned.dtc_alpha(), conditioned.dtc_factor_b(),
                                            conditioned.LogMarginalLikelihood()};
  double extra = 0.0;
  for (auto _ : state) {
    EulerLagrangeGP gp(h);
    EulerLagrangeGP::DtcFactors copy = factors;  // what the posterior file holds, read
    const bool reset = ResetPeak();
    const double before = StatusMiB("VmRSS");
    if (gp.RestoreDtc(X, Y, Z, std::move(copy)) != Status::kOk) state.SkipWithError("restore failed");
    extra = reset ? StatusMiB("VmHWM") - before : -1.0;
    benchmark::DoNotOptimize(gp.LogMarginalLikelihood());
  }
  state.counters["extra_MiB"] = extra;
}

// Args: m, threads. Random states and torques of a 6-joint arm (only the cost matters).
void BM_EulerLagrangeEvidence(benchmark::State& state) {
  constexpr int n = 6;
  const Eigen::Index m = state.range(0);
  const int threads = static_cast<int>(state.range(1));
  std::mt19937_64 rng(12345);
  std::uniform_real_distribution<double> uniform(-2.0, 2.0);
  const Matrix X = Matrix::NullaryExpr(m, 3 * n, [&]() { return uniform(rng); });
  const Matrix Y = Matrix::NullaryExpr(m, n, [&]() { return uniform(rng); });
  EulerLagrangeGPHyperparameters h;
  h.sigma = 3.0;
  h.part_weights = Vector::Ones(2 * n);
  h.noise_std = Vector::Constant(n, 0.1);
  std::vector<int> parts(2 * n);
  for (int k = 0; k < 2 * n; ++k) parts[static_cast<size_t>(k)] = k;
  const EulerLagrangeEvidence evidence(h, X, Y, parts, nullptr, threads);
  const Vector log_parameters = Vector::Zero(evidence.num_parameters());
  Vector gradient(evidence.num_parameters());
  for (auto _ : state) {
    const double value = evidence.Evaluate(log_parameters.data(), gradient.data());
    if (!std::isfinite(value)) state.SkipWithError("evidence not finite");
    benchmark::DoNotOptimize(value);
  }
  state.counters["values"] = static_cast<double>(m * n);
}

BENCHMARK(BM_EulerLagrangeEvidence)
    ->ArgNames({"m", "threads"})
    ->ArgsProduct({{400}, {1, 2}})
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);

BENCHMARK(BM_EulerLagrangeDtc)
    ->ArgNames({"m", "p", "workers"})
    ->ArgsProduct({{4000}, {400}, {1, 2}})
    ->Iterations(1)
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_EulerLagrangeRestoreDtc)
    ->ArgNames({"m", "p"})
    ->Args({4000, 400})
    ->Iterations(1)
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);

BENCHMARK(BM_Statistics)
    ->ArgNames({"m", "D", "new"})
    ->ArgsProduct({{100000}, {133, 512}, {0, 1}})
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);

BENCHMARK(BM_BatchFitLarge)
    ->ArgNames({"m", "D", "threads"})
    ->ArgsProduct({{10000, 100000, 1000000}, {133, 512}, {1, 2}})
    ->Iterations(1)
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace structgp

int main(int argc, char** argv) {
  // Fixed mmap threshold: every block above 128 KiB (a D x D matrix, a chunk of features) is
  // mapped on allocation and unmapped on release, so the resident size follows the live
  // memory; with glibc's default sliding threshold a released block would stay resident
  // and a later fit could reuse it without raising the peak.
  mallopt(M_MMAP_THRESHOLD, 128 * 1024);
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
