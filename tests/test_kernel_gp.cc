// KernelGP against independent references: WeightSpaceGP with the same feature map (the
// function-space / weight-space twin), a dense evaluation of the likelihood, a batch Fit for
// points added one by one, central finite differences for the likelihood gradient; plus
// every failure mode of the real-time API and a proof that it does not allocate.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <iostream>
#include <limits>
#include <memory>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Cholesky>

#include "alloc_counter.h"
#include "structgp/feature/random_feature_map.h"
#include "structgp/feature/feature_hyperparameters.h"
#include "structgp/kernel/feature_kernel.h"
#include "structgp/kernel/rbf_kernel.h"
#include "structgp/model/kernel_gp.h"
#include "structgp/model/weight_space_gp.h"

namespace structgp {
namespace {

constexpr double kLog2Pi = 1.8378770664093453;

// Seeds are fixed; each test prints the seeds it uses so a failure can be replayed.
std::mt19937_64 SeededRng(std::uint64_t seed) {
  std::cout << "[ seed     ] " << seed << std::endl;
  return std::mt19937_64(seed);
}

Matrix RandomMatrix(int rows, int cols, double scale, std::mt19937_64* rng) {
  std::normal_distribution<double> normal(0.0, scale);
  return Matrix::NullaryExpr(rows, cols, [&]() { return normal(*rng); });
}

Vector RandomVector(int size, double scale, std::mt19937_64* rng) {
  std::normal_distribution<double> normal(0.0, scale);
  return Vector::NullaryExpr(size, [&]() { return normal(*rng); });
}

struct Data {
  Matrix X;  // m x input_dim
  Matrix Y;  // m x P
};

// Smooth targets (sines of random projections) plus noise of standard deviation 0.1.
Data MakeData(int m, int input_dim, int P, std::mt19937_64* rng) {
  Data d;
  d.X = RandomMatrix(m, input_dim, 1.0, rng);
  const Matrix W = RandomMatrix(input_dim, P, 1.0, rng);
  d.Y = (d.X * W).array().sin().matrix() + RandomMatrix(m, P, 0.1, rng);
  return d;
}

// |a - b| <= rel * max(|a|, |b|, floor), entry by entry.
void ExpectRelNear(const Vector& a, const Vector& b, double rel, double floor,
                   const std::string& what) {
  ASSERT_EQ(a.size(), b.size()) << what;
  for (Eigen::Index i = 0; i < a.size(); ++i) {
    const double scale = std::max({std::abs(a[i]), std::abs(b[i]), floor});
    EXPECT_LE(std::abs(a[i] - b[i]), rel * scale)
        << what << "[" << i << "]: " << a[i] << " vs " << b[i];
  }
}

// log p(Y) from a dense Cholesky of s_j^2 (K + sigma_n^2 I), independently of KernelGP.
double DenseLogLikelihood(const Kernel& kernel, double noise_variance, const Vector& scales,
                          const Data& d) {
  Matrix K;
  kernel.Gram(d.X, d.X, &K);
  K.diagonal().array() += noise_variance;
  const Eigen::LLT<Matrix> llt(K);
  const double log_det = 2.0 * Matrix(llt.matrixL()).diagonal().array().log().sum();
  const double m = static_cast<double>(d.X.rows());
  double value = 0.0;
  for (int j = 0; j < d.Y.cols(); ++j) {
    const double s2 = scales[j] * scales[j];
    value += -0.5 * d.Y.col(j).dot(llt.solve(d.Y.col(j))) / s2 -
             0.5 * (log_det + m * std::log(s2)) - 0.5 * m * kLog2Pi;
  }
  return value;
}

struct Prediction {
  Vector mean, latent, noisy;
};

Prediction PredictAt(const KernelGP& model, const Vector& x) {
  Prediction p;
  p.mean.resize(model.num_outputs());
  p.latent.resize(model.num_outputs());
  p.noisy.resize(model.num_outputs());
  KernelGP::Workspace workspace = model.MakeWorkspace();
  EXPECT_EQ(model.PredictWithVariance(x, p.mean, p.latent, p.noisy, workspace), Status::kOk);
  return p;
}

// ---------------------------------------------------------------------------------------
// (a) Function space vs weight space.

// Both forms solve the same Gaussian conditioning exactly, through backward-stable Cholesky
// factorisations of C = Phi Lambda Phi^T + sigma^2 I (m x m) and A = Phi^T Phi + sigma^2
// Lambda^{-1} (D x D). With sigma_n = 0.2 and O(1) features the condition numbers are
// <= ~1e5, so the forms agree to ~1e-11 relative; 1e-8 only fails on a real discrepancy.
// Variances are compared relative to the prior variance s^2 (k(x,x) + sigma^2), which is
// the scale at which they are computed (a posterior variance is a difference of terms of
// that size).
TEST(KernelGP, FeatureKernelMatchesWeightSpaceGP) {
  const int P = 2;
  for (std::uint64_t seed : {11u, 12u, 13u}) {
    // More points than features, and fewer.
    for (const auto& [m, D] : {std::pair<int, int>{60, 25}, std::pair<int, int>{25, 60}}) {
      SCOPED_TRACE("seed " + std::to_string(seed) + ", m " + std::to_string(m) + ", D " +
                   std::to_string(D));
      auto rng = SeededRng(seed);
      auto map = std::make_shared<RandomFeatureMap>(3, D, 3, seed + 1000);
      Hyperparameters h = DefaultHyperparameters(*map, P);
      h.shape = RandomVector(1, 0.3, &rng);
      h.log_block_scale = RandomVector(3, 0.3, &rng);
      h.log_noise_std = std::log(0.2);
      h.log_output_scale = RandomVector(P, 0.3, &rng);
      const Data d = MakeData(m, 3, P, &rng);

      WeightSpaceGP weight_space(PriorVariance(*map, h), h.noise_variance(), P, h.output_scales());
      Matrix Phi;
      map->EvaluateRows(d.X, &Phi);
      ASSERT_EQ(weight_space.Fit(Phi, d.Y), Status::kOk);

      const FeatureKernel kernel(map, h);
      KernelGP model(kernel, h.noise_variance(), P, h.output_scales());
      ASSERT_EQ(model.Fit(d.X, d.Y), Status::kOk);

      const double lml = model.LogMarginalLikelihood();
      EXPECT_NEAR(lml, weight_space.LogMarginalLikelihood(), 1e-8 * std::abs(lml));
      EXPECT_NEAR(lml, DenseLogLikelihood(kernel, h.noise_variance(), h.output_scales(), d),
                  1e-10 * std::abs(lml));

      Vector phi(D), mean(P), latent(P), noisy(P);
      for (int t = 0; t < 10; ++t) {
        const Vector x = RandomVector(3, 1.0, &rng);
        map->Evaluate(x, phi);
        ASSERT_EQ(weight_space.PredictWithVariance(phi, mean, latent, noisy), Status::kOk);
        const Prediction p = PredictAt(model, x);
        const double prior = kernel.Evaluate(x, x) + h.noise_variance();
        ExpectRelNear(p.mean, mean, 1e-8, d.Y.cwiseAbs().maxCoeff(), "mean");
        for (int j = 0; j < P; ++j) {
          const double s2 = h.output_scales()[j] * h.output_scales()[j];
          EXPECT_NEAR(p.latent[j], latent[j], 1e-8 * s2 * prior) << "latent " << j;
          EXPECT_NEAR(p.noisy[j], noisy[j], 1e-8 * s2 * prior) << "noisy " << j;
        }
      }
    }
  }
}

// d log p / d log Lambda_k from the weight-space model, summed over a block (times 2, since
// Lambda_k = lambda_k exp(2 log_block_scale)), is the kernel form's derivative with respect
// to the block scale; likewise for the shape parameter (chain rule through d Lambda / d shape),
// the noise and the output scales. Same conditioning argument as above: 1e-8 relative.
TEST(KernelGP, FeatureKernelGradientMatchesWeightSpaceEvidenceGradient) {
  const int P = 2, D = 30, m = 45;
  auto rng = SeededRng(21);
  auto map = std::make_shared<RandomFeatureMap>(3, D, 4, 2100);
  Hyperparameters h = DefaultHyperparameters(*map, P);
  h.shape << 0.2;
  h.log_block_scale = RandomVector(4, 0.3, &rng);
  h.log_noise_std = std::log(0.25);
  h.log_output_scale = RandomVector(P, 0.3, &rng);
  const Data d = MakeData(m, 3, P, &rng);

  Matrix d_lambda_d_shape;
  const Vector lambda = PriorVariance(*map, h, &d_lambda_d_shape);
  WeightSpaceGP weight_space(lambda, h.noise_variance(), P, h.output_scales());
  Matrix Phi;
  map->EvaluateRows(d.X, &Phi);
  ASSERT_EQ(weight_space.Fit(Phi, d.Y), Status::kOk);
  EvidenceGradient reference;
  weight_space.LogMarginalLikelihood(&reference);

  KernelGP model(FeatureKernel(map, h), h.noise_variance(), P, h.output_scales());
  ASSERT_EQ(model.Fit(d.X, d.Y), Status::kOk);
  Vector dk, ds;
  double dn = 0.0;
  model.LogMarginalLikelihood(&dk, &dn, &ds);
  ASSERT_EQ(dk.size(), 1 + 4);

  const double scale = reference.d_log_prior_variance.cwiseAbs().sum() + 1.0;
  const double d_shape =
      reference.d_log_prior_variance.dot(d_lambda_d_shape.col(0).cwiseQuotient(lambda));
  EXPECT_NEAR(dk[0], d_shape, 1e-8 * scale) << "log_decay";
  const auto blocks = map->blocks();
  for (int b = 0; b < 4; ++b) {
    const double expected =
        2.0 * reference.d_log_prior_variance.segment(blocks[b].begin, blocks[b].size).sum();
    EXPECT_NEAR(dk[1 + b], expected, 1e-8 * scale) << "block " << b;
  }
  EXPECT_NEAR(dn, reference.d_log_noise_std, 1e-8 * (std::abs(dn) + m * P));
  ExpectRelNear(ds, reference.d_log_output_scale, 1e-8, m, "d_log_output_scale");
}

// ---------------------------------------------------------------------------------------
// (b) Online updates.

// Points added one by one build the same factor as a batch Cholesky, with rounding in a
// different order; with sigma_n = 0.3 and unit signal variance cond(C) <= 1 + m / 0.09
// ~ 700, so predictions and likelihood agree to ~1e-13; 1e-10 leaves a wide margin.
TEST(KernelGP, AddsEqualBatchFit) {
  const int P = 3, m = 50, n_dim = 5;
  auto rng = SeededRng(31);
  const Data d = MakeData(m, n_dim, P, &rng);
  const Vector scales = (RandomVector(P, 0.3, &rng)).array().exp();
  RbfKernel kernel(n_dim, true, 1.2, 1.0);
  kernel = Reparameterized(kernel, RandomVector(n_dim + 1, 0.2, &rng));

  KernelGP online(kernel, 0.09, P, scales);
  online.Reserve(m);
  for (int i = 0; i < m; ++i) {
    ASSERT_EQ(online.Add(d.X.row(i).transpose(), d.Y.row(i).transpose()), Status::kOk) << i;
  }
  KernelGP batch(kernel, 0.09, P, scales);
  ASSERT_EQ(batch.Fit(d.X, d.Y), Status::kOk);

  EXPECT_EQ(online.size(), m);
  EXPECT_TRUE(online.inputs() == d.X);
  EXPECT_TRUE(online.targets() == d.Y);
  EXPECT_NEAR(online.LogMarginalLikelihood(), batch.LogMarginalLikelihood(),
              1e-10 * std::abs(batch.LogMarginalLikelihood()));
  for (int t = 0; t < 10; ++t) {
    const Vector x = RandomVector(n_dim, 1.0, &rng);
    const Prediction a = PredictAt(online, x), b = PredictAt(batch, x);
    ExpectRelNear(a.mean, b.mean, 1e-10, 1.0, "mean");
    ExpectRelNear(a.latent, b.latent, 1e-10, scales.squaredNorm(), "latent");
    ExpectRelNear(a.noisy, b.noisy, 1e-10, scales.squaredNorm(), "noisy");
  }

  // Truncate(k) is exactly the model of the first k points (compare with a batch fit), and
  // adding after a truncation works.
  online.Truncate(20);
  KernelGP first(kernel, 0.09, P, scales);
  ASSERT_EQ(first.Fit(d.X.topRows(20), d.Y.topRows(20)), Status::kOk);
  first.Reserve(21);
  EXPECT_NEAR(online.LogMarginalLikelihood(), first.LogMarginalLikelihood(),
              1e-10 * std::abs(first.LogMarginalLikelihood()));
  const Vector x = RandomVector(n_dim, 1.0, &rng);
  ExpectRelNear(PredictAt(online, x).mean, PredictAt(first, x).mean, 1e-10, 1.0, "mean");
  ASSERT_EQ(online.Add(d.X.row(20).transpose(), d.Y.row(20).transpose()), Status::kOk);
  ASSERT_EQ(first.Add(d.X.row(20).transpose(), d.Y.row(20).transpose()), Status::kOk);
  ExpectRelNear(PredictAt(online, x).latent, PredictAt(first, x).latent, 1e-10,
                scales.squaredNorm(), "latent after re-add");
  EXPECT_THROW(online.Truncate(22), std::invalid_argument);
  EXPECT_THROW(online.Truncate(-1), std::invalid_argument);
}

// AddAndPredict runs the same arithmetic in the same order as Add followed by
// PredictWithVariance (the two right-hand sides share the pass over L, each with the
// summation order of the single solve), so the results are bit-identical.
TEST(KernelGP, AddAndPredictEqualsAddThenPredict) {
  const int P = 3, n_dim = 9;
  auto rng = SeededRng(41);
  const Data d = MakeData(300, n_dim, P, &rng);
  const Data next = MakeData(40, n_dim, P, &rng);
  RbfKernel kernel(n_dim, false, 2.0, 1.0);
  KernelGP fused(kernel, 0.01, P), separate(kernel, 0.01, P);
  ASSERT_EQ(fused.Fit(d.X, d.Y), Status::kOk);
  ASSERT_EQ(separate.Fit(d.X, d.Y), Status::kOk);
  fused.Reserve(400);
  separate.Reserve(400);
  Vector mean(P), latent(P), noisy(P);
  for (int t = 0; t + 1 < next.X.rows(); ++t) {
    const Vector x = next.X.row(t).transpose(), y = next.Y.row(t).transpose();
    const Vector x_predict = next.X.row(t + 1).transpose();
    ASSERT_EQ(fused.AddAndPredict(x, y, x_predict, mean, latent, noisy), Status::kOk);
    ASSERT_EQ(separate.Add(x, y), Status::kOk);
    const Prediction p = PredictAt(separate, x_predict);
    ASSERT_TRUE(mean == p.mean) << "step " << t << "\n" << mean << "\n" << p.mean;
    ASSERT_TRUE(latent == p.latent) << "step " << t;
    ASSERT_TRUE(noisy == p.noisy) << "step " << t;
    // Variances skipped: the same mean.
    Vector mean_only(P), empty;
    separate.Truncate(separate.size() - 1);
    ASSERT_EQ(separate.AddAndPredict(x, y, x_predict, mean_only, empty, empty), Status::kOk);
    ASSERT_TRUE(mean_only == p.mean) << "step " << t;
  }
  EXPECT_EQ(fused.LogMarginalLikelihood(), separate.LogMarginalLikelihood());
}

TEST(KernelGP, ReserveKeepsTheModelAndEmptyModelPredictsThePrior) {
  const int P = 2;
  auto rng = SeededRng(51);
  const Data d = MakeData(30, 4, P, &rng);
  Vector scales(P);
  scales << 0.5, 2.0;
  RbfKernel kernel(4, false, 1.0, 1.5);
  KernelGP model(kernel, 0.04, P, scales);

  const Vector x = RandomVector(4, 1.0, &rng);
  const Prediction prior = PredictAt(model, x);
  EXPECT_TRUE(prior.mean.isZero(0.0));
  for (int j = 0; j < P; ++j) {
    EXPECT_DOUBLE_EQ(prior.latent[j], scales[j] * scales[j] * 2.25);
    EXPECT_DOUBLE_EQ(prior.noisy[j], scales[j] * scales[j] * (2.25 + 0.04));
  }
  EXPECT_EQ(model.LogMarginalLikelihood(), 0.0);

  ASSERT_EQ(model.Fit(d.X, d.Y), Status::kOk);
  EXPECT_EQ(model.capacity(), 30);
  const Prediction before = PredictAt(model, x);
  model.Reserve(100);
  EXPECT_EQ(model.capacity(), 100);
  model.Reserve(10);  // never shrinks
  EXPECT_EQ(model.capacity(), 100);
  const Prediction after = PredictAt(model, x);
  EXPECT_TRUE(before.mean == after.mean && before.latent == after.latent);
  EXPECT_THROW(model.Reserve(-1), std::invalid_argument);
}

// ---------------------------------------------------------------------------------------
// (c) Likelihood gradient against central differences.

struct GradientCase {
  std::string name;
  std::shared_ptr<Kernel> kernel;
  int input_dim;
};

// The likelihood as a function of every hyper-parameter: kernel parameters, log sigma_n,
// log s_j (fitted from scratch at each point).
double LikelihoodAt(const Kernel& prototype, const Vector& theta, double log_noise_std,
                    const Vector& log_scales, const Data& d) {
  auto kernel = prototype.Clone();
  kernel = kernel->WithParameters(theta);
  KernelGP model(*kernel, std::exp(2.0 * log_noise_std), static_cast<int>(log_scales.size()),
                 log_scales.array().exp().matrix());
  EXPECT_EQ(model.Fit(d.X, d.Y), Status::kOk);
  return model.LogMarginalLikelihood();
}

// Central differences with h = 1e-5: truncation h^2 |f'''| / 6 and rounding ~ eps cond(C)
// |f| / h, both below ~1e-6 here (|f| ~ 1e2, cond(C) < 1e3); the tolerance 1e-5 (1 + |g|)
// is far below the size of any real error in a gradient entry.
TEST(KernelGP, LikelihoodGradientMatchesCentralDifferences) {
  const int P = 2;
  auto map = std::make_shared<RandomFeatureMap>(3, 20, 3, 3100);
  Hyperparameters h = DefaultHyperparameters(*map, P);
  h.shape << 0.3;
  h.log_block_scale << 0.2, -0.3, 0.1;
  std::vector<GradientCase> cases;
  cases.push_back({"rbf_ard", std::make_shared<RbfKernel>(3, true, 1.0, 1.2), 3});
  cases.push_back({"rbfs_ard", std::make_shared<RbfsKernel>(2, true, 1.5, 0.8), 6});
  cases.push_back({"rbfs_iso", std::make_shared<RbfsKernel>(1, false, 1.5, 0.8), 3});
  cases.push_back({"feature", std::make_shared<FeatureKernel>(map, h), 3});
  std::uint64_t seed = 3200;
  for (const GradientCase& c : cases) {
    SCOPED_TRACE(c.name);
    auto rng = SeededRng(seed++);
    const Data d = MakeData(35, c.input_dim, P, &rng);
    Vector theta = c.kernel->parameters() + RandomVector(c.kernel->num_parameters(), 0.1, &rng);
    const std::shared_ptr<Kernel> kernel = c.kernel->WithParameters(theta);
    const double log_noise = std::log(0.3);
    const Vector log_scales = RandomVector(P, 0.3, &rng);

    KernelGP model(*kernel, std::exp(2.0 * log_noise), P, log_scales.array().exp().matrix());
    ASSERT_EQ(model.Fit(d.X, d.Y), Status::kOk);
    Vector dk, ds;
    double dn = 0.0;
    const double value = model.LogMarginalLikelihood(&dk, &dn, &ds);
    EXPECT_EQ(value, model.LogMarginalLikelihood());
    EXPECT_NEAR(value, LikelihoodAt(*kernel, theta, log_noise, log_scales, d),
                1e-12 * std::abs(value));

    const double step = 1e-5;
    auto check = [&](double analytic, double plus, double minus, const std::string& what) {
      const double fd = (plus - minus) / (2.0 * step);
      EXPECT_NEAR(analytic, fd, 1e-7 * (1.0 + std::abs(fd))) << what;
    };
    for (int p = 0; p < theta.size(); ++p) {
      Vector tp = theta, tm = theta;
      tp[p] += step;
      tm[p] -= step;
      check(dk[p], LikelihoodAt(*kernel, tp, log_noise, log_scales, d),
            LikelihoodAt(*kernel, tm, log_noise, log_scales, d), kernel->parameter_names()[p]);
    }
    check(dn, LikelihoodAt(*kernel, theta, log_noise + step, log_scales, d),
          LikelihoodAt(*kernel, theta, log_noise - step, log_scales, d), "log_noise_std");
    for (int j = 0; j < P; ++j) {
      Vector sp = log_scales, sm = log_scales;
      sp[j] += step;
      sm[j] -= step;
      check(ds[j], LikelihoodAt(*kernel, theta, log_noise, sp, d),
            LikelihoodAt(*kernel, theta, log_noise, sm, d),
            "log_output_scale " + std::to_string(j));
    }
  }
}

// ---------------------------------------------------------------------------------------
// (e) Failure modes: each leaves the model bit-identical.

class KernelGPFailures : public ::testing::Test {
 protected:
  void SetUp() override {
    auto rng = SeededRng(61);
    data_ = MakeData(20, 3, 2, &rng);
    probe_ = RandomVector(3, 1.0, &rng);
  }
  // A model with tiny noise, so that a duplicate point has no pivot left.
  std::unique_ptr<KernelGP> MakeModel(double noise_variance, int capacity) const {
    auto model = std::make_unique<KernelGP>(RbfKernel(3, false, 1.0, 1.0), noise_variance, 2);
    EXPECT_EQ(model->Fit(data_.X, data_.Y), Status::kOk);
    model->Reserve(capacity);
    return model;
  }
  void ExpectUnchanged(const KernelGP& model, const Prediction& before, double lml_before,
                       int size_before) const {
    EXPECT_EQ(model.size(), size_before);
    const Prediction after = PredictAt(model, probe_);
    EXPECT_TRUE(after.mean == before.mean);
    EXPECT_TRUE(after.latent == before.latent);
    EXPECT_TRUE(after.noisy == before.noisy);
    EXPECT_EQ(model.LogMarginalLikelihood(), lml_before);
  }
  Data data_;
  Vector probe_;
};

TEST_F(KernelGPFailures, DuplicatePointWithTinyNoiseIsNotPositiveDefinite) {
  auto model = MakeModel(1e-20, 30);
  const Prediction before = PredictAt(*model, probe_);
  const double lml = model->LogMarginalLikelihood();
  const Vector x = data_.X.row(7).transpose();
  const Vector y = data_.Y.row(7).transpose();
  EXPECT_EQ(model->Add(x, y), Status::kNotPositiveDefinite);
  ExpectUnchanged(*model, before, lml, 20);
  Vector mean = Vector::Constant(2, 42.0), latent = mean, noisy = mean;
  EXPECT_EQ(model->AddAndPredict(x, y, probe_, mean, latent, noisy), Status::kNotPositiveDefinite);
  EXPECT_TRUE(mean == Vector::Constant(2, 42.0));  // nothing written
  ExpectUnchanged(*model, before, lml, 20);
  // A new point is still accepted afterwards.
  EXPECT_EQ(model->Add(probe_, y), Status::kOk);

  // Fit rejects the same data set, and leaves the model as it was.
  auto fitted = MakeModel(1e-20, 30);
  const Prediction fitted_before = PredictAt(*fitted, probe_);
  Matrix X(21, 3), Y(21, 2);
  X << data_.X, data_.X.row(7);
  Y << data_.Y, data_.Y.row(7);
  EXPECT_EQ(fitted->Fit(X, Y), Status::kNotPositiveDefinite);
  ExpectUnchanged(*fitted, fitted_before, lml, 20);
}

TEST_F(KernelGPFailures, InvalidInputLeavesModelUnchanged) {
  auto model = MakeModel(0.01, 30);
  const Prediction before = PredictAt(*model, probe_);
  const double lml = model->LogMarginalLikelihood();
  const Vector y = data_.Y.row(0).transpose();
  Vector mean(2), latent(2), noisy(2), wrong(3), empty;
  for (double bad : {std::nan(""), std::numeric_limits<double>::infinity(),
                     -std::numeric_limits<double>::infinity()}) {
    Vector x = probe_;
    x[1] = bad;
    Vector y_bad = y;
    y_bad[1] = bad;
    EXPECT_EQ(model->Add(x, y), Status::kInvalidInput);
    EXPECT_EQ(model->Add(probe_, y_bad), Status::kInvalidInput);
    EXPECT_EQ(model->Predict(x, mean), Status::kInvalidInput);
    EXPECT_EQ(model->PredictWithVariance(x, mean, latent, noisy), Status::kInvalidInput);
    EXPECT_EQ(model->AddAndPredict(x, y, probe_, mean, latent, noisy), Status::kInvalidInput);
    EXPECT_EQ(model->AddAndPredict(probe_, y_bad, probe_, mean, latent, noisy),
              Status::kInvalidInput);
    EXPECT_EQ(model->AddAndPredict(probe_, y, x, mean, latent, noisy), Status::kInvalidInput);
  }
  const Vector short_x = probe_.head(2);
  EXPECT_EQ(model->Add(short_x, y), Status::kInvalidInput);
  EXPECT_EQ(model->Add(probe_, wrong), Status::kInvalidInput);
  EXPECT_EQ(model->Predict(short_x, mean), Status::kInvalidInput);
  EXPECT_EQ(model->Predict(probe_, wrong), Status::kInvalidInput);
  EXPECT_EQ(model->PredictWithVariance(probe_, mean, wrong, noisy), Status::kInvalidInput);
  EXPECT_EQ(model->PredictWithVariance(probe_, mean, empty, empty), Status::kInvalidInput);
  EXPECT_EQ(model->AddAndPredict(probe_, y, probe_, wrong, latent, noisy), Status::kInvalidInput);
  EXPECT_EQ(model->AddAndPredict(probe_, y, probe_, mean, latent, empty), Status::kInvalidInput);
  ExpectUnchanged(*model, before, lml, 20);
}

TEST_F(KernelGPFailures, FitThrowsOnBadData) {
  auto model = MakeModel(0.01, 30);
  const Prediction before = PredictAt(*model, probe_);
  const double lml = model->LogMarginalLikelihood();
  Matrix X = data_.X;
  X(3, 1) = std::nan("");
  try {
    model->Fit(X, data_.Y);
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("row 3"), std::string::npos) << message;
    EXPECT_NE(message.find("column 1"), std::string::npos) << message;
  }
  Matrix Y = data_.Y;
  Y(5, 0) = std::numeric_limits<double>::infinity();
  EXPECT_THROW(model->Fit(data_.X, Y), std::invalid_argument);
  EXPECT_THROW(model->Fit(data_.X.leftCols(2), data_.Y), std::invalid_argument);
  EXPECT_THROW(model->Fit(data_.X, data_.Y.leftCols(1)), std::invalid_argument);
  EXPECT_THROW(model->Fit(data_.X.topRows(10), data_.Y), std::invalid_argument);
  ExpectUnchanged(*model, before, lml, 20);

