// Weight-space GP against independent dense references: the kernel-form formulas with
// K = Phi Lambda Phi^T (m x m Cholesky), batch refits for online updates, forgetting and
// downdates, and central finite differences for the evidence gradient.

#include <cmath>
#include <random>
#include <stdexcept>

#include <Eigen/Cholesky>
#include <gtest/gtest.h>

#include "structgp/model/weight_space_gp.h"

namespace structgp {
namespace {

constexpr double kLog2Pi = 1.8378770664093453;

struct Problem {
  Matrix Phi;   // m x D
  Matrix Y;     // m x P
  Vector lambda;
  double noise_variance;
  Vector scales;
};

// Features with a wide but controlled spectrum, targets from a random linear model + noise.
Problem MakeProblem(int m, int D, int P, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal;
  std::uniform_real_distribution<double> uniform(0.2, 2.0);
  Problem p;
  p.Phi = Matrix::NullaryExpr(m, D, [&]() { return normal(rng); });
  p.lambda = Vector::NullaryExpr(D, [&]() { return uniform(rng); });
  p.noise_variance = 0.05;
  p.scales = Vector::NullaryExpr(P, [&]() { return uniform(rng); });
  Matrix W = Matrix::NullaryExpr(D, P, [&]() { return normal(rng); });
  p.Y = p.Phi * W + 0.2 * Matrix::NullaryExpr(m, P, [&]() { return normal(rng); });
  return p;
}

double RelDiff(const Matrix& a, const Matrix& b) {
  return (a - b).norm() / std::max(1e-300, std::max(a.norm(), b.norm()));
}

// Dense function-space reference with sample weights v (noise variance sigma^2 / v_i).
struct DenseReference {
  DenseReference(const Matrix& Phi, const Matrix& Y, const Vector& lambda, double s2n,
                 const Vector& scales, const Vector& v)
      : Phi_(Phi), lambda_(lambda), s2n_(s2n), scales_(scales) {
    const int m = static_cast<int>(Phi.rows());
    Matrix C = Phi * lambda.asDiagonal() * Phi.transpose();
    C.diagonal() += s2n * v.cwiseInverse();
    llt_.compute(C);
    alpha_ = llt_.solve(Y);
    lml_ = 0.0;
    const double log_det = 2.0 * Matrix(llt_.matrixL()).diagonal().array().log().sum();
    for (int j = 0; j < Y.cols(); ++j) {
      const double s2 = scales[j] * scales[j];
      lml_ += -0.5 * Y.col(j).dot(alpha_.col(j)) / s2 - 0.5 * (log_det + m * std::log(s2)) -
              0.5 * m * kLog2Pi;
    }
  }
  Vector Mean(const Vector& phi) const {
    const Vector k = Phi_ * lambda_.asDiagonal() * phi;
    return alpha_.transpose() * k;
  }
  Vector LatentVariance(const Vector& phi) const {
    const Vector k = Phi_ * lambda_.asDiagonal() * phi;
    const double v = phi.dot(lambda_.asDiagonal() * phi) - k.dot(llt_.solve(k));
    return v * scales_.cwiseAbs2();
  }
  Matrix Phi_;
  Vector lambda_;
  double s2n_;
  Vector scales_;
  Eigen::LLT<Matrix> llt_;
  Matrix alpha_;
  double lml_;
};

void ExpectPredictionsMatch(const WeightSpaceGP& model, const DenseReference& ref,
                            const Matrix& queries, double tol) {
  const int P = model.num_outputs();
  Vector mean(P), latent(P), noisy(P);
  WeightSpaceGP::Workspace workspace = model.MakeWorkspace();
  for (int i = 0; i < queries.rows(); ++i) {
    const Vector phi = queries.row(i).transpose();
    ASSERT_EQ(model.PredictWithVariance(phi, mean, latent, noisy, workspace), Status::kOk);
    EXPECT_LT(RelDiff(mean, ref.Mean(phi)), tol) << "query " << i;
    EXPECT_LT(RelDiff(latent, ref.LatentVariance(phi)), tol) << "query " << i;
    EXPECT_LT(RelDiff(noisy, latent + model.noise_variance() * ref.scales_.cwiseAbs2()), 1e-15);
  }
}

TEST(WeightSpaceGP, BatchFitMatchesKernelFormReference) {
  for (unsigned seed : {1u, 2u, 3u}) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    for (auto [m, D] : {std::pair{40, 12}, std::pair{10, 30}}) {  // m > D and m < D
      const Problem p = MakeProblem(m, D, 3, seed);
      WeightSpaceGP model(p.lambda, p.noise_variance, 3, p.scales);
      ASSERT_EQ(model.Fit(p.Phi, p.Y), Status::kOk);
      const DenseReference ref(p.Phi, p.Y, p.lambda, p.noise_variance, p.scales,
                               Vector::Ones(m));
      const Problem q = MakeProblem(5, D, 3, seed + 100);
      ExpectPredictionsMatch(model, ref, q.Phi, 1e-9);
      EXPECT_NEAR(model.LogMarginalLikelihood(), ref.lml_, 1e-9 * std::abs(ref.lml_));
    }
  }
}

TEST(WeightSpaceGP, OnlineUpdatesEqualBatchFitUpTo10k) {
  const int D = 24, P = 7, n = 10000;
  const unsigned seed = 11;
  const Problem p = MakeProblem(n, D, P, seed);
  const Problem q = MakeProblem(8, D, P, seed + 1);
  WeightSpaceGP online(p.lambda, p.noise_variance, P, p.scales);
  WeightSpaceGP batch(p.lambda, p.noise_variance, P, p.scales);
  int checked = 0;
  for (int i = 0; i < n; ++i) {
    ASSERT_EQ(online.Update(p.Phi.row(i).transpose(), p.Y.row(i).transpose()), Status::kOk);
    const int count = i + 1;
    if (count == 1 || count == 10 || count == 100 || count == 1000 || count == n) {
      SCOPED_TRACE("n = " + std::to_string(count) + ", seed " + std::to_string(seed));
      ASSERT_EQ(batch.Fit(p.Phi.topRows(count), p.Y.topRows(count)), Status::kOk);
      EXPECT_LT(RelDiff(online.weights(), batch.weights()), 1e-10);
      Vector m1(P), l1(P), v1(P), m2(P), l2(P), v2(P);
      for (int k = 0; k < q.Phi.rows(); ++k) {
        const Vector phi = q.Phi.row(k).transpose();
        online.PredictWithVariance(phi, m1, l1, v1);
        batch.PredictWithVariance(phi, m2, l2, v2);
        EXPECT_LT(RelDiff(m1, m2), 1e-10);
        EXPECT_LT(RelDiff(l1, l2), 1e-10);
      }
      const double lml_batch = batch.LogMarginalLikelihood();
      EXPECT_NEAR(online.LogMarginalLikelihood(), lml_batch, 1e-10 * std::abs(lml_batch));
      ++checked;
    }
  }
  EXPECT_EQ(checked, 5);
}

TEST(WeightSpaceGP, ForgettingEqualsWeightedBatchWithBroadenedPrior) {
  const int D = 10, P = 2, n = 300;
  const double lambda_f = 0.98;
  const Problem p = MakeProblem(n, D, P, 21);
  WeightSpaceGP online(p.lambda, p.noise_variance, P, p.scales);
  for (int i = 0; i < n; ++i) {
    ASSERT_EQ(online.Update(p.Phi.row(i).transpose(), p.Y.row(i).transpose(), lambda_f),
              Status::kOk);
  }
  // Sample i (0-based) has weight lambda^(n-1-i); the prior variance is Lambda / lambda^n.
  Vector v(n);
  for (int i = 0; i < n; ++i) v[i] = std::pow(lambda_f, n - 1 - i);
  const Vector broadened = p.lambda / std::pow(lambda_f, n);
  EXPECT_LT(RelDiff(online.effective_prior_variance(), broadened), 1e-12);
  const DenseReference ref(p.Phi, p.Y, broadened, p.noise_variance, p.scales, v);
  const Problem q = MakeProblem(6, D, P, 22);
  ExpectPredictionsMatch(online, ref, q.Phi, 1e-9);
  EXPECT_NEAR(online.LogMarginalLikelihood(), ref.lml_, 1e-9 * std::abs(ref.lml_));
  EXPECT_NEAR(online.effective_count(), v.sum(), 1e-9 * v.sum());
}

TEST(WeightSpaceGP, DowndateUndoesUpdate) {
  const int D = 16, P = 3;
  const Problem p = MakeProblem(60, D, P, 31);
  WeightSpaceGP model(p.lambda, p.noise_variance, P, p.scales);
  ASSERT_EQ(model.Fit(p.Phi.topRows(50), p.Y.topRows(50)), Status::kOk);
  const Matrix w0 = model.weights();
  const Matrix cov0 = model.WeightCovariance(0);
  const double lml0 = model.LogMarginalLikelihood();
  for (int i = 50; i < 60; ++i) {
    ASSERT_EQ(model.Update(p.Phi.row(i).transpose(), p.Y.row(i).transpose()), Status::kOk);
  }
  for (int i = 59; i >= 50; --i) {
    ASSERT_EQ(model.Downdate(p.Phi.row(i).transpose(), p.Y.row(i).transpose()), Status::kOk);
  }
  EXPECT_LT(RelDiff(model.weights(), w0), 1e-10);
  EXPECT_LT(RelDiff(model.WeightCovariance(0), cov0), 1e-10);
  EXPECT_NEAR(model.LogMarginalLikelihood(), lml0, 1e-10 * std::abs(lml0));
  EXPECT_EQ(model.num_samples(), 50);

  // Removing samples from the middle of a batch equals the batch without them.
  ASSERT_EQ(model.Downdate(p.Phi.row(7).transpose(), p.Y.row(7).transpose()), Status::kOk);
  Matrix Phi_rest(49, D), Y_rest(49, P);
  Phi_rest << p.Phi.topRows(7), p.Phi.middleRows(8, 42);
  Y_rest << p.Y.topRows(7), p.Y.middleRows(8, 42);
  WeightSpaceGP reference(p.lambda, p.noise_variance, P, p.scales);
  ASSERT_EQ(reference.Fit(Phi_rest, Y_rest), Status::kOk);
  EXPECT_LT(RelDiff(model.weights(), reference.weights()), 1e-10);
  EXPECT_NEAR(model.LogMarginalLikelihood(), reference.LogMarginalLikelihood(),
              1e-10 * std::abs(lml0));
}

TEST(WeightSpaceGP, DowndateThatWouldLoseDefinitenessIsRefusedAndChangesNothing) {
  const int D = 6, P = 2;
  const Problem p = MakeProblem(3, D, P, 41);
  WeightSpaceGP model(p.lambda, p.noise_variance, P, p.scales);
  ASSERT_EQ(model.Fit(p.Phi, p.Y), Status::kOk);
  const Matrix w0 = model.weights();
  const Matrix s0 = model.covariance_factor();
  // A large feature vector that was never added: phi^T A^{-1} phi >> 1.
  const Vector phi = 100.0 * Vector::Ones(D);
  EXPECT_EQ(model.Downdate(phi, Vector::Zero(P)), Status::kNotPositiveDefinite);
  EXPECT_TRUE(model.weights() == w0);
  EXPECT_TRUE(model.covariance_factor() == s0);
  // Removing a sample twice: the second removal takes out information that is not there.
  ASSERT_EQ(model.Downdate(p.Phi.row(0).transpose(), p.Y.row(0).transpose()), Status::kOk);
  const Matrix s1 = model.covariance_factor();
  const Status twice = model.Downdate(p.Phi.row(0).transpose(), p.Y.row(0).transpose());
  if (twice != Status::kOk) {
    EXPECT_EQ(twice, Status::kNotPositiveDefinite);
    EXPECT_TRUE(model.covariance_factor() == s1);
  }
  EXPECT_TRUE(model.covariance_factor().allFinite());
}

TEST(WeightSpaceGP, UpdateAndPredictEqualsUpdateThenPredict) {
  const int D = 20, P = 4;
  const Problem p = MakeProblem(40, D, P, 51);
  WeightSpaceGP a(p.lambda, p.noise_variance, P, p.scales);
  WeightSpaceGP b(p.lambda, p.noise_variance, P, p.scales);
  Vector m1(P), l1(P), v1(P), m2(P), l2(P), v2(P);
  Vector none(0);
  for (int i = 0; i + 1 < 40; ++i) {
    const double forgetting = (i % 3 == 0) ? 0.97 : 1.0;
    const Vector phi = p.Phi.row(i).transpose(), y = p.Y.row(i).transpose();
    const Vector phi_next = p.Phi.row(i + 1).transpose();
    ASSERT_EQ(a.UpdateAndPredict(phi, y, phi_next, m1, l1, v1, forgetting), Status::kOk);
    ASSERT_EQ(b.Update(phi, y, forgetting), Status::kOk);
    ASSERT_EQ(b.PredictWithVariance(phi_next, m2, l2, v2), Status::kOk);
    EXPECT_LT(RelDiff(m1, m2), 1e-12);
    EXPECT_LT(RelDiff(l1, l2), 1e-10);
    EXPECT_LT(RelDiff(v1, v2), 1e-12);
    Vector m3(P);
    WeightSpaceGP c = a;  // mean-only variant, on a copy
    ASSERT_EQ(c.UpdateAndPredict(phi_next, y, phi, m3, none, none), Status::kOk);
  }
  EXPECT_LT(RelDiff(a.weights(), b.weights()), 1e-12);
}

// The staged update of UpdateAndPredict is invisible: whatever call follows it (predict,
// accessors, evidence, update, downdate, another step) sees the exact posterior.
TEST(WeightSpaceGP, StagedUpdateIsExactUnderAnyInterleaving) {
  const int D = 13, P = 3, n = 400;  // D not a multiple of 4: exercises the tail columns
  const unsigned seed = 55;
  const Problem p = MakeProblem(n, D, P, seed);
  WeightSpaceGP staged(p.lambda, p.noise_variance, P, p.scales);
  WeightSpaceGP plain(p.lambda, p.noise_variance, P, p.scales);
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<int> op(0, 5);
  Vector m1(P), l1(P), v1(P), m2(P), l2(P), v2(P);
  for (int i = 0; i + 1 < n; ++i) {
    SCOPED_TRACE("step " + std::to_string(i) + ", seed " + std::to_string(seed));
    const Vector phi = p.Phi.row(i).transpose(), y = p.Y.row(i).transpose();
    const Vector next = p.Phi.row(i + 1).transpose();
    ASSERT_EQ(staged.UpdateAndPredict(phi, y, next, m1, l1, v1), Status::kOk);
    ASSERT_EQ(plain.Update(phi, y), Status::kOk);
    ASSERT_EQ(plain.PredictWithVariance(next, m2, l2, v2), Status::kOk);
    ASSERT_LT(RelDiff(m1, m2), 1e-11);
    ASSERT_LT(RelDiff(l1, l2), 1e-9);
    switch (op(rng)) {
      case 0:
        staged.Predict(next, m1);
        plain.Predict(next, m2);
        ASSERT_LT(RelDiff(m1, m2), 1e-11);
        break;
      case 1:
        ASSERT_LT(RelDiff(staged.weights(), plain.weights()), 1e-11);
        ASSERT_LT(RelDiff(staged.covariance_factor(), plain.covariance_factor()), 1e-11);
        break;
      case 2:
        ASSERT_NEAR(staged.LogMarginalLikelihood(), plain.LogMarginalLikelihood(),
                    1e-10 * std::abs(plain.LogMarginalLikelihood()));
        break;
      case 3:
        ASSERT_EQ(staged.Update(next, y, 0.99), Status::kOk);
        ASSERT_EQ(plain.Update(next, y, 0.99), Status::kOk);
        break;
      case 4:
        ASSERT_EQ(staged.Downdate(phi, y), plain.Downdate(phi, y));
        break;
      default:
        break;  // two staged steps in a row
    }
  }
  EXPECT_LT(RelDiff(staged.weights(), plain.weights()), 1e-10);
}

// d log p / d (log Lambda_k, log sigma_n, log s_j) against central differences of batch fits.
TEST(WeightSpaceGP, EvidenceGradientMatchesCentralDifferences) {
  const int D = 8, P = 3, m = 25;
  const unsigned seed = 61;
  const Problem p = MakeProblem(m, D, P, seed);
  auto lml_at = [&](const Vector& log_lambda, double log_sn, const Vector& log_s) {
    WeightSpaceGP model(log_lambda.array().exp().matrix(), std::exp(2 * log_sn), P,
                        log_s.array().exp().matrix());
    EXPECT_EQ(model.Fit(p.Phi, p.Y), Status::kOk);
    return model.LogMarginalLikelihood();
  };
  const Vector log_lambda = p.lambda.array().log();
  const double log_sn = 0.5 * std::log(p.noise_variance);
  const Vector log_s = p.scales.array().log();
  WeightSpaceGP model(p.lambda, p.noise_variance, P, p.scales);
  ASSERT_EQ(model.Fit(p.Phi, p.Y), Status::kOk);
  EvidenceGradient g;
  model.LogMarginalLikelihood(&g);
  const double h = 1e-5;
  // Central difference error ~ h^2 f''' + eps |f| / h; |f| ~ 1e2 here.
  const double tol = 1e-5;
  for (int k = 0; k < D; ++k) {
    Vector up = log_lambda, dn = log_lambda;
    up[k] += h;
    dn[k] -= h;
    const double fd = (lml_at(up, log_sn, log_s) - lml_at(dn, log_sn, log_s)) / (2 * h);
    EXPECT_NEAR(g.d_log_prior_variance[k], fd, tol * std::max(1.0, std::abs(fd))) << "k " << k;
  }
  const double fd_sn = (lml_at(log_lambda, log_sn + h, log_s) -
                        lml_at(log_lambda, log_sn - h, log_s)) / (2 * h);
  EXPECT_NEAR(g.d_log_noise_std, fd_sn, tol * std::max(1.0, std::abs(fd_sn)));
  for (int j = 0; j < P; ++j) {
    Vector up = log_s, dn = log_s;
    up[j] += h;
    dn[j] -= h;
    const double fd = (lml_at(log_lambda, log_sn, up) - lml_at(log_lambda, log_sn, dn)) / (2 * h);
    EXPECT_NEAR(g.d_log_output_scale[j], fd, tol * std::max(1.0, std::abs(fd))) << "j " << j;
  }
}

TEST(WeightSpaceGP, VarianceNeverNegativeAndIllConditionedGivesStatusNotNaN) {
  const int D = 12, P = 2;
  Problem p = MakeProblem(30, D, P, 71);
  // Every sample duplicated many times, tiny noise: A is dominated by a rank-deficient Gram.
  Matrix Phi(300, D), Y(300, P);
  for (int i = 0; i < 300; ++i) {
    Phi.row(i) = p.Phi.row(i % 5);
    Y.row(i) = p.Y.row(i % 5);
  }
  for (double noise : {1e-2, 1e-12, 1e-24}) {
    SCOPED_TRACE("noise variance " + std::to_string(noise));
    WeightSpaceGP model(p.lambda, noise, P);
    const Status batch = model.Fit(Phi, Y);
    EXPECT_TRUE(batch == Status::kOk || batch == Status::kNotPositiveDefinite);
    WeightSpaceGP online(p.lambda, noise, P);
    for (int i = 0; i < 300; ++i) {
      const Status s = online.Update(Phi.row(i).transpose(), Y.row(i).transpose());
      EXPECT_TRUE(s == Status::kOk || s == Status::kNotPositiveDefinite) << ToString(s);
    }
    for (const WeightSpaceGP* m : {&model, &online}) {
      EXPECT_TRUE(m->weights().allFinite());
      EXPECT_TRUE(m->covariance_factor().allFinite());
      Vector mean(P), latent(P), noisy(P);
      WeightSpaceGP::Workspace workspace = m->MakeWorkspace();
      for (int i = 0; i < 20; ++i) {
        ASSERT_EQ(m->PredictWithVariance(p.Phi.row(i).transpose(), mean, latent, noisy, workspace),
                  Status::kOk);
        EXPECT_TRUE(mean.allFinite());
        EXPECT_TRUE((latent.array() >= 0.0).all());
        EXPECT_TRUE((noisy.array() >= latent.array()).all());
      }
    }
  }
}

TEST(WeightSpaceGP, BadInputIsRejectedAndModelUnchanged) {
  const int D = 5, P = 2;
  const Problem p = MakeProblem(20, D, P, 81);
  WeightSpaceGP model(p.lambda, p.noise_variance, P);
  ASSERT_EQ(model.Fit(p.Phi, p.Y), Status::kOk);
  const Matrix w0 = model.weights();
  const Matrix s0 = model.covariance_factor();
  const double lml0 = model.LogMarginalLikelihood();
  Vector phi = p.Phi.row(0).transpose();
  Vector y = p.Y.row(0).transpose();
  Vector bad_phi = phi;
  bad_phi[2] = std::nan("");
  Vector inf_y = y;
  inf_y[1] = HUGE_VAL;
  EXPECT_EQ(model.Update(bad_phi, y), Status::kInvalidInput);
  EXPECT_EQ(model.Update(phi, inf_y), Status::kInvalidInput);
  EXPECT_EQ(model.Update(Vector::Ones(D + 1), y), Status::kInvalidInput);
  EXPECT_EQ(model.Update(phi, Vector::Ones(P + 1)), Status::kInvalidInput);
  EXPECT_EQ(model.Update(phi, y, 0.0), Status::kInvalidInput);
  EXPECT_EQ(model.Update(phi, y, 1.5), Status::kInvalidInput);
  EXPECT_EQ(model.Update(phi, y, 1.0, -1.0), Status::kInvalidInput);
  EXPECT_EQ(model.Downdate(bad_phi, y), Status::kInvalidInput);
  Vector mean(P), small(P - 1), latent(P), noisy(P);
  EXPECT_EQ(model.Predict(bad_phi, mean), Status::kInvalidInput);
  EXPECT_EQ(model.Predict(phi, small), Status::kInvalidInput);
  EXPECT_EQ(model.PredictWithVariance(phi, mean, small, noisy), Status::kInvalidInput);
  EXPECT_TRUE(model.weights() == w0);
  EXPECT_TRUE(model.covariance_factor() == s0);
  EXPECT_EQ(model.LogMarginalLikelihood(), lml0);

  Matrix bad_Y = p.Y;
  bad_Y(7, 1) = std::nan("");
  try {
    model.Fit(p.Phi, bad_Y);
    FAIL() << "Fit accepted NaN";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("row 7, column 1"), std::string::npos) << e.what();
  }
  EXPECT_THROW(model.Fit(p.Phi.leftCols(D - 1), p.Y), std::invalid_argument);
  EXPECT_TRUE(model.weights() == w0);
  EXPECT_THROW(WeightSpaceGP(Vector::Zero(3), 0.1, 1), std::invalid_argument);
  EXPECT_THROW(WeightSpaceGP(Vector::Ones(3), -0.1, 1), std::invalid_argument);
  EXPECT_THROW(WeightSpaceGP(Vector::Ones(3), 0.1, 2, Vector::Ones(3)), std::invalid_argument);
}


