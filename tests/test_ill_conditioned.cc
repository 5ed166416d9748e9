// Ill-conditioned inputs to the weight-space model and its evidence, one test per case of the
// policy in weight_space_gp.h (docs/reliability.md): duplicate samples with a tiny noise (the
// jitter ladder), zero-velocity data under friction features with forgetting (the bound on the
// prior broadening), the pol shape parameter sigma -> 0 and sigma -> infinity, a tiny noise
// variance, inputs of absurd magnitude. Each ends in a Status and a model without NaN.

#include <cmath>
#include <memory>
#include <random>
#include <stdexcept>
#include <string>

#include <gtest/gtest.h>

#include "structgp/feature/friction_feature_map.h"
#include "structgp/feature/pol_feature_map.h"
#include "structgp/feature/sum_feature_map.h"
#include "structgp/hyper/evidence.h"
#include "structgp/feature/feature_hyperparameters.h"
#include "structgp/model/sufficient_statistics.h"
#include "structgp/model/weight_space_gp.h"

namespace structgp {
namespace {

// Every result a caller can read is finite, and variances are not negative.
void ExpectNoNaN(const WeightSpaceGP& model, const Matrix& queries) {
  EXPECT_TRUE(model.weights().allFinite());
  EXPECT_TRUE(model.covariance_factor().allFinite());
  EXPECT_TRUE((model.covariance_factor().diagonal().array() > 0.0).all());
  const int P = model.num_outputs();
  Vector mean(P), latent(P), noisy(P);
  WeightSpaceGP::Workspace workspace = model.MakeWorkspace();
  for (int i = 0; i < queries.rows(); ++i) {
    ASSERT_EQ(
        model.PredictWithVariance(queries.row(i).transpose(), mean, latent, noisy, workspace),
        Status::kOk);
    EXPECT_TRUE(mean.allFinite() && latent.allFinite() && noisy.allFinite()) << "query " << i;
    EXPECT_TRUE((latent.array() >= 0.0).all()) << "query " << i;
  }
}

// Random states of an N-joint robot (seed printed by the test name: fixed).
Matrix RandomStates(int N, int m, unsigned seed, double qd_range = 2.0) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> q(-M_PI, M_PI), qd(-qd_range, qd_range), qdd(-5, 5);
  Matrix X(m, 3 * N);
  for (int i = 0; i < m; ++i) {
    for (int n = 0; n < N; ++n) {
      X(i, n) = q(rng);
      X(i, N + n) = qd_range > 0.0 ? qd(rng) : 0.0;
      X(i, 2 * N + n) = qdd(rng);
    }
  }
  return X;
}

// One sample repeated 400 times with a tiny noise: A = 400 phi phi^T + sigma^2 Lambda^{-1} is
// singular to working precision. Fit takes the jitter ladder, says so, and the posterior mean at
// the repeated input is the observed value, as the kernel form gives it for m identical samples:
// mean = m k y / (m k + sigma^2), k = phi^T Lambda phi.
TEST(IllConditioned, DuplicateSamplesWithTinyNoiseTakeTheJitterLadder) {
  const PolFeatureMap map(1);
  const int D = map.dim();
  Vector lambda(D);
  map.PriorVariance(map.default_shape_parameters(), lambda);
  const Vector x = (Vector(3) << 0.3, -0.7, 1.1).finished();
  Vector phi(D);
  map.Evaluate(x, phi);
  const int m = 400;
  const Matrix Phi = phi.transpose().replicate(m, 1);
  const Matrix Y = Matrix::Constant(m, 1, 2.5);
  const double k = phi.dot(lambda.asDiagonal() * phi);

  for (double noise : {1e-2, 1e-20}) {
    SCOPED_TRACE("noise variance " + std::to_string(noise));
    WeightSpaceGP model(lambda, noise, 1);
    ASSERT_EQ(model.Fit(Phi, Y), Status::kOk);
    if (noise == 1e-2) {
      EXPECT_EQ(model.fit_jitter(), 0.0) << "a well-conditioned fit needs no jitter";
    } else {
      EXPECT_GT(model.fit_jitter(), 0.0) << "a singular precision must take the ladder";
      // Bounded: at most the last step of the ladder.
      EXPECT_LE(model.fit_jitter(),
                kJitterFirst * std::pow(kJitterGrowth, kMaxJitterSteps - 1) * 1.0001);
    }
    Vector mean(1);
    ASSERT_EQ(model.Predict(phi, mean), Status::kOk);
    const double reference = m * k * 2.5 / (m * k + noise);
    EXPECT_NEAR(mean[0], reference, 1e-6 * std::abs(reference));
    ExpectNoNaN(model, Phi.topRows(1));
  }
}

// A precision that cannot be factorised whatever the jitter (a NaN that slipped into hand-made
// statistics) is refused and the model is left as it was.
TEST(IllConditioned, FitGivesUpAfterTheLadderAndChangesNothing) {
  const int D = 4;
  WeightSpaceGP model(Vector::Ones(D), 0.1, 1);
  SufficientStatistics stats(D, 1);
  stats.gram(2, 2) = std::nan("");
  stats.count = 1;
  const Matrix s0 = model.covariance_factor();
  EXPECT_EQ(model.Fit(stats), Status::kNotPositiveDefinite);
  EXPECT_TRUE(model.covariance_factor() == s0);
  EXPECT_EQ(model.fit_jitter(), 0.0);
}

// Zero velocities under friction features: the features qd_n and tanh(qd_n / w) are zero, so
// forgetting broadens their prior by 1/lambda per step without bound. Without a limit the factor
// overflows (to inf, then NaN) after about 2000 steps at lambda = 0.5; with the policy, the
// forgetting step that would pass kMaxPriorToNoiseRatio is refused with kNotPositiveDefinite,
// the model stays finite and keeps learning without forgetting.
TEST(IllConditioned, ZeroVelocityUnderFrictionWithForgettingIsRefusedNotNaN) {
  const int N = 1;
  auto pol = std::make_shared<const PolFeatureMap>(N);
  auto fri = std::make_shared<const FrictionFeatureMap>(N, 0.01);
  const SumFeatureMap map({pol, fri});
  const Hyperparameters hyper = DefaultHyperparameters(map, N);
  const Vector lambda = PriorVariance(map, hyper);
  const Matrix X = RandomStates(N, 3000, 11, /*qd_range=*/0.0);
  Matrix Phi;
  map.EvaluateRows(X, &Phi);
  ASSERT_TRUE((Phi.col(pol->dim()).array() == 0.0).all()) << "viscous feature should be zero";

  WeightSpaceGP model(lambda, hyper.noise_variance(), N);
  int refused = 0, first_refused = -1;
  for (int i = 0; i < X.rows(); ++i) {
    const Vector y = Vector::Constant(1, std::cos(X(i, 0)));
    const Status s = model.Update(Phi.row(i).transpose(), y, 0.5);
    if (s == Status::kNotPositiveDefinite) {
      ++refused;
      if (first_refused < 0) first_refused = i;
      // The caller's way out: the same sample without forgetting.
      ASSERT_EQ(model.Update(Phi.row(i).transpose(), y, 1.0), Status::kOk);
    } else {
      ASSERT_EQ(s, Status::kOk) << "update " << i;
    }
  }
  EXPECT_GT(refused, 0) << "forgetting was never limited";
  // log(1e200) ~ 460.5 nats of broadening at log 2 per step, minus log(max Lambda / sigma^2).
  EXPECT_GT(first_refused, 500);
  EXPECT_LT(first_refused, 700);
  EXPECT_LE(std::log(model.effective_prior_variance().maxCoeff() / model.noise_variance()),
            std::log(kMaxPriorToNoiseRatio) + 1e-9);
  ExpectNoNaN(model, Phi.topRows(20));
  // UpdateAndPredict follows the same rule.
  const int P = 1;
  Vector mean(P), latent(P), noisy(P);
  EXPECT_EQ(model.UpdateAndPredict(Phi.row(0).transpose(), Vector::Ones(1),
                                   Phi.row(1).transpose(), mean, latent, noisy, 0.5),
            Status::kNotPositiveDefinite);
  ExpectNoNaN(model, Phi.topRows(20));
}

// The limit concerns actual variances, not the prior broadening: data that excite every
// direction keep the variances bounded, and forgetting goes on however far the prior has been
// broadened (here e^3466, far beyond 1e200) without a refusal, matching a batch refit on the
// last samples (the prior's weight lambda^n has long underflowed).
TEST(IllConditioned, ExcitedDirectionsForgetWithoutLimit) {
  const int D = 4, P = 1;
  std::mt19937_64 rng(41);
  std::normal_distribution<double> normal;
  const Vector w_true = (Vector(D) << 1.0, -2.0, 0.5, 3.0).finished();
  WeightSpaceGP model(Vector::Ones(D), 0.01, P);
  const double lambda = 0.5;
  for (int i = 0; i < 5000; ++i) {
    const Vector phi = Vector::NullaryExpr(D, [&]() { return normal(rng); });
    const Vector y = Vector::Constant(P, phi.dot(w_true));
    ASSERT_EQ(model.Update(phi, y, lambda), Status::kOk) << "update " << i;
  }
  EXPECT_GT(-5000 * std::log(lambda), std::log(kMaxPriorToNoiseRatio));
  // Noise-free data of a linear model: the weights are the true ones.
  EXPECT_LT((model.weights().col(0) - w_true).norm(), 1e-9);
  ExpectNoNaN(model, Matrix::Identity(D, D));
}

// The pol shape parameter: sigma -> 0 (theta -> 1) is harmless; sigma -> infinity (theta -> 0)
// makes prior variances underflow to 0. The evidence returns a status (an optimiser backs off)
// instead of throwing or giving NaN; a model built directly from such a prior is a caller
// mistake (std::invalid_argument naming the ratio).
TEST(IllConditioned, PolShapeParameterAtExtremesGivesStatus) {
  const int N = 2;
  auto map = std::make_shared<const PolFeatureMap>(N);
  const Matrix X = RandomStates(N, 300, 21);
  Matrix Phi;
  map->EvaluateRows(X, &Phi);
  Matrix Y(X.rows(), N);
  for (int i = 0; i < X.rows(); ++i) {
    Y(i, 0) = std::cos(X(i, 0)) + 0.3 * X(i, 4);
    Y(i, 1) = std::sin(X(i, 1)) * X(i, 2);
  }
  SufficientStatistics stats(map->dim(), N);
  stats.Accumulate(Phi, Y);
  const WeightSpaceEvidence evidence(map, stats);
  int refused = 0;
  for (double log_sigma : {-30.0, -5.0, 0.0, 5.0, 30.0, 300.0, 700.0}) {
    SCOPED_TRACE("log sigma " + std::to_string(log_sigma));
    Hyperparameters hyper = DefaultHyperparameters(*map, N);
    hyper.shape[0] = log_sigma;
    double lml = std::nan("");
    Hyperparameters gradient;
    Status s = Status::kOk;
    EXPECT_NO_THROW(s = evidence.Evaluate(hyper, &lml, &gradient));
    if (s == Status::kOk) {
      EXPECT_TRUE(std::isfinite(lml));
      EXPECT_TRUE(gradient.shape.allFinite());
    } else {
      EXPECT_EQ(s, Status::kNotPositiveDefinite);
      ++refused;
      const Vector lambda = PriorVariance(*map, hyper);
      EXPECT_THROW(WeightSpaceGP(lambda, hyper.noise_variance(), N), std::invalid_argument);
    }
  }
  EXPECT_GT(refused, 0) << "sigma = e^700 underflows the prior; the evidence must say so";
}

// Noise variance at the edge: 1e-300 makes Lambda / sigma^2 unrepresentable (a clear
// std::invalid_argument); 1e-14 with plenty of data is an ordinary fit without NaN.
TEST(IllConditioned, TinyNoiseVariance) {
  const PolFeatureMap map(1);
  const int D = map.dim();
  Vector lambda(D);
  map.PriorVariance(map.default_shape_parameters(), lambda);
  try {
    WeightSpaceGP model(lambda, 1e-300, 1);
    FAIL() << "accepted sigma_n^2 = 1e-300";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("prior_variance / noise_variance"), std::string::npos)
        << e.what();
  }
  const Matrix X = RandomStates(1, 500, 31);
  Matrix Phi;
  map.EvaluateRows(X, &Phi);
  Matrix Y(X.rows(), 1);
  for (int i = 0; i < X.rows(); ++i) Y(i, 0) = 2.0 * X(i, 2) + 9.81 * std::cos(X(i, 0));
  WeightSpaceGP batch(lambda, 1e-14, 1);
  ASSERT_EQ(batch.Fit(Phi, Y), Status::kOk);
  ExpectNoNaN(batch, Phi.topRows(20));
  WeightSpaceGP online(lambda, 1e-14, 1);
  for (int i = 0; i < X.rows(); ++i) {
    ASSERT_EQ(online.Update(Phi.row(i).transpose(), Y.row(i).transpose()), Status::kOk);
  }
  ExpectNoNaN(online, Phi.topRows(20));
  // The data are exactly in the model's span: both reproduce them to rounding.
  Vector mean(1);
  ASSERT_EQ(online.Predict(Phi.row(3).transpose(), mean), Status::kOk);
  EXPECT_NEAR(mean[0], Y(3, 0), 1e-6 * std::abs(Y(3, 0)));
}

