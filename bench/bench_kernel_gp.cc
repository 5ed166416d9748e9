// Function-space GP (KernelGP) with an rbf kernel on a 9-dimensional input and 3 outputs:
//  - BM_AddAndPredict: one online step at a fixed size m: add one point, predict mean and
//    variances at the next input (one pass over the packed factor), then Truncate(m) to drop
//    the point again, so every iteration sees the same m;
//  - BM_AddThenPredict: the same step as two calls (two passes over the factor), for
//    comparison;
//  - BM_Predict: PredictWithVariance alone (one pass, one right-hand side);
//  - BM_StreamFactor: a plain sum over m (m + 1) / 2 doubles, the same bytes as one pass over
//    the factor: the memory-bandwidth floor of the steps above on this machine;
//  - BM_Fit: batch fit from scratch;
//  - BM_LogEvidenceGradient: the log evidence with its gradient (type-II maximum likelihood's
//    evaluation: C^{-1} from the factor, O(m^3));
//  - BM_InverseFromFactor / BM_InverseBySolve: C^{-1} from its Cholesky factor by the two
//    triangular recursions of internal/cholesky.h against solving C X = I with the factor
//    (what both evidence gradients did before), at the sizes the evidences see (m = 2400:
//    400 rows of a six-joint Euler-Lagrange GP), on 1 and 2 threads.
//  - BM_Factorize: the factorisation itself (internal::Cholesky) on 1 and 2 threads.
//
//   build/bench/bench_kernel_gp --benchmark_repetitions=10 --benchmark_report_aggregates_only=true
//
// Counter allocs_per_step must be 0 (allocation counter linked in from tests/). The models
// are built once per m and shared by the benchmarks (the fit at m = 4000 takes seconds).

#include <cmath>
#include <cstdlib>
#include <map>
#include <memory>
#include <random>
#include <vector>

#include <benchmark/benchmark.h>

#include "alloc_counter.h"
#include "structgp/internal/cholesky.h"
#include "structgp/kernel/rbf_kernel.h"
#include "structgp/model/kernel_gp.h"

namespace {

using structgp::KernelGP;
using structgp::Matrix;
using structgp::Status;
using structgp::Vector;

constexpr int kInputDim = 9;
constexpr int kOutputs = 3;
constexpr int kPool = 64;  // distinct new points cycled through
constexpr unsigned kSeed = 20240;

struct Data {
  Matrix X;  // m x kInputDim
  Matrix Y;  // m x kOutputs
};

// Inputs in [-1, 1]^9, targets smooth functions of them plus noise.
Data MakeData(int m, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  std::normal_distribution<double> normal;
  Data d;
  d.X = Matrix::NullaryExpr(m, kInputDim, [&]() { return uniform(rng); });
  const Matrix W = Matrix::NullaryExpr(kInputDim, kOutputs, [&]() { return normal(rng); });
  d.Y = (d.X * W).array().sin().matrix() +
        0.1 * Matrix::NullaryExpr(m, kOutputs, [&]() { return normal(rng); });
  return d;
}

structgp::RbfKernel MakeKernel() { return structgp::RbfKernel(kInputDim, false, 1.0, 1.0); }
constexpr double kNoiseVariance = 0.01;

// A model fitted on m points with room for one more, built once per m.
KernelGP& FittedModel(int m) {
  static std::map<int, std::unique_ptr<KernelGP>> models;
  auto& model = models[m];
  if (model == nullptr) {
    const Data data = MakeData(m, kSeed);
    model = std::make_unique<KernelGP>(MakeKernel(), kNoiseVariance, kOutputs);
    if (model->Fit(data.X, data.Y) != Status::kOk) std::abort();
    model->Reserve(m + 1);
  }
  return *model;
}

struct Pool {
  std::vector<Vector> x, y;
};

Pool MakePool() {
  const Data data = MakeData(kPool, kSeed + 1);
  Pool pool;
  for (int i = 0; i < kPool; ++i) {
    pool.x.push_back(data.X.row(i).transpose());
    pool.y.push_back(data.Y.row(i).transpose());
  }
  return pool;
}

void SetCounters(benchmark::State& state, std::size_t allocations, int m) {
  state.counters["allocs_per_step"] =
      benchmark::Counter(static_cast<double>(allocations), benchmark::Counter::kAvgIterations);
  // Bytes of the packed factor read per step (one pass), as a rate.
  state.counters["factor_bytes"] =
      benchmark::Counter(8.0 * m * (m + 1) / 2.0, benchmark::Counter::kIsIterationInvariantRate,
                         benchmark::Counter::kIs1024);
}

void BM_AddAndPredict(benchmark::State& state) {
  const int m = static_cast<int>(state.range(0));
  KernelGP& model = FittedModel(m);
  const Pool pool = MakePool();
  Vector mean(kOutputs), latent(kOutputs), noisy(kOutputs);
  int i = 0;
  const std::size_t allocs_before = structgp::testing::TotalAllocations();
  for (auto _ : state) {
    const Status status =
        model.AddAndPredict(pool.x[i], pool.y[i], pool.x[(i + 1) % kPool], mean, latent, noisy);
    benchmark::DoNotOptimize(status);
    benchmark::DoNotOptimize(mean.data());
    benchmark::DoNotOptimize(latent.data());
    benchmark::ClobberMemory();
    model.Truncate(m);  // forget the point again: O(1)
    i = (i + 1) % kPool;
  }
  SetCounters(state, structgp::testing::TotalAllocations() - allocs_before, m);
}

void BM_AddThenPredict(benchmark::State& state) {
  const int m = static_cast<int>(state.range(0));
  KernelGP& model = FittedModel(m);
  const Pool pool = MakePool();
  Vector mean(kOutputs), latent(kOutputs), noisy(kOutputs);
  int i = 0;
  const std::size_t allocs_before = structgp::testing::TotalAllocations();
  for (auto _ : state) {
    Status status = model.Add(pool.x[i], pool.y[i]);
    benchmark::DoNotOptimize(status);
    status = model.PredictWithVariance(pool.x[(i + 1) % kPool], mean, latent, noisy);
    benchmark::DoNotOptimize(status);
    benchmark::DoNotOptimize(mean.data());
    benchmark::ClobberMemory();
    model.Truncate(m);
    i = (i + 1) % kPool;
  }
  SetCounters(state, structgp::testing::TotalAllocations() - allocs_before, m);
}

void BM_Predict(benchmark::State& state) {
  const int m = static_cast<int>(state.range(0));
  const KernelGP& model = FittedModel(m);
  const Pool pool = MakePool();
  Vector mean(kOutputs), latent(kOutputs), noisy(kOutputs);
  KernelGP::Workspace workspace = model.MakeWorkspace();
  int i = 0;
  const std::size_t allocs_before = structgp::testing::TotalAllocations();
  for (auto _ : state) {
    const Status status = model.PredictWithVariance(pool.x[i], mean, latent, noisy, workspace);
    benchmark::DoNotOptimize(status);
    benchmark::DoNotOptimize(mean.data());
    benchmark::ClobberMemory();
    i = (i + 1) % kPool;
  }
  SetCounters(state, structgp::testing::TotalAllocations() - allocs_before, m);
}

void BM_StreamFactor(benchmark::State& state) {
  const int m = static_cast<int>(state.range(0));
  const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(m) * (m + 1) / 2;
  const Vector buffer = Vector::Constant(n, 1e-3);
  for (auto _ : state) {
    double sum = buffer.sum();  // Eigen's vectorised reduction
    benchmark::DoNotOptimize(sum);
  }
  SetCounters(state, 0, m);
}

void BM_Fit(benchmark::State& state) {
  const int m = static_cast<int>(state.range(0));
  const Data data = MakeData(m, kSeed);
  KernelGP model(MakeKernel(), kNoiseVariance, kOutputs);
  for (auto _ : state) {
    const Status status = model.Fit(data.X, data.Y);
    benchmark::DoNotOptimize(status);
  }
}

void BM_LogEvidenceGradient(benchmark::State& state) {
  const int m = static_cast<int>(state.range(0));
  const Data data = MakeData(m, kSeed);
  KernelGP model(MakeKernel(), kNoiseVariance, kOutputs);
  if (model.Fit(data.X, data.Y) != Status::kOk) {
    state.SkipWithError("fit failed");
    return;
  }
  Vector d_kernel, d_scale;
  double d_noise = 0.0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(model.LogMarginalLikelihood(&d_kernel, &d_noise, &d_scale));
  }
}