// UpdateBatch against the same steps as single Update / Downdate calls (an independent path:
// one projection per step on the current factor), for sizes that exercise the vector blocks
// and the scalar tails of the fused pass, with forgetting, weights and removals mixed in.
TEST(WeightSpaceGP, UpdateBatchEqualsTheSequenceOfSingleSteps) {
  for (int D : {1, 5, 8, 13, 64, 203}) {
    for (int k : {1, 2, 3, 7, 16}) {
      SCOPED_TRACE("D = " + std::to_string(D) + ", k = " + std::to_string(k));
      const int P = 3;
      // More fitted samples than features, so that removing one keeps A well conditioned.
      const int fitted = D + 40, total = fitted + 6 * k;
      const Problem p = MakeProblem(total, D, P, 61 + D + k);
      WeightSpaceGP batched(p.lambda, p.noise_variance, P, p.scales);
      batched.ReserveBatch(k);
      WeightSpaceGP single(p.lambda, p.noise_variance, P, p.scales);
      ASSERT_EQ(batched.Fit(p.Phi.topRows(fitted), p.Y.topRows(fitted)), Status::kOk);
      ASSERT_EQ(single.Fit(p.Phi.topRows(fitted), p.Y.topRows(fitted)), Status::kOk);
      std::mt19937_64 rng(7);
      std::uniform_real_distribution<double> uniform(0.5, 2.0);
      int next = fitted;
      int removed = 0;     // samples 0.. removed in order, each added with weight 1 by Fit
      double decay = 1.0;  // what forgetting has left of the fitted samples' weights
      for (int round = 0; round < 6; ++round) {
        Matrix Phi(D, k), Y(P, k);
        Vector forgetting(k), weights(k);
        for (int i = 0; i < k; ++i) {
          // Every third step removes a sample of the fit; the others add new ones.
          if (i % 3 == 2 && removed < 20) {
            Phi.col(i) = p.Phi.row(removed).transpose();
            Y.col(i) = p.Y.row(removed).transpose();
            forgetting[i] = 1.0;
            weights[i] = -decay;
            ++removed;
          } else {
            Phi.col(i) = p.Phi.row(next).transpose();
            Y.col(i) = p.Y.row(next).transpose();
            forgetting[i] = round % 2 == 0 ? 1.0 : 0.97;
            decay *= forgetting[i];
            weights[i] = uniform(rng);
            ++next;
          }
        }
        Status status = Status::kInvalidInput;
        ASSERT_EQ(batched.UpdateBatch(Phi, Y, forgetting, weights, &status), k);
        ASSERT_EQ(status, Status::kOk);
        for (int i = 0; i < k; ++i) {
          if (weights[i] < 0) {
            ASSERT_EQ(single.Downdate(Phi.col(i), Y.col(i), -weights[i]), Status::kOk);
          } else {
            ASSERT_EQ(single.Update(Phi.col(i), Y.col(i), forgetting[i], weights[i]),
                      Status::kOk);
          }
        }
        EXPECT_LT(RelDiff(batched.weights(), single.weights()), 1e-11);
        EXPECT_LT(RelDiff(batched.covariance_factor(), single.covariance_factor()), 1e-11);
        EXPECT_TRUE(batched.covariance_factor().triangularView<Eigen::StrictlyLower>()
                        .toDenseMatrix()
                        .isZero(0.0));
      }
      EXPECT_EQ(batched.num_samples(), single.num_samples());
      EXPECT_NEAR(batched.LogMarginalLikelihood(), single.LogMarginalLikelihood(),
                  1e-9 * std::abs(single.LogMarginalLikelihood()));
      EXPECT_NEAR(batched.effective_count(), single.effective_count(), 1e-12 * D);
    }
  }
}