// Inputs of absurd magnitude (finite, but their products overflow): refused with a status, the
// model unchanged.
TEST(IllConditioned, HugeFeatureValuesAreRefusedAndChangeNothing) {
  const int D = 6, P = 2;
  WeightSpaceGP model(Vector::Ones(D), 0.01, P);
  const Matrix Phi = Matrix::Identity(D, D);
  for (int i = 0; i < D; ++i) {
    ASSERT_EQ(model.Update(Phi.row(i).transpose(), Vector::Constant(P, 1.0 + i)), Status::kOk);
  }
  const Matrix w0 = model.weights();
  const Matrix s0 = model.covariance_factor();
  const Vector huge = Vector::Constant(D, 1e200);
  const Status s = model.Update(huge, Vector::Ones(P));
  EXPECT_TRUE(s == Status::kInvalidInput || s == Status::kNotPositiveDefinite) << ToString(s);
  Vector mean(P), latent(P), noisy(P);
  EXPECT_EQ(model.PredictWithVariance(huge, mean, latent, noisy), Status::kInvalidInput);
  EXPECT_TRUE(model.weights() == w0);
  EXPECT_TRUE(model.covariance_factor() == s0);
  ExpectNoNaN(model, Phi);
}

}  // namespace
}  // namespace structgp
