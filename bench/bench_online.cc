// Online step of the weight-space GP: rank-one update of the shared factor, weights kept
// current, predictive mean and variance at the next state, for 7 outputs.
//
//   build/bench/bench_online --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
//
// Counters: allocs_per_step must be 0 (allocation counter linked in from tests/).

#include <random>

#include <Eigen/Cholesky>
#include <benchmark/benchmark.h>

#include "alloc_counter.h"
#include "structgp/model/weight_space_gp.h"

namespace {

using structgp::Matrix;
using structgp::Vector;

constexpr int kOutputs = 7;
constexpr int kPool = 256;  // distinct samples cycled through

struct Data {
  Matrix Phi;  // kPool x D
  Matrix Y;    // kPool x P
};

Data MakeData(int D, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal;
  Data d;
  d.Phi = Matrix::NullaryExpr(kPool, D, [&]() { return normal(rng); }) / std::sqrt(D);
  d.Y = Matrix::NullaryExpr(kPool, kOutputs, [&]() { return normal(rng); });
  return d;
}

void BM_OnlineStep(benchmark::State& state) {
  const int D = static_cast<int>(state.range(0));
  const Data data = MakeData(D, 7);
  structgp::WeightSpaceGP model(Vector::Ones(D), 0.01, kOutputs);
  Vector phi(D), phi_next(D), y(kOutputs), mean(kOutputs), latent(kOutputs), noisy(kOutputs);
  int i = 0;
  // Warm up: a few hundred samples so that the factor is a realistic posterior.
  for (int k = 0; k < 2 * kPool; ++k) {
    model.Update(data.Phi.row(k % kPool).transpose(), data.Y.row(k % kPool).transpose());
  }
  const std::size_t allocs_before = structgp::testing::TotalAllocations();
  for (auto _ : state) {
    phi = data.Phi.row(i).transpose();
    phi_next = data.Phi.row((i + 1) % kPool).transpose();
    y = data.Y.row(i).transpose();
    const auto status =
        model.UpdateAndPredict(phi, y, phi_next, mean, latent, noisy, /*forgetting=*/0.9999);
    benchmark::DoNotOptimize(status);
    benchmark::DoNotOptimize(mean.data());
    benchmark::DoNotOptimize(latent.data());
    i = (i + 1) % kPool;
  }
  state.counters["allocs_per_step"] = benchmark::Counter(
      static_cast<double>(structgp::testing::TotalAllocations() - allocs_before) /
      static_cast<double>(state.iterations()));
  state.counters["D"] = D;
}
BENCHMARK(BM_OnlineStep)->RangeMultiplier(2)->Range(64, 2048)->Unit(benchmark::kMicrosecond);

// Predict only (mean + variance), the control thread's share.
void BM_PredictWithVariance(benchmark::State& state) {
  const int D = static_cast<int>(state.range(0));
  const Data data = MakeData(D, 8);
  structgp::WeightSpaceGP model(Vector::Ones(D), 0.01, kOutputs);
  for (int k = 0; k < kPool; ++k) {
    model.Update(data.Phi.row(k).transpose(), data.Y.row(k).transpose());
  }
  Vector phi(D), mean(kOutputs), latent(kOutputs), noisy(kOutputs);
  int i = 0;
  for (auto _ : state) {
    phi = data.Phi.row(i).transpose();
    benchmark::DoNotOptimize(model.PredictWithVariance(phi, mean, latent, noisy));
    i = (i + 1) % kPool;
  }
}
BENCHMARK(BM_PredictWithVariance)->RangeMultiplier(2)->Range(64, 2048)->Unit(benchmark::kMicrosecond);

// Reference point: the straightforward route with Eigen's LLT::rankUpdate on the precision
// factor, then a 7-column solve for the weights and a triangular solve for the variance.
void BM_EigenLltBaseline(benchmark::State& state) {
  const int D = static_cast<int>(state.range(0));
  const Data data = MakeData(D, 9);
  Matrix A = Matrix::Identity(D, D) * 0.01;
  Matrix B = Matrix::Zero(D, kOutputs);
  for (int k = 0; k < kPool; ++k) {
    A += data.Phi.row(k).transpose() * data.Phi.row(k);
    B += data.Phi.row(k).transpose() * data.Y.row(k);
  }
  Eigen::LLT<Matrix> llt(A);
  Matrix W(D, kOutputs);
  Vector phi(D), v(D);
  int i = 0;
  for (auto _ : state) {
    phi = data.Phi.row(i).transpose();
    llt.rankUpdate(phi);
    B.noalias() += phi * data.Y.row(i);
    W = llt.solve(B);
    v = llt.matrixL().solve(data.Phi.row((i + 1) % kPool).transpose());
    benchmark::DoNotOptimize(W.data());
    benchmark::DoNotOptimize(v.squaredNorm());
    i = (i + 1) % kPool;
  }
}
BENCHMARK(BM_EigenLltBaseline)->Arg(512)->Unit(benchmark::kMicrosecond);

// Batch fit: sufficient statistics of m samples (BLAS-3) and one O(D^3) factorisation.
void BM_BatchFit(benchmark::State& state) {
  const int m = static_cast<int>(state.range(0));
  const int D = static_cast<int>(state.range(1));
  std::mt19937_64 rng(10);
  std::normal_distribution<double> normal;
  const Matrix Phi = Matrix::NullaryExpr(m, D, [&]() { return normal(rng); });
  const Matrix Y = Matrix::NullaryExpr(m, kOutputs, [&]() { return normal(rng); });
  structgp::WeightSpaceGP model(Vector::Ones(D), 0.01, kOutputs);
  for (auto _ : state) {
    benchmark::DoNotOptimize(model.Fit(Phi, Y));
  }
}
BENCHMARK(BM_BatchFit)->Args({10000, 512})->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