// A step the single call would refuse stops the batch there: the steps before it are applied,
// its status is returned, nothing after it is touched.
TEST(WeightSpaceGP, UpdateBatchStopsAtTheFirstRefusedStep) {
  const int D = 6, P = 2, k = 4;
  const Problem p = MakeProblem(20, D, P, 71);
  WeightSpaceGP batched(p.lambda, p.noise_variance, P, p.scales);
  WeightSpaceGP single(p.lambda, p.noise_variance, P, p.scales);
  batched.ReserveBatch(k);
  Matrix Phi(D, k), Y(P, k);
  for (int i = 0; i < k; ++i) {
    Phi.col(i) = p.Phi.row(i).transpose();
    Y.col(i) = p.Y.row(i).transpose();
  }
  Phi.col(2) = 100.0 * Vector::Ones(D);  // removing what was never added: refused
  const Vector forgetting = Vector::Ones(k);
  Vector weights = Vector::Ones(k);
  weights[2] = -1.0;
  Status status = Status::kOk;
  EXPECT_EQ(batched.UpdateBatch(Phi, Y, forgetting, weights, &status), 2);
  EXPECT_EQ(status, Status::kNotPositiveDefinite);
  ASSERT_EQ(single.Update(Phi.col(0), Y.col(0)), Status::kOk);
  ASSERT_EQ(single.Update(Phi.col(1), Y.col(1)), Status::kOk);
  EXPECT_LT(RelDiff(batched.weights(), single.weights()), 1e-12);
  EXPECT_EQ(batched.num_samples(), 2);
  // Bad input: NaN at step 1 applies step 0 only; more steps than reserved apply nothing.
  Phi.col(1)[0] = std::nan("");
  weights[2] = 1.0;
  EXPECT_EQ(batched.UpdateBatch(Phi, Y, forgetting, weights, &status), 1);
  EXPECT_EQ(status, Status::kInvalidInput);
  EXPECT_EQ(batched.num_samples(), 3);
  Matrix wide = Matrix::Zero(D, k + 1);
  EXPECT_EQ(batched.UpdateBatch(wide, Matrix::Zero(P, k + 1), Vector::Ones(k + 1),
                                Vector::Ones(k + 1), &status),
            0);
  EXPECT_EQ(status, Status::kInvalidInput);
  EXPECT_EQ(batched.num_samples(), 3);
}

}  // namespace
}  // namespace structgp