// A random symmetric positive definite C (condition ~1e3) and its factor.
Matrix RandomFactor(int m) {
  std::mt19937_64 rng(kSeed);
  std::normal_distribution<double> normal;
  const Matrix A = Matrix::NullaryExpr(m, m, [&]() { return normal(rng); });
  Matrix C = A * A.transpose() / m;
  C.diagonal().array() += 1e-3;
  structgp::internal::Cholesky chol;
  chol.Factorize(C);
  return chol.ReleaseFactor();
}

// Args: m, threads.
void BM_InverseFromFactor(benchmark::State& state) {
  const Matrix L = RandomFactor(static_cast<int>(state.range(0)));
  const int threads = static_cast<int>(state.range(1));
  for (auto _ : state) {
    benchmark::DoNotOptimize(structgp::internal::InverseFromFactor(L, threads).data());
  }
}

// The factorisation of L L^T (internal::Cholesky, no jitter). Args: m, threads.
void BM_Factorize(benchmark::State& state) {
  const Matrix L = RandomFactor(static_cast<int>(state.range(0)));
  const Matrix A = L * L.transpose();
  structgp::internal::CholeskyOptions options{structgp::internal::JitterLadder::kNone};
  options.num_threads = static_cast<int>(state.range(1));
  structgp::internal::Cholesky chol(A.rows());
  for (auto _ : state) {
    if (!IsOk(chol.Factorize(A, options).status)) state.SkipWithError("not positive definite");
    benchmark::DoNotOptimize(chol.factor().data());
  }
}

void BM_InverseBySolve(benchmark::State& state) {
  const Matrix L = RandomFactor(static_cast<int>(state.range(0)));
  const Eigen::Index m = L.rows();
  for (auto _ : state) {
    Matrix X = Matrix::Identity(m, m);
    L.triangularView<Eigen::Lower>().solveInPlace(X);
    L.transpose().triangularView<Eigen::Upper>().solveInPlace(X);
    benchmark::DoNotOptimize(X.data());
  }
}

BENCHMARK(BM_AddAndPredict)->Arg(1000)->Arg(2000)->Arg(4000)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_AddThenPredict)->Arg(1000)->Arg(2000)->Arg(4000)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Predict)->Arg(1000)->Arg(2000)->Arg(4000)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_StreamFactor)->Arg(1000)->Arg(2000)->Arg(4000)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Fit)->Arg(1000)->Arg(2000)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_LogEvidenceGradient)->Arg(1000)->Arg(2000)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_InverseFromFactor)
    ->ArgNames({"m", "threads"})
    ->ArgsProduct({{1000, 2400}, {1, 2}})
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Factorize)
    ->ArgNames({"m", "threads"})
    ->ArgsProduct({{1000, 2400}, {1, 2}})
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_InverseBySolve)->Arg(1000)->Arg(2400)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