  const RbfKernel kernel(3);
  EXPECT_THROW(KernelGP(kernel, 0.0, 1), std::invalid_argument);
  EXPECT_THROW(KernelGP(kernel, std::nan(""), 1), std::invalid_argument);
  EXPECT_THROW(KernelGP(kernel, 0.1, 0), std::invalid_argument);
  EXPECT_THROW(KernelGP(kernel, 0.1, 2, Vector::Ones(3)), std::invalid_argument);
  EXPECT_THROW(KernelGP(kernel, 0.1, 2, Vector::Constant(2, -1.0)), std::invalid_argument);
}

TEST_F(KernelGPFailures, CapacityExceeded) {
  auto model = MakeModel(0.01, 22);
  const Vector y = data_.Y.row(0).transpose();
  Vector mean(2), latent(2), noisy(2);
  EXPECT_EQ(model->Add(probe_, y), Status::kOk);
  EXPECT_EQ(model->AddAndPredict(probe_ * 2.0, y, probe_, mean, latent, noisy), Status::kOk);
  const Prediction before = PredictAt(*model, probe_);
  const double lml = model->LogMarginalLikelihood();
  EXPECT_EQ(model->Add(probe_ * 3.0, y), Status::kCapacityExceeded);
  EXPECT_EQ(model->AddAndPredict(probe_ * 3.0, y, probe_, mean, latent, noisy),
            Status::kCapacityExceeded);
  ExpectUnchanged(*model, before, lml, 22);
  model->Reserve(23);
  EXPECT_EQ(model->Add(probe_ * 3.0, y), Status::kOk);
}

// ---------------------------------------------------------------------------------------
// (f) No allocation on the real-time path after Reserve.

TEST(KernelGP, RealTimePathDoesNotAllocate) {
  const int P = 3;
  auto map = std::make_shared<RandomFeatureMap>(6, 30, 3, 7100);
  const Hyperparameters h = DefaultHyperparameters(*map, P);
  const std::vector<std::shared_ptr<Kernel>> kernels = {
      std::make_shared<RbfKernel>(6, true, 1.0, 1.0), std::make_shared<RbfsKernel>(2, false),
      std::make_shared<FeatureKernel>(map, h)};
  for (const auto& kernel : kernels) {
    auto rng = SeededRng(7200);
    const Data d = MakeData(80, 6, P, &rng);
    const Data next = MakeData(20, 6, P, &rng);
    KernelGP model(*kernel, 0.04, P);
    ASSERT_EQ(model.Fit(d.X, d.Y), Status::kOk);
    model.Reserve(120);
    Vector mean(P), latent(P), noisy(P), empty;
    Vector bad = next.X.row(0).transpose();
    bad[0] = std::nan("");
    // Inputs as contiguous vectors prepared in advance (a row of a column-major matrix would
    // be copied into a temporary when bound to a vector reference).
    std::vector<Vector> xs, ys;
    for (int t = 0; t < 20; ++t) {
      xs.push_back(next.X.row(t).transpose());
      ys.push_back(next.Y.row(t).transpose());
    }
    std::size_t count = 0;
    {
      testing::AllocationCounter guard;
      for (int t = 0; t + 1 < 20; t += 2) {
        const Vector& x = xs[t];
        const Vector& y = ys[t];
        const Vector& x2 = xs[t + 1];
        const Vector& y2 = ys[t + 1];
        EXPECT_EQ(model.Add(x, y), Status::kOk);
        EXPECT_EQ(model.Predict(x2, mean), Status::kOk);
        EXPECT_EQ(model.PredictWithVariance(x2, mean, latent, noisy), Status::kOk);
        EXPECT_EQ(model.AddAndPredict(x2, y2, x, mean, latent, noisy), Status::kOk);
        EXPECT_EQ(model.AddAndPredict(x, y, x2, mean, empty, empty), Status::kOk);
        model.Truncate(model.size() - 1);
        EXPECT_EQ(model.Add(bad, y), Status::kInvalidInput);
        EXPECT_EQ(model.Predict(bad, mean), Status::kInvalidInput);
      }
      count = guard.count();
    }
    if (testing::CountsEveryAllocation()) {
      EXPECT_EQ(count, 0u) << kernel->parameter_names()[0];
    }
    EXPECT_EQ(model.size(), 100);
    // Full (Fit reserves exactly m): the capacity status does not allocate either.
    KernelGP full(*kernel, 0.04, P);
    ASSERT_EQ(full.Fit(d.X, d.Y), Status::kOk);
    ASSERT_EQ(full.capacity(), full.size());
    Status status = Status::kOk;
    {
      testing::AllocationCounter guard;
      status = full.AddAndPredict(xs[0], ys[0], xs[1], mean, latent, noisy);
      status = status == Status::kCapacityExceeded ? full.Add(xs[0], ys[0]) : status;
      count = guard.count();
    }
    EXPECT_EQ(status, Status::kCapacityExceeded);
    if (testing::CountsEveryAllocation()) {
      EXPECT_EQ(count, 0u);
    }
  }
  if (!testing::CountsEveryAllocation()) GTEST_SKIP() << testing::kIncompleteCountReason;
}

}  // namespace
}  // namespace structgp
