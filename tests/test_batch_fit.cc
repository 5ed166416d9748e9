// Batch training on large data sets: the chunked, multi-threaded accumulation of Phi^T Phi
// against the plain product of the whole feature matrix, thread counts against one thread,
// and the function-space form's evenly spaced subset against a model fitted on those rows.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <random>

#include "structgp/feature/pol_feature_map.h"
#include "structgp/feature/random_feature_map.h"
#include "structgp/kernel/rbf_kernel.h"
#include "structgp/model/gaussian_process.h"
#include "structgp/model/sufficient_statistics.h"

namespace structgp {
namespace {

// Fixed seed; printed so that a failure can be replayed.
constexpr unsigned kSeed = 20261201;

struct Data {
  Matrix X, Y;
};

Data MakeData(Eigen::Index m, int d, int P, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> uniform(-2.0, 2.0);
  Data data;
  data.X = Matrix::NullaryExpr(m, d, [&]() { return uniform(rng); });
  data.Y = Matrix::NullaryExpr(m, P, [&]() { return uniform(rng); });
  return data;
}

// Largest |a - b| relative to the largest |b| (lower triangles of square matrices).
double RelativeLower(const Matrix& a, const Matrix& b) {
  const Matrix al = a.triangularView<Eigen::Lower>();
  const Matrix bl = b.triangularView<Eigen::Lower>();
  return (al - bl).cwiseAbs().maxCoeff() / bl.cwiseAbs().maxCoeff();
}

double Relative(const Matrix& a, const Matrix& b) {
  return (a - b).cwiseAbs().maxCoeff() / b.cwiseAbs().maxCoeff();
}

// Sums of m products: rounding differences between summation orders are bounded by about
// m * epsilon relative to the sum of magnitudes; the entries here are sums of like-signed
// and mixed terms of similar size, so 1e-12 relative to the largest entry is ample at m ~ 1e4
// and still 1000x below any real mistake (a lost or doubled chunk changes entries by ~1e-1).
constexpr double kSumTolerance = 1e-12;

TEST(AccumulateStatistics, EqualsThePlainProductForAnyChunkAndThreadCount) {
  std::printf("[ seed     ] %u\n", kSeed);
  const PolFeatureMap map(2);  // D = 133
  const Data data = MakeData(2345, map.input_dim(), 2, kSeed);
  Matrix Phi;
  map.EvaluateRows(data.X, &Phi);
  const Matrix gram = Phi.transpose() * Phi;  // independent reference: one plain GEMM
  const Matrix cross = Phi.transpose() * data.Y;
  const Vector y2 = data.Y.colwise().squaredNorm().transpose();
  for (const Eigen::Index chunk : {1, 100, 1024, 5000}) {
    for (const int threads : {1, 2, 3, 4}) {
      AccumulateOptions options;
      options.chunk_rows = chunk;
      options.num_threads = threads;
      const SufficientStatistics s = AccumulateStatistics(map, data.X, data.Y, options);
      EXPECT_EQ(s.count, 2345.0);
      EXPECT_LT(RelativeLower(s.gram, gram), kSumTolerance) << chunk << " " << threads;
      EXPECT_LT(Relative(s.cross, cross), kSumTolerance) << chunk << " " << threads;
      EXPECT_LT(Relative(s.y_squared, y2), kSumTolerance) << chunk << " " << threads;
    }
  }
}

TEST(AccumulateStatistics, ThreadsGiveTheSingleThreadResult) {
  const RandomFeatureMap map(9, 256, 4, kSeed);
  const Data data = MakeData(6000, 9, 3, kSeed + 1);
  AccumulateOptions one;
  const SufficientStatistics a = AccumulateStatistics(map, data.X, data.Y, one);
  for (const int threads : {2, 7}) {
    AccumulateOptions many;
    many.num_threads = threads;
    const SufficientStatistics b = AccumulateStatistics(map, data.X, data.Y, many);
    const double gram = RelativeLower(b.gram, a.gram);
    std::printf("  %d threads: relative difference of Phi^T Phi %.2e, of Phi^T Y %.2e\n", threads,
                gram, Relative(b.cross, a.cross));
    EXPECT_LT(gram, kSumTolerance);
    EXPECT_LT(Relative(b.cross, a.cross), kSumTolerance);
    EXPECT_EQ(b.count, a.count);
    // Reproducible for a given thread count.
    const SufficientStatistics c = AccumulateStatistics(map, data.X, data.Y, many);
    EXPECT_EQ(Matrix(c.gram.triangularView<Eigen::Lower>()),
              Matrix(b.gram.triangularView<Eigen::Lower>()));
  }
}

TEST(AccumulateStatistics, TransposedAndMergedAgreeWithAccumulate) {
  const PolFeatureMap map(1);
  const Data data = MakeData(300, map.input_dim(), 1, kSeed + 2);
  Matrix Phi;
  map.EvaluateRows(data.X, &Phi);
  SufficientStatistics a(map.dim(), 1), b(map.dim(), 1), c(map.dim(), 1);
  a.Accumulate(Phi, data.Y);
  b.AccumulateTransposed(Phi.topRows(100).transpose(), data.Y.topRows(100));
  c.AccumulateTransposed(Phi.bottomRows(200).transpose(), data.Y.bottomRows(200));
  b.Merge(c);
  EXPECT_LT(RelativeLower(b.gram, a.gram), kSumTolerance);
  EXPECT_LT(Relative(b.cross, a.cross), kSumTolerance);
  EXPECT_EQ(b.count, 300.0);
  EXPECT_THROW(b.Merge(SufficientStatistics(3, 1)), std::invalid_argument);
}

TEST(AccumulateStatistics, RejectsBadInput) {
  const PolFeatureMap map(1);
  Data data = MakeData(10, map.input_dim(), 1, kSeed + 3);
  AccumulateOptions options;
  options.num_threads = 0;
  EXPECT_THROW(AccumulateStatistics(map, data.X, data.Y, options), std::invalid_argument);
  options = AccumulateOptions();
  options.chunk_rows = 0;
  EXPECT_THROW(AccumulateStatistics(map, data.X, data.Y, options), std::invalid_argument);
  data.X(4, 1) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(AccumulateStatistics(map, data.X, data.Y), std::invalid_argument);
  EXPECT_THROW(AccumulateStatistics(map, data.X.leftCols(2), data.Y), std::invalid_argument);
}

TEST(GaussianProcessBatch, ThreadedFitEqualsSingleThreadFit) {
  auto map = std::make_shared<PolFeatureMap>(2);
  const Hyperparameters h = DefaultHyperparameters(*map, 2);
  const Data data = MakeData(5000, map->input_dim(), 2, kSeed + 4);
  GaussianProcess one(map, h, 2, Form::kWeightSpace);
  BatchFitOptions batch;
  batch.num_threads = 2;
  batch.chunk_rows = 333;
  GaussianProcess two(map, h, 2, Form::kWeightSpace, batch);
  ASSERT_EQ(one.Fit(data.X, data.Y), Status::kOk);
  ASSERT_EQ(two.Fit(data.X, data.Y), Status::kOk);
  const double w = Relative(two.weight_space()->weights(), one.weight_space()->weights());
  std::printf("  relative difference of the posterior weights: %.2e\n", w);
  // The weights amplify the statistics' rounding (~1e-16) by up to the condition number of A;
  // 1e-11 leaves room for that and still catches any real difference.
  EXPECT_LT(w, 1e-11);
  EXPECT_NEAR(two.LogMarginalLikelihood(), one.LogMarginalLikelihood(),
              1e-9 * std::abs(one.LogMarginalLikelihood()));
  EXPECT_FALSE(two.subsampled());
  EXPECT_EQ(two.fit_rows(), 5000);
}

TEST(GaussianProcessBatch, FunctionSpaceTakesAnEvenlySpacedSubsetBeyondTheLimit) {
  const RbfKernel kernel(3, /*ard=*/false);
  const Data data = MakeData(230, 3, 2, kSeed + 5);
  BatchFitOptions batch;
  batch.max_kernel_rows = 50;
  Hyperparameters h = DefaultHyperparameters(kernel, 2);
  h.log_noise_std = 0.5 * std::log(0.1);
  GaussianProcess gp(kernel, h, 2, batch);
  ASSERT_EQ(gp.Fit(data.X, data.Y), Status::kOk);
  EXPECT_TRUE(gp.subsampled());
  EXPECT_EQ(gp.fit_rows(), 50);
  EXPECT_EQ(gp.data_rows(), 230);
  // Reference: an exact GP fitted on rows floor(k 230 / 50), k = 0..49.
  Matrix Xs(50, 3), Ys(50, 2);
  for (int k = 0; k < 50; ++k) {
    Xs.row(k) = data.X.row(k * 230 / 50);
    Ys.row(k) = data.Y.row(k * 230 / 50);
  }
  KernelGP reference(kernel, h.noise_variance(), 2);
  ASSERT_EQ(reference.Fit(Xs, Ys), Status::kOk);
  EXPECT_EQ(gp.function_space()->inputs(), reference.inputs());
  Vector a(2), b(2);
  const Vector x = data.X.row(7).transpose();
  ASSERT_EQ(gp.Predict(x, a), Status::kOk);
  ASSERT_EQ(reference.Predict(x, b), Status::kOk);
  EXPECT_LT((a - b).cwiseAbs().maxCoeff(), 1e-12);
  // No limit: every row.
  batch.max_kernel_rows = 0;
  GaussianProcess all(kernel, h, 2, batch);
  ASSERT_EQ(all.Fit(data.X, data.Y), Status::kOk);
  EXPECT_FALSE(all.subsampled());
  EXPECT_EQ(all.function_space()->size(), 230);
  // A feature-map model in function space obeys the same limit.
  auto map = std::make_shared<PolFeatureMap>(2);
  batch.max_kernel_rows = 40;
  GaussianProcess pol(map, DefaultHyperparameters(*map, 2), 2, Form::kFunctionSpace, batch);
  const Data states = MakeData(100, map->input_dim(), 2, kSeed + 6);
  ASSERT_EQ(pol.Fit(states.X, states.Y), Status::kOk);
  EXPECT_EQ(pol.function_space()->size(), 40);
  batch.num_threads = 0;
  EXPECT_THROW(GaussianProcess(kernel, h, 2, batch), std::invalid_argument);
}

}  // namespace
}  // namespace structgp
