// EulerLagrangeGP against independent references: its exact posterior and evidence against
// RegressorGP on the Lagrangian regressor with the kernel's prior variances (weight space vs
// kernel form); the DTC posterior with every state induced against the exact one; the evidence
// gradient against central differences; a fit on torques of the prior's class against held-out
// truth; effects of the time against the same model without the time and the weight-space GP;
// and the errors a user gets for bad input.

#include "structgp/model/euler_lagrange_gp.h"
#include "structgp/hyper/euler_lagrange_fit.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <cstdio>
#include <random>
#include <stdexcept>
#include <string>

#include <gtest/gtest.h>

#include "alloc_counter.h"

#include "structgp/core/row_subset.h"
#include "structgp/feature/effect_feature_map.h"
#include "structgp/feature/effects.h"
#include "structgp/feature/lagrangian_regressor_map.h"
#include "structgp/feature/sum_feature_map.h"
#include "structgp/model/weight_space_gp.h"
#include "structgp/model/regressor_gp.h"

namespace structgp {
namespace {

std::string FormatRow(const Vector& v) {
  std::string out;
  char buffer[32];
  for (Eigen::Index k = 0; k < v.size(); ++k) {
    std::snprintf(buffer, sizeof buffer, "%s%.3g", k == 0 ? "" : " ", v[k]);
    out += buffer;
  }
  return out;
}

Matrix RandomStates(int m, int n, std::mt19937* rng) {
  std::uniform_real_distribution<double> u(-2.5, 2.5);
  return Matrix::NullaryExpr(m, 3 * n, [&]() { return u(*rng); });
}

EulerLagrangeGPHyperparameters RandomHyper(int n, bool friction, std::mt19937* rng) {
  std::uniform_real_distribution<double> u(0.3, 2.0);
  EulerLagrangeGPHyperparameters h;
  h.sigma = 3.0;
  h.part_weights = Vector::NullaryExpr(2 * n, [&]() { return u(*rng); });
  h.noise_std = Vector::NullaryExpr(n, [&]() { return 0.1 * u(*rng); });
  if (friction) {
    h.friction_std = Vector::NullaryExpr(n, [&]() { return u(*rng); });
    h.friction_velocity_scale = Vector::NullaryExpr(n, [&]() { return u(*rng); });
    h.coulomb_width = 0.2;
  }
  return h;
}

// Torques of the Lagrangian regressor with parameters drawn from the kernel's own prior.
Matrix TwinTorques(const LagrangianRegressorMap& map, const Vector& theta, const Matrix& X) {
  const int n = map.num_outputs();
  Matrix Y(X.rows(), n), psi(n, map.dim());
  for (Eigen::Index s = 0; s < X.rows(); ++s) {
    map.Evaluate(X.row(s).transpose(), psi);
    Y.row(s) = (psi * theta).transpose();
  }
  return Y;
}

TEST(EulerLagrangeGP, ExactPosteriorEqualsTheRegressorTwin) {
  std::mt19937 rng(21);
  const int n = 3, m = 40;
  const LagrangianRegressorMap map(n);
  const EulerLagrangeGPHyperparameters h = RandomHyper(n, false, &rng);
  const Vector v = map.KernelPriorVariance(h.sigma, h.part_weights);
  std::normal_distribution<double> normal;
  const Vector theta = Vector::NullaryExpr(map.dim(), [&]() { return normal(rng); })
                           .cwiseProduct(v.cwiseSqrt());
  const Matrix X = RandomStates(m, n, &rng);
  Matrix Y = TwinTorques(map, theta, X);
  for (Eigen::Index s = 0; s < m; ++s) {
    for (int i = 0; i < n; ++i) Y(s, i) += h.noise_std[i] * normal(rng);
  }

  EulerLagrangeGP gp(h);
  ASSERT_EQ(gp.Condition(X, Y), Status::kOk);
  RegressorGP twin(Vector::Zero(map.dim()), v, h.noise_std.array().square());
  RegressorStatistics stats(map.dim(), n);
  stats.Accumulate(map, X, Y);
  ASSERT_EQ(twin.Fit(stats, false), Status::kOk);

  const Matrix Xt = RandomStates(10, n, &rng);
  Matrix mean, var;
  ASSERT_EQ(gp.Predict(Xt, &mean, &var), Status::kOk);
  auto ws = twin.MakeWorkspace();
  Matrix psi(n, map.dim());
  Vector m2(n), lat(n), noisy(n);
  double scale = 0.0, vscale = 0.0;
  Matrix mean2(Xt.rows(), n), var2(Xt.rows(), n);
  for (Eigen::Index s = 0; s < Xt.rows(); ++s) {
    map.Evaluate(Xt.row(s).transpose(), psi);
    ASSERT_EQ(twin.PredictWithVariance(psi, m2, lat, noisy, ws), Status::kOk);
    mean2.row(s) = m2.transpose();
    var2.row(s) = lat.transpose();
  }
  scale = mean2.cwiseAbs().maxCoeff();
  vscale = var2.cwiseAbs().maxCoeff();
  EXPECT_LT((mean - mean2).cwiseAbs().maxCoeff(), 1e-6 * scale) << mean << "\n\n" << mean2;
  EXPECT_LT((var - var2).cwiseAbs().maxCoeff(), 1e-6 * vscale) << var << "\n\n" << var2;
  EXPECT_NEAR(gp.LogMarginalLikelihood(), twin.LogMarginalLikelihood(),
              1e-7 * std::abs(twin.LogMarginalLikelihood()));
  EXPECT_NEAR(EulerLagrangeGP::LogEvidence(h, X, Y), gp.LogMarginalLikelihood(),
              1e-9 * std::abs(gp.LogMarginalLikelihood()));
}

TEST(EulerLagrangeGP, DtcWithEveryStateInducedEqualsTheExactPosterior) {
  std::mt19937 rng(4);
  const int n = 3, m = 25;
  const EulerLagrangeGPHyperparameters h = RandomHyper(n, true, &rng);
  const Matrix X = RandomStates(m, n, &rng);
  std::normal_distribution<double> normal;
  const Matrix Y = Matrix::NullaryExpr(m, n, [&]() { return normal(rng); });
  EulerLagrangeGP exact(h), dtc(h), half(h);
  ASSERT_EQ(exact.Condition(X, Y), Status::kOk);
  ASSERT_EQ(dtc.Condition(X, Y, X), Status::kOk);
  ASSERT_EQ(half.Condition(X, Y, X.topRows(5)), Status::kOk);
  const Matrix Xt = RandomStates(8, n, &rng);
  Matrix me, ve, md, vd, mh, vh;
  ASSERT_EQ(exact.Predict(Xt, &me, &ve), Status::kOk);
  ASSERT_EQ(dtc.Predict(Xt, &md, &vd), Status::kOk);
  ASSERT_EQ(half.Predict(Xt, &mh, &vh), Status::kOk);
  EXPECT_LT((me - md).cwiseAbs().maxCoeff(), 1e-4 * me.cwiseAbs().maxCoeff());
  EXPECT_LT((ve - vd).cwiseAbs().maxCoeff(), 1e-4 * ve.cwiseAbs().maxCoeff());
  // Five inducing states of 25 do not carry the same posterior (the comparison can fail).
  EXPECT_GT((me - mh).cwiseAbs().maxCoeff(), 1e-2 * me.cwiseAbs().maxCoeff());
  // The DTC's evidence through every state is the exact evidence.
  EXPECT_NEAR(dtc.LogMarginalLikelihood(), exact.LogMarginalLikelihood(),
              1e-4 * std::abs(exact.LogMarginalLikelihood()));
  EXPECT_GT(std::abs(half.LogMarginalLikelihood() - exact.LogMarginalLikelihood()), 1e-3);

  // One state at a time with a workspace: the same as the batch prediction, exact and DTC,
  // and allocation-free.
  for (const EulerLagrangeGP* gp : {&exact, &half}) {
    const Matrix& mb = gp == &exact ? me : mh;
    const Matrix& vb = gp == &exact ? ve : vh;
    EulerLagrangeGP::Workspace w = gp->MakeWorkspace();
    Vector mean(n), var(n), x(3 * n);
    for (Eigen::Index s = 0; s < Xt.rows(); ++s) {
      x = Xt.row(s).transpose();
      std::size_t allocations = 0;
      {
        testing::AllocationCounter counter;
        ASSERT_EQ(gp->PredictOne(x, mean, var, w), Status::kOk);
        allocations = counter.count();
      }
      if (testing::CountsEveryAllocation()) {
        EXPECT_EQ(allocations, 0u);
      }
      EXPECT_LT((mean - mb.row(s).transpose()).cwiseAbs().maxCoeff(),
                1e-10 * (1.0 + mb.cwiseAbs().maxCoeff()));
      EXPECT_LT((var - vb.row(s).transpose()).cwiseAbs().maxCoeff(),
                1e-8 * (1.0 + vb.cwiseAbs().maxCoeff()));
    }
    x[0] = std::numeric_limits<double>::quiet_NaN();
    EXPECT_EQ(gp->PredictOne(x, mean, var, w), Status::kInvalidInput);
  }
  // A workspace of another posterior is refused, not read past its end.
  EulerLagrangeGP::Workspace small = half.MakeWorkspace();
  Vector mean(n), var(n);
  EXPECT_EQ(exact.PredictOne(Xt.row(0).transpose(), mean, var, small), Status::kInvalidInput);
}

// DTC over blocks of training states and several workers: against the dense formulas (mean
// K_*Z (K_ZZ + K_ZX S^-1 K_XZ)^-1 K_ZX S^-1 y, evidence log N(y; 0, K_XZ K_ZZ^-1 K_ZX + S)),
// with a last block shorter than the others, a system of two panels, the second shorter, and
// bit for bit the same for 1 to 7 workers.
TEST(EulerLagrangeGP, DtcOverBlocksAndWorkersEqualsTheDenseFormulas) {
  // Four joints: a space of more functions than the p N = 192 inducing torques, so that every
  // panel of the system carries information (at two joints the inducing torques beyond the
  // space's few dozen functions leave rows of V near zero).
  std::mt19937 rng(8);
  const int n = 4;
  const int m = 3 * static_cast<int>(EulerLagrangeGP::kDtcBlockStates) + 17;
  const int p = static_cast<int>(EulerLagrangeGP::kDtcPanelRows) / n + 16;
  const EulerLagrangeGPHyperparameters h = RandomHyper(n, false, &rng);
  const Matrix X = RandomStates(m, n, &rng);
  const Matrix Z = X.topRows(p);
  std::normal_distribution<double> normal;
  const Matrix Y = Matrix::NullaryExpr(m, n, [&]() { return normal(rng); });
  const Matrix Xt = RandomStates(6, n, &rng);

  // The dense reference, from the kernel's blocks (row index state * N + joint).
  const EulerLagrangeKernel kernel(n, h.sigma);
  auto gram = [&](const Matrix& A, const Matrix& B) {
    Matrix K(A.rows() * n, B.rows() * n), block(n, n);
    for (Eigen::Index s = 0; s < A.rows(); ++s) {
      for (Eigen::Index t = 0; t < B.rows(); ++t) {
        kernel.Evaluate(A.row(s).transpose(), B.row(t).transpose(), h.part_weights, block);
        K.block(s * n, t * n, n, n) = block;
      }
    }
    return K;
  };
  Matrix Kzz = gram(Z, Z);
  Kzz.diagonal().array() += 1e-8 * Kzz.diagonal().mean();  // the model's jitter
  const Matrix Kzx = gram(Z, X), Ksz = gram(Xt, Z);
  Vector s_inv(m * n), y(m * n);
  for (int r = 0; r < m * n; ++r) {
    s_inv[r] = 1.0 / (h.noise_std[r % n] * h.noise_std[r % n]);
    y[r] = Y(r / n, r % n);
  }
  const Matrix A = Kzz + Kzx * s_inv.asDiagonal() * Kzx.transpose();
  const Vector mean_ref = Ksz * A.ldlt().solve(Kzx * s_inv.asDiagonal() * y);
  Matrix Q = Kzx.transpose() * Kzz.ldlt().solve(Kzx);
  Q.diagonal() += s_inv.cwiseInverse();
  const Eigen::LLT<Matrix> q(Q);
  ASSERT_EQ(q.info(), Eigen::Success);
  double half_logdet = 0.0;
  for (Eigen::Index r = 0; r < Q.rows(); ++r) half_logdet += std::log(q.matrixL()(r, r));
  const double evidence_ref = -0.5 * y.dot(q.solve(y)) - half_logdet -
                              0.5 * std::log(2.0 * M_PI) * static_cast<double>(y.size());

  Matrix mean_one;
  double evidence_one = 0.0;
  for (int workers : {1, 2, 3, 7}) {
    EulerLagrangeGP gp(h);
    ASSERT_EQ(gp.Condition(X, Y, Z, workers), Status::kOk) << workers << " workers";
    Matrix mean, var;
    ASSERT_EQ(gp.Predict(Xt, &mean, &var), Status::kOk);
    for (Eigen::Index s = 0; s < Xt.rows(); ++s) {
      for (int i = 0; i < n; ++i) {
        EXPECT_NEAR(mean(s, i), mean_ref[s * n + i], 1e-6 * (1.0 + mean_ref.cwiseAbs().maxCoeff()))
            << workers << " workers, state " << s << ", joint " << i + 1;
      }
    }
    EXPECT_NEAR(gp.LogMarginalLikelihood(), evidence_ref, 1e-7 * std::abs(evidence_ref))
        << workers << " workers";
    if (workers == 1) {
      mean_one = mean;
      evidence_one = gp.LogMarginalLikelihood();
    } else {
      // Several workers: the same sums in the same order, bit for bit.
      EXPECT_EQ(mean, mean_one) << workers << " workers";
      EXPECT_EQ(gp.LogMarginalLikelihood(), evidence_one) << workers << " workers";
    }
  }
  EulerLagrangeGP gp(h);
  EXPECT_THROW(gp.Condition(X, Y, Z, 0), std::invalid_argument);
}

// With every part weight zero and no friction, only the effects remain: the posterior is the
// weight-space GP on the effects' features with joint i's prior and noise scaled by s_i^2.
// The one rule for inducing states: InducingRows is FarthestStateRows or EvenlySpacedRows (none
// at count 0 or when the rows are no more than count), and Condition through a count is
// Condition through those states, bit for bit.
TEST(EulerLagrangeGP, InducingStatesByCountAreTheRulesRows) {
  using Rule = EulerLagrangeGP::InducingRule;
  std::mt19937 rng(6);
  const int n = 2, m = 30, p = 7;
  const EulerLagrangeGPHyperparameters h = RandomHyper(n, true, &rng);
  const Matrix X = RandomStates(m, n, &rng);
  std::normal_distribution<double> normal;
  const Matrix Y = Matrix::NullaryExpr(m, n, [&]() { return normal(rng); });
  EXPECT_EQ(EulerLagrangeGP::InducingRows(X, p, Rule::kCoverStates), FarthestStateRows(X, p));
  EXPECT_EQ(EulerLagrangeGP::InducingRows(X, p, Rule::kEvenlySpaced), EvenlySpacedRows(m, p));
  EXPECT_NE(FarthestStateRows(X, p), EvenlySpacedRows(m, p));
  EXPECT_TRUE(EulerLagrangeGP::InducingRows(X, 0, Rule::kCoverStates).empty());
  EXPECT_TRUE(EulerLagrangeGP::InducingRows(X, m, Rule::kCoverStates).empty());
  EXPECT_THROW(EulerLagrangeGP::InducingRows(X, -1, Rule::kCoverStates), std::invalid_argument);
  const Matrix Xt = RandomStates(5, n, &rng);
  for (Rule rule : {Rule::kCoverStates, Rule::kEvenlySpaced}) {
    EulerLagrangeGP by_count(h), by_states(h);
    ASSERT_EQ(by_count.Condition(X, Y, p, rule), Status::kOk);
    ASSERT_EQ(by_states.Condition(X, Y, SelectRows(X, EulerLagrangeGP::InducingRows(X, p, rule))),
              Status::kOk);
    EXPECT_TRUE(by_count.dtc());
    Matrix mc, vc, ms, vs;
    ASSERT_EQ(by_count.Predict(Xt, &mc, &vc), Status::kOk);
    ASSERT_EQ(by_states.Predict(Xt, &ms, &vs), Status::kOk);
    EXPECT_EQ(mc, ms);
    EXPECT_EQ(vc, vs);
  }
  EulerLagrangeGP all(h);
  ASSERT_EQ(all.Condition(X, Y, m), Status::kOk);
  EXPECT_FALSE(all.dtc());
}

TEST(EulerLagrangeGP, EffectsAloneEqualTheWeightSpaceGPOnTheirFeatures) {
  std::mt19937 rng(21);
  const int n = 3, m = 40;
  std::shared_ptr<const FeatureMap> effects = std::make_shared<SumFeatureMap>(
      std::vector<std::shared_ptr<const FeatureMap>>{
          std::make_shared<EffectFeatureMap>(n, MakeEffect("coulomb"), std::vector<int>{2}, false),
          std::make_shared<EffectFeatureMap>(n, MakeEffect("offset"), std::vector<int>{}, false)});
  EulerLagrangeGPHyperparameters h;
  h.sigma = 3.0;
  h.part_weights = Vector::Zero(2 * n);
  h.effect_prior_variance = Vector::LinSpaced(effects->dim(), 0.5, 2.0);
  h.effect_scale = Vector::LinSpaced(n, 0.7, 1.9);
  const double sigma_n = 0.1;
  h.noise_std = sigma_n * h.effect_scale;
  const Matrix X = RandomStates(m, n, &rng);
  std::normal_distribution<double> normal;
  const Matrix Y = Matrix::NullaryExpr(m, n, [&]() { return normal(rng); });
  EulerLagrangeGP gp(h, effects);
  ASSERT_EQ(gp.Condition(X, Y), Status::kOk);
  Matrix Phi;
  effects->EvaluateRows(X, &Phi);
  WeightSpaceGP twin(h.effect_prior_variance, sigma_n * sigma_n, n, h.effect_scale);
  ASSERT_EQ(twin.Fit(Phi, Y), Status::kOk);
  const Matrix Xt = RandomStates(6, n, &rng);
  Matrix mean, var;
  ASSERT_EQ(gp.Predict(Xt, &mean, &var), Status::kOk);
  WeightSpaceGP::Workspace w = twin.MakeWorkspace();
  Vector phi(effects->dim()), tm(n), tl(n), tn(n);
  for (Eigen::Index s = 0; s < Xt.rows(); ++s) {
    effects->Evaluate(Xt.row(s).transpose(), phi);
    ASSERT_EQ(twin.PredictWithVariance(phi, tm, tl, tn, w), Status::kOk);
    EXPECT_LT((mean.row(s).transpose() - tm).cwiseAbs().maxCoeff(), 1e-8 * (1.0 + tm.norm()));
    EXPECT_LT((var.row(s).transpose() - tl).cwiseAbs().maxCoeff(), 1e-8 * (1.0 + tl.norm()));
  }
  EXPECT_NEAR(gp.LogMarginalLikelihood(), twin.LogMarginalLikelihood(),
              1e-8 * std::abs(twin.LogMarginalLikelihood()));
  // A map that does not fit the prior variances is refused by name.
  EulerLagrangeGPHyperparameters bad = h;
  bad.effect_prior_variance = Vector::Ones(effects->dim() + 1);
  EXPECT_THROW(EulerLagrangeGP(bad, effects), std::invalid_argument);
  EXPECT_THROW(EulerLagrangeGP(h, nullptr), std::invalid_argument);
}

// Effects of the time: the inputs end with the time, which only the effects read. (a) With
// the kernel, friction and an effect of the state only, a map that takes the time gives the
// posterior of the map without it (the kernel and friction read the states alone), exactly and
// through inducing states, one state at a time without allocating. (b) A drift alone (zero
// part weights) is the weight-space GP on its features of the time. (c) Inputs without the
// time are refused by name.
TEST(EulerLagrangeGP, TimeEffectsReadTheLastColumnAndTheKernelDoesNot) {
  std::mt19937 rng(33);
  const int n = 3, m = 36;
  const Matrix S = RandomStates(m, n, &rng);
  Matrix X(m, 3 * n + 1);
  X << S, Vector::LinSpaced(m, 0.0, 12.0);
  std::normal_distribution<double> normal;
  const Matrix Y = Matrix::NullaryExpr(m, n, [&]() { return normal(rng); });
  auto coulomb = [&](bool with_time) -> std::shared_ptr<const FeatureMap> {
    return std::make_shared<EffectFeatureMap>(n, MakeEffect("coulomb"), std::vector<int>{2},
                                              with_time);
  };
  EulerLagrangeGPHyperparameters h = RandomHyper(n, true, &rng);
  h.effect_prior_variance = Vector::Constant(coulomb(false)->dim(), 0.8);
  h.effect_scale = Vector::LinSpaced(n, 0.7, 1.9);
  const Matrix St = RandomStates(7, n, &rng);
  Matrix Xt(7, 3 * n + 1);
  Xt << St, Vector::LinSpaced(7, 30.0, 40.0);
  for (bool through_inducing : {false, true}) {
    EulerLagrangeGP states_only(h, coulomb(false)), with_time(h, coulomb(true));
    EXPECT_EQ(states_only.input_dim(), 3 * n);
    EXPECT_EQ(with_time.input_dim(), 3 * n + 1);
    const std::vector<int> z = {0, 5, 9, 17, 22, 30, 35};
    ASSERT_EQ(states_only.Condition(S, Y, through_inducing ? SelectRows(S, z) : Matrix()),
              Status::kOk);
    ASSERT_EQ(with_time.Condition(X, Y, through_inducing ? SelectRows(X, z) : Matrix()),
              Status::kOk);
    Matrix m1, v1, m2, v2;
    ASSERT_EQ(states_only.Predict(St, &m1, &v1), Status::kOk);
    ASSERT_EQ(with_time.Predict(Xt, &m2, &v2), Status::kOk);
    EXPECT_LT((m1 - m2).cwiseAbs().maxCoeff(), 1e-12 * (1.0 + m1.cwiseAbs().maxCoeff()));
    EXPECT_LT((v1 - v2).cwiseAbs().maxCoeff(), 1e-12 * (1.0 + v1.cwiseAbs().maxCoeff()));
    EXPECT_NEAR(states_only.LogMarginalLikelihood(), with_time.LogMarginalLikelihood(),
                1e-10 * std::abs(states_only.LogMarginalLikelihood()));
    EulerLagrangeGP::Workspace w = with_time.MakeWorkspace();
    Vector mean(n), var(n), x(3 * n + 1);
    x = Xt.row(3).transpose();
    std::size_t allocations = 0;
    {
      testing::AllocationCounter counter;
      ASSERT_EQ(with_time.PredictOne(x, mean, var, w), Status::kOk);
      allocations = counter.count();
    }
    if (testing::CountsEveryAllocation()) {
      EXPECT_EQ(allocations, 0u);
    }
    EXPECT_LT((mean - m2.row(3).transpose()).cwiseAbs().maxCoeff(),
              1e-10 * (1.0 + m2.cwiseAbs().maxCoeff()));
    // A state without its time is refused.
    EXPECT_EQ(with_time.PredictOne(x.head(3 * n), mean, var, w), Status::kInvalidInput);
  }

  // (b) A drift on joint 1 and the coulomb effect, alone: the weight-space GP on their features.
  EffectParameters drift_parameters = MakeEffect("drift")->parameters();
  drift_parameters["span"] = 6.0;
  std::shared_ptr<const FeatureMap> effects = std::make_shared<SumFeatureMap>(
      std::vector<std::shared_ptr<const FeatureMap>>{
          coulomb(true), std::make_shared<EffectFeatureMap>(n, MakeEffect("drift",
                                                                          drift_parameters),
                                                            std::vector<int>{1}, true)});
  EulerLagrangeGPHyperparameters e;
  e.sigma = 3.0;
  e.part_weights = Vector::Zero(2 * n);
  e.effect_prior_variance = Vector::LinSpaced(effects->dim(), 0.5, 2.0);
  e.effect_scale = Vector::LinSpaced(n, 0.7, 1.9);
  const double sigma_n = 0.1;
  e.noise_std = sigma_n * e.effect_scale;
  EulerLagrangeGP gp(e, effects);
  ASSERT_EQ(gp.Condition(X, Y), Status::kOk);
  Matrix Phi;
  effects->EvaluateRows(X, &Phi);
  WeightSpaceGP twin(e.effect_prior_variance, sigma_n * sigma_n, n, e.effect_scale);
  ASSERT_EQ(twin.Fit(Phi, Y), Status::kOk);
  Matrix mean, var;
  ASSERT_EQ(gp.Predict(Xt, &mean, &var), Status::kOk);
  WeightSpaceGP::Workspace tw = twin.MakeWorkspace();
  Vector phi(effects->dim()), tm(n), tl(n), tn(n);
  for (Eigen::Index s = 0; s < Xt.rows(); ++s) {
    effects->Evaluate(Xt.row(s).transpose(), phi);
    ASSERT_EQ(twin.PredictWithVariance(phi, tm, tl, tn, tw), Status::kOk);
    EXPECT_LT((mean.row(s).transpose() - tm).cwiseAbs().maxCoeff(), 1e-8 * (1.0 + tm.norm()));
    EXPECT_LT((var.row(s).transpose() - tl).cwiseAbs().maxCoeff(), 1e-8 * (1.0 + tl.norm()));
  }
  // The drift's features are of the time: the prediction at other times differs.
  Matrix later = Xt, mean_later;
  later.col(3 * n).array() += 20.0;
  ASSERT_EQ(gp.Predict(later, &mean_later), Status::kOk);
  EXPECT_GT((mean_later - mean).cwiseAbs().maxCoeff(), 1e-3 * (1.0 + mean.cwiseAbs().maxCoeff()));

  // (c) States without the time are refused by name, in the GP and in its fit.
  try {
    gp.Condition(S, Y);
    ADD_FAILURE() << "no exception";
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("the states and the time"), std::string::npos)
        << error.what();
  }
  EXPECT_EQ(gp.Predict(St, &mean), Status::kInvalidInput);
  EulerLagrangeGPOptions o;
  o.sigmas = {3.0};
  o.effects = effects;
  o.effect_prior_variance = e.effect_prior_variance;
  EXPECT_THROW(FitEulerLagrangeGP(S, Y, o, nullptr), std::invalid_argument);
  const EulerLagrangeGPSummary fitted = FitEulerLagrangeGP(X, Y, o, nullptr);
  EXPECT_EQ(fitted.status, Status::kOk) << fitted.message;
}

TEST(EulerLagrangeGP, HyperparametersRoundTripThroughTheCommonType) {
  std::mt19937 rng(12);
  for (bool friction : {false, true}) {
    const EulerLagrangeGPHyperparameters h = RandomHyper(4, friction, &rng);
    const Hyperparameters common = ToHyperparameters(h);
    const EulerLagrangeGPHyperparameters back =
        EulerLagrangeFromHyperparameters(common, 4, friction);
    EXPECT_NEAR(back.sigma, h.sigma, 1e-12 * h.sigma);
    EXPECT_LT((back.part_weights - h.part_weights).cwiseAbs().maxCoeff(),
              1e-12 * h.part_weights.cwiseAbs().maxCoeff());
    EXPECT_LT((back.noise_std - h.noise_std).cwiseAbs().maxCoeff(), 1e-12);
    EXPECT_EQ(back.friction(), friction);
    if (friction) {
      EXPECT_LT((back.friction_std - h.friction_std).cwiseAbs().maxCoeff(), 1e-12);
      EXPECT_NEAR(back.coulomb_width, h.coulomb_width, 1e-15);
    }
    // The layout of the other setting, or of another number of joints, is refused by name.
    EXPECT_THROW(EulerLagrangeFromHyperparameters(common, 4, !friction), std::invalid_argument);
    EXPECT_THROW(EulerLagrangeFromHyperparameters(common, 3, friction), std::invalid_argument);
  }
}

TEST(EulerLagrangeGP, EvidenceGradientMatchesCentralDifferences) {
  std::mt19937 rng(9);
  const int n = 3, m = 12;
  const EulerLagrangeGPHyperparameters h = RandomHyper(n, true, &rng);
  const Matrix X = RandomStates(m, n, &rng);
  std::normal_distribution<double> normal;
  const Matrix Y = Matrix::NullaryExpr(m, n, [&]() { return 3.0 * normal(rng); });
  Vector g;
  const double value = EulerLagrangeGP::LogEvidence(h, X, Y, &g);
  ASSERT_TRUE(std::isfinite(value));
  ASSERT_EQ(g.size(), 3 * n);
  const double step = 1e-5;
  for (int k = 0; k < 3 * n; ++k) {
    EulerLagrangeGPHyperparameters plus = h, minus = h;
    Vector& a = k < 2 * n ? plus.part_weights : plus.noise_std;
    Vector& b = k < 2 * n ? minus.part_weights : minus.noise_std;
    const int idx = k < 2 * n ? k : k - 2 * n;
    a[idx] *= std::exp(step);
    b[idx] *= std::exp(-step);
    const double fd = (EulerLagrangeGP::LogEvidence(plus, X, Y) -
                       EulerLagrangeGP::LogEvidence(minus, X, Y)) / (2.0 * step);
    EXPECT_NEAR(g[k], fd, 1e-5 * (1.0 + std::abs(fd))) << "parameter " << k;
  }
}

// The evidence on several threads (EulerLagrangeEvidence's num_threads: the covariance's
// columns, the blocked factorisation and inverse from 256 values on, the parts' gradient terms)
// against one thread, at 360 values (above the threshold), 180 and 24 (below it): the value and every
// gradient component equal up to rounding, and bit for bit among thread counts from two on (the
// threads share fixed chunks of the work).
TEST(EulerLagrangeGP, EvidenceOnThreadsEqualsTheOneThreadEvidence) {
  std::mt19937 rng(10);
  const int n = 3;
  for (int m : {120, 60, 8}) {
    const EulerLagrangeGPHyperparameters h = RandomHyper(n, true, &rng);
    const Matrix X = RandomStates(m, n, &rng);
    std::normal_distribution<double> normal;
    const Matrix Y = Matrix::NullaryExpr(m, n, [&]() { return 3.0 * normal(rng); });
    const std::vector<int> parts = {0, 1, 2, 3, 4, 5};
    Vector log_parameters(3 * n);
    log_parameters << h.part_weights.array().log(), h.noise_std.array().log();
    const EulerLagrangeEvidence one(h, X, Y, parts, nullptr, 1);
    Vector g_one(3 * n);
    const double value_one = one.Evaluate(log_parameters.data(), g_one.data());
    ASSERT_TRUE(std::isfinite(value_one));
    const EulerLagrangeEvidence two(h, X, Y, parts, nullptr, 2);
    Vector g_two(3 * n);
    const double value_two = two.Evaluate(log_parameters.data(), g_two.data());
    // At 360 values the factorisation's blocked path runs: its rounding shows in the gradient.
    if (m == 120) {
      EXPECT_FALSE(g_two == g_one) << "the threaded factorisation did not run";
    }
    for (int threads : {2, 3, 4}) {
      SCOPED_TRACE("m = " + std::to_string(m) + ", threads = " + std::to_string(threads));
      const EulerLagrangeEvidence many(h, X, Y, parts, nullptr, threads);
      Vector g(3 * n);
      const double value = many.Evaluate(log_parameters.data(), g.data());
      EXPECT_NEAR(value, value_one, 1e-10 * std::abs(value_one));
      for (int k = 0; k < 3 * n; ++k) {
        // A gradient component is the difference of two far larger terms (tr(C^-1 A) and
        // alpha^T A alpha), so the factor's rounding shows at 1e-8 of it.
        EXPECT_NEAR(g[k], g_one[k], 1e-6 * (1.0 + std::abs(g_one[k]))) << "parameter " << k;
      }
      EXPECT_EQ(many.Evaluate(log_parameters.data(), nullptr), value);
      EXPECT_EQ(value, value_two);
      EXPECT_TRUE(g == g_two);
    }
  }
  const EulerLagrangeGPHyperparameters h = RandomHyper(n, false, &rng);
  EXPECT_THROW(EulerLagrangeEvidence(h, RandomStates(4, n, &rng), Matrix::Zero(4, n), {0},
                                     nullptr, 0),
               std::invalid_argument);
}

// Torques of a 3-joint chain drawn from the kernel's own class (the regressor twin's prior at
// sigma 3 with a weight per part): at `rows` random states with 5% noise (Y), and noiseless at
// `test_rows` more.
struct ClassDraw {
  Matrix X, truth, Y, X_test, truth_test;
  double noise = 0.0;
};
ClassDraw DrawOfItsClass(unsigned seed, int rows, int test_rows) {
  std::mt19937 rng(seed);
  const int n = 3;
  const LagrangianRegressorMap map(n);
  Vector w(2 * n);
  w << 0.5, 2.0, 1.0, 3.0, 1.0, 0.5;
  const Vector v = map.KernelPriorVariance(3.0, w);
  std::normal_distribution<double> normal;
  const Vector theta = Vector::NullaryExpr(map.dim(), [&]() { return normal(rng); })
                           .cwiseProduct(v.cwiseSqrt());
  ClassDraw d;
  d.X = RandomStates(rows, n, &rng);
  d.X_test = RandomStates(test_rows, n, &rng);
  d.truth = TwinTorques(map, theta, d.X);
  d.truth_test = TwinTorques(map, theta, d.X_test);
  d.noise = 0.05 * std::sqrt(d.truth.squaredNorm() / d.truth.size());
  d.Y = d.truth + Matrix::NullaryExpr(rows, n, [&]() { return d.noise * normal(rng); });
  return d;
}

TEST(EulerLagrangeGP, FitPredictsHeldOutTorquesOfItsClassForEveryJoint) {
  const int n = 3;
  const ClassDraw draw = DrawOfItsClass(13, 200, 100);
  const Matrix &X = draw.X, &Y = draw.Y, &Xt = draw.X_test, &truth_t = draw.truth_test;
  const double noise = draw.noise;
  EulerLagrangeGPOptions options;
  options.sigmas = {1.0, 3.0, 10.0};
  options.hyperparameter_rows = 120;
  std::optional<EulerLagrangeGP> gp;
  const EulerLagrangeGPSummary summary = FitEulerLagrangeGP(X, Y, options, &gp);
  ASSERT_EQ(summary.status, Status::kOk) << summary.message;
  ASSERT_TRUE(gp.has_value());
  EXPECT_EQ(summary.rows, 200);
  EXPECT_EQ(summary.hyperparameter_rows, 120);
  EXPECT_EQ(summary.log_evidence_per_sigma.size(), 3u);
  // The grid is searched in increasing order, each sigma after the first from the better of
  // the cold start and the previous optimum; the best sigma's evidence is the summary's.
  EXPECT_EQ(summary.sigmas, options.sigmas);
  ASSERT_EQ(summary.iterations_per_sigma.size(), 3u);
  ASSERT_EQ(summary.warm_start_per_sigma.size(), 3u);
  EXPECT_FALSE(summary.warm_start_per_sigma[0]);
  for (int k = 0; k < 3; ++k) EXPECT_GT(summary.iterations_per_sigma[k], 0) << "sigma " << k;
  // The chosen sigma has the largest evidence plus log prior (type-II MAP by default).
  ASSERT_EQ(summary.log_prior_per_sigma.size(), 3u);
  int chosen = -1;
  for (int k = 0; k < 3; ++k) {
    if (chosen < 0 || summary.log_evidence_per_sigma[k] + summary.log_prior_per_sigma[k] >
                          summary.log_evidence_per_sigma[chosen] + summary.log_prior_per_sigma[chosen]) {
      chosen = k;
    }
  }
  EXPECT_EQ(summary.hyperparameters.sigma, options.sigmas[chosen]);
  EXPECT_EQ(summary.log_evidence, summary.log_evidence_per_sigma[chosen]);
  EXPECT_EQ(summary.log_prior, summary.log_prior_per_sigma[chosen]);
  EXPECT_LE(summary.log_prior, 0.0);
  Matrix mean, var;
  ASSERT_EQ(gp->Predict(Xt, &mean, &var), Status::kOk);
  int inside = 0;
  for (int i = 0; i < n; ++i) {
    const double rms = std::sqrt((mean.col(i) - truth_t.col(i)).squaredNorm() / Xt.rows());
    const double signal = std::sqrt(truth_t.col(i).squaredNorm() / Xt.rows());
    EXPECT_LT(rms, 0.1 * signal) << "joint " << i + 1;
    EXPECT_GT(summary.hyperparameters.noise_std[i], 0.5 * noise) << "joint " << i + 1;
    EXPECT_LT(summary.hyperparameters.noise_std[i], 2.0 * noise) << "joint " << i + 1;
    for (Eigen::Index s = 0; s < Xt.rows(); ++s) {
      inside += std::abs(mean(s, i) - truth_t(s, i)) <= 2.0 * std::sqrt(var(s, i)) + 1e-12;
    }
  }
  EXPECT_GT(inside, 0.8 * n * Xt.rows());

  // The grid's order and repeats do not matter: the same search as the sorted grid.
  EulerLagrangeGPOptions shuffled = options;
  shuffled.sigmas = {10.0, 1.0, 3.0, 3.0};
  const EulerLagrangeGPSummary same = FitEulerLagrangeGP(X, Y, shuffled, nullptr);
  ASSERT_EQ(same.status, Status::kOk) << same.message;
  EXPECT_EQ(same.sigmas, options.sigmas);
  EXPECT_EQ(same.log_evidence, summary.log_evidence);
  EXPECT_EQ(same.hyperparameters.part_weights, summary.hyperparameters.part_weights);

  // One weight pair for the whole chain: only link N's parts are fitted.
  options.per_link = false;
  const EulerLagrangeGPSummary whole = FitEulerLagrangeGP(X, Y, options, &gp);
  ASSERT_EQ(whole.status, Status::kOk) << whole.message;
  const Vector& pw = whole.hyperparameters.part_weights;
  for (int link = 0; link + 1 < n; ++link) {
    EXPECT_EQ(pw[link], 0.0);
    EXPECT_EQ(pw[n + link], 0.0);
  }
  EXPECT_GT(pw[n - 1], 0.0);
  EXPECT_GT(pw[2 * n - 1], 0.0);

  // Through 80 inducing states of 200 (DTC), by either rule: still close on held-out states.
  options.per_link = true;
  options.inducing_states = 80;
  for (auto rule : {EulerLagrangeGPOptions::InducingRule::kCoverStates,
                    EulerLagrangeGPOptions::InducingRule::kEvenlySpaced}) {
    options.inducing_rule = rule;
    const EulerLagrangeGPSummary dtc = FitEulerLagrangeGP(X, Y, options, &gp);
    ASSERT_EQ(dtc.status, Status::kOk) << dtc.message;
    EXPECT_EQ(dtc.inducing_states, 80);
    ASSERT_EQ(gp->Predict(Xt, &mean), Status::kOk);
    const double rms = std::sqrt((mean - truth_t).squaredNorm() / truth_t.size());
    EXPECT_LT(rms, 0.2 * std::sqrt(truth_t.squaredNorm() / truth_t.size()));
    EXPECT_TRUE(std::isfinite(gp->LogMarginalLikelihood()));
  }
}

// A search from given hyper-parameters (a refit with an effect added starts from the model's
// own): at their sigma alone, from their weights and noise levels. From a grid's optimum it
// starts at that optimum's evidence and does not leave it; from another sigma's optimum it
// stays at that sigma, where the grid would have moved; a start that does not fit is refused.
// A log whose joint accelerations are zero to rounding (a via-point trajectory sampled only at
// its via points and midpoints, say) does not excite link 1's kinetic energy, whose torque is
// I_1 qdd_1. Its weight cannot be measured against those rows: the fit must say so, keep it
// at the other parts' scale, and predict motions that accelerate with finite means and a band
// that covers the truth (not 1e14 N m with a weight of e^71, as a start divided by the part's
// rounding-level variance gave).
TEST(EulerLagrangeGP, ALogWithoutAccelerationsIsNamedAndPredictsFiniteHonestTorques) {
  const int n = 3;
  ClassDraw draw = DrawOfItsClass(31, 150, 200);
  std::mt19937 rng(5);
  std::normal_distribution<double> normal;
  for (Eigen::Index r = 0; r < draw.X.rows(); ++r) {
    for (int j = 0; j < n; ++j) draw.X(r, 2 * n + j) = 1e-15 * normal(rng);
  }
  // The torques of the same draw (the same parameters) at the accelerations now in X.
  const LagrangianRegressorMap map(n);
  Vector w(2 * n);
  w << 0.5, 2.0, 1.0, 3.0, 1.0, 0.5;
  const Matrix truth_rounded = [&] {
    std::mt19937 again(31);
    std::normal_distribution<double> z;
    const Vector v = map.KernelPriorVariance(3.0, w);
    const Vector theta =
        Vector::NullaryExpr(map.dim(), [&]() { return z(again); }).cwiseProduct(v.cwiseSqrt());
    return TwinTorques(map, theta, draw.X);
  }();
  const Matrix Y = truth_rounded + (draw.Y - draw.truth);

  EulerLagrangeGPOptions options;
  options.sigmas = {3.0};
  options.hyperparameter_rows = 0;
  std::optional<EulerLagrangeGP> gp;
  const EulerLagrangeGPSummary summary = FitEulerLagrangeGP(draw.X, Y, options, &gp);
  ASSERT_EQ(summary.status, Status::kOk) << summary.message;
  EXPECT_EQ(summary.warnings.size(), 1u);
  for (const std::string& warning : summary.warnings) {
    EXPECT_NE(warning.find("kinetic energy of link 1 "), std::string::npos) << warning;
    EXPECT_EQ(warning.find("link 2"), std::string::npos) << warning;
  }
  // Its weight: within the range of the measured parts' weights, not e^60 above them.
  const Vector log_w = summary.hyperparameters.part_weights.array().log();
  const Vector others = log_w.tail(2 * n - 1);
  EXPECT_LE(log_w[0], others.maxCoeff() + 1e-9) << FormatRow(log_w);
  EXPECT_GE(log_w[0], others.minCoeff() - 1e-9) << FormatRow(log_w);

  Matrix mean, var;
  ASSERT_EQ(gp->Predict(draw.X_test, &mean, &var), Status::kOk);
  ASSERT_TRUE(mean.allFinite() && var.allFinite());
  const Matrix& truth = draw.truth_test;
  for (int i = 0; i < n; ++i) {
    const double signal = std::sqrt(truth.col(i).squaredNorm() / truth.rows());
    const double rms = std::sqrt((mean.col(i) - truth.col(i)).squaredNorm() / truth.rows());
    EXPECT_LT(rms, 3.0 * signal) << "joint " << i + 1;
    int inside = 0;
    for (Eigen::Index r = 0; r < truth.rows(); ++r) {
      inside += std::abs(mean(r, i) - truth(r, i)) <= 2.0 * std::sqrt(var(r, i)) ? 1 : 0;
    }
    EXPECT_GE(inside, 0.8 * truth.rows()) << "joint " << i + 1 << ": the band must cover";
  }
}

// An evidence is exact or none: where one part's weight dwarfs the noise so far that the
// factor's pivots are rounding error, LogEvidence is -inf (a search backs off), never a finite
// number that rounding made up. Reference: the closed form of a rank-one covariance plus noise
// (one joint, link 1's kinetic energy alone: tau = I_1 qdd), by the matrix determinant lemma
// and Sherman-Morrison, which has no cancellation.
TEST(EulerLagrangeGP, EvidenceIsExactOrNoneWhenAWeightDwarfsTheNoise) {
  const int m = 6;
  Matrix X = Matrix::Zero(m, 3);
  Matrix Y(m, 1);
  for (int r = 0; r < m; ++r) {
    X(r, 2) = 1.0 + 1e-9 * r;  // nearly the same acceleration on every row
    Y(r, 0) = 0.3 * X(r, 2) + 0.01 * ((r % 3) - 1.0);
  }
  EulerLagrangeGPHyperparameters h;
  h.sigma = 3.0;
  h.noise_std = Vector::Constant(1, 0.01);
  h.part_weights = Vector::Zero(2);
  // Covariance of the kinetic part alone at weight 1: a a^T with a = c qdd for the kernel's c.
  h.part_weights[0] = 1.0;
  const EulerLagrangeKernel kernel(1, h.sigma);
  Matrix block(1, 1);
  kernel.Evaluate(X.row(0).transpose(), X.row(0).transpose(), h.part_weights, block);
  const double c2 = block(0, 0) / (X(0, 2) * X(0, 2));
  ASSERT_GT(c2, 0.0);
  const auto closed_form = [&](double weight) {
    const Vector a = std::sqrt(weight * c2) * X.col(2);
    const double s2 = h.noise_std[0] * h.noise_std[0];
    const Vector y = Y.col(0);
    const double denominator = s2 + a.squaredNorm();
    const double quad = (y.squaredNorm() - a.dot(y) * a.dot(y) / denominator) / s2;
    const double logdet = (m - 1) * std::log(s2) + std::log(denominator);
    return -0.5 * quad - 0.5 * logdet - 0.5 * m * std::log(2.0 * M_PI);
  };
  // An accepted factor's pivots keep at least 1e-13 of their diagonal: the value is then good
  // to about eps / 1e-13 ~ 1e-3 (here 1e-5 at weight 1e8, whose pivots keep ~1e-12).
  const auto tolerance = [&](double weight) { return 1e-3 * (1.0 + std::abs(closed_form(weight))); };
  for (double weight : {1.0, 1e4, 1e8}) {
    h.part_weights[0] = weight;
    EXPECT_NEAR(EulerLagrangeGP::LogEvidence(h, X, Y), closed_form(weight), tolerance(weight))
        << "weight " << weight;
  }
  for (double weight : {1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16, 1e20, 1e30}) {
    h.part_weights[0] = weight;
    const double value = EulerLagrangeGP::LogEvidence(h, X, Y);
    if (std::isfinite(value)) {
      EXPECT_NEAR(value, closed_form(weight), tolerance(weight))
          << "weight " << weight << ": a finite evidence must be the exact one";
    } else {
      EXPECT_EQ(value, -std::numeric_limits<double>::infinity()) << "weight " << weight;
    }
  }
}

TEST(EulerLagrangeGP, ASearchFromGivenHyperparametersStaysAtTheirSigma) {
  const int n = 3;
  const ClassDraw draw = DrawOfItsClass(17, 150, 0);
  const Matrix &X = draw.X, &Y = draw.Y;
  EulerLagrangeGPOptions options;
  options.sigmas = {1.0, 3.0, 10.0};
  options.hyperparameter_rows = 100;
  const EulerLagrangeGPSummary grid = FitEulerLagrangeGP(X, Y, options, nullptr);
  ASSERT_EQ(grid.status, Status::kOk) << grid.message;

  EulerLagrangeGPOptions from = options;
  from.start = grid.hyperparameters;
  const EulerLagrangeGPSummary again = FitEulerLagrangeGP(X, Y, from, nullptr);
  ASSERT_EQ(again.status, Status::kOk) << again.message;
  EXPECT_EQ(again.sigmas, std::vector<double>{grid.hyperparameters.sigma});
  // The objective is the evidence plus the log prior, centred where a search from scratch
  // centres it: the same objective, so the search starts at the grid's optimum and keeps it.
  const auto objective = [](const EulerLagrangeGPSummary& s) { return s.log_evidence + s.log_prior; };
  EXPECT_NEAR(again.initial_log_evidence, grid.log_evidence, 1e-6 * std::abs(grid.log_evidence));
  EXPECT_GE(objective(again), objective(grid) - 1e-6 * std::abs(objective(grid)));
  for (int k = 0; k < 2 * n; ++k) {
    EXPECT_NEAR(std::log(again.hyperparameters.part_weights[k]),
                std::log(grid.hyperparameters.part_weights[k]), 0.05)
        << "part " << k;
  }

  // The optimum at a sigma the grid did not choose: the search from it stays there.
  const double other = grid.hyperparameters.sigma == 10.0 ? 1.0 : 10.0;
  EulerLagrangeGPOptions at_other = options;
  at_other.sigmas = {other};
  const EulerLagrangeGPSummary other_fit = FitEulerLagrangeGP(X, Y, at_other, nullptr);
  ASSERT_EQ(other_fit.status, Status::kOk) << other_fit.message;
  from.start = other_fit.hyperparameters;
  std::optional<EulerLagrangeGP> gp;
  const EulerLagrangeGPSummary stays = FitEulerLagrangeGP(X, Y, from, &gp);
  ASSERT_EQ(stays.status, Status::kOk) << stays.message;
  ASSERT_TRUE(gp.has_value());
  EXPECT_EQ(stays.hyperparameters.sigma, other);
  EXPECT_LT(objective(stays), objective(grid));
  EXPECT_GE(objective(stays), objective(other_fit) - 1e-6 * std::abs(objective(other_fit)));

  // A start that does not fit the data or has a searched part without weight.
  EulerLagrangeGPHyperparameters bad = grid.hyperparameters;
  bad.noise_std = Vector::Ones(n + 1);
  bad.part_weights = Vector::Ones(2 * (n + 1));
  from.start = bad;
  EXPECT_THROW(FitEulerLagrangeGP(X, Y, from, nullptr), std::invalid_argument);
  bad = grid.hyperparameters;
  bad.part_weights[1] = 0.0;
  from.start = bad;
  EXPECT_THROW(FitEulerLagrangeGP(X, Y, from, nullptr), std::invalid_argument);
}

// Type-II MAP: the search maximises the evidence plus a prior on the searched log values
// centred on the data-derived start (EulerLagrangeStart), width options.prior's. Checked against
// EulerLagrangeGP::LogEvidence (the evidence by another path) and the prior by hand: the result
// is a stationary point of that sum, and the summary's numbers are its two terms. A very
// tight prior returns the start. On slow motion (velocities and accelerations a twentieth of
// the class draw's), where the kinetic energies hardly show, plain type-II maximum likelihood
// drives a kinetic part's weight far below its start; the prior keeps every value closer.
TEST(EulerLagrangeGP, TypeIIMapMaximisesTheEvidencePlusThePriorAroundTheDataDerivedStart) {
  const int n = 3;
  ClassDraw draw = DrawOfItsClass(23, 90, 0);
  EulerLagrangeGPOptions options;
  options.sigmas = {3.0};
  options.hyperparameter_rows = 0;  // every row: the evidence below is of the same rows
  options.max_iterations = 400;
  ASSERT_EQ(options.prior.family, HyperpriorFamily::kGaussian);  // the default
  const double width = options.prior.block_scale_width;
  ASSERT_EQ(options.prior.noise_width, width);

  const auto logs = [](const EulerLagrangeGPHyperparameters& h) {
    Vector x(3 * n);
    x << h.part_weights.array().log().matrix(), h.noise_std.array().log().matrix();
    return x;
  };
  const auto with = [](EulerLagrangeGPHyperparameters h, const Vector& x) {
    h.part_weights = x.head(2 * n).array().exp().matrix();
    h.noise_std = x.tail(n).array().exp().matrix();
    return h;
  };

  const EulerLagrangeGPSummary map = FitEulerLagrangeGP(draw.X, draw.Y, options, nullptr);
  ASSERT_EQ(map.status, Status::kOk) << map.message;
  const Vector centre = logs(EulerLagrangeStart(draw.X, draw.Y, options, 3.0));
  const Vector x = logs(map.hyperparameters);
  const auto log_prior = [&](const Vector& v) {
    return -0.5 * ((v - centre) / width).squaredNorm();
  };
  const auto log_posterior = [&](const Vector& v) {
    return EulerLagrangeGP::LogEvidence(with(map.hyperparameters, v), draw.X, draw.Y) +
           log_prior(v);
  };
  EXPECT_NEAR(map.log_prior, log_prior(x), 1e-9 * (1.0 + std::abs(map.log_prior)));
  EXPECT_NEAR(map.log_evidence, EulerLagrangeGP::LogEvidence(map.hyperparameters, draw.X, draw.Y),
              1e-8 * std::abs(map.log_evidence));
  EXPECT_LT(map.log_prior, -0.01);  // the optimum is not the start: the prior is doing work
  // Stationary: the central difference of evidence + prior is at the optimiser's tolerance
  // (1e-4 per torque value), where the prior's own gradient alone is far larger on some value
  // (a search that ignored the prior would fail here).
  const double step = 1e-4, tolerance = 1e-4 * static_cast<double>(draw.Y.size());
  double largest_pull = 0.0;
  for (int k = 0; k < 3 * n; ++k) {
    Vector plus = x, minus = x;
    plus[k] += step;
    minus[k] -= step;
    const double g = (log_posterior(plus) - log_posterior(minus)) / (2.0 * step);
    const double pull = std::abs(x[k] - centre[k]) / (width * width);  // the prior's gradient
    largest_pull = std::max(largest_pull, pull);
    EXPECT_LT(std::abs(g), tolerance) << "value " << k << " at its optimum (prior's gradient "
                                      << pull << ")";
  }
  EXPECT_GT(largest_pull, 10.0 * tolerance);

  // A prior of width 1e-4 holds every value at the start.
  EulerLagrangeGPOptions tight = options;
  tight.prior.block_scale_width = tight.prior.noise_width = 1e-4;
  const EulerLagrangeGPSummary held = FitEulerLagrangeGP(draw.X, draw.Y, tight, nullptr);
  ASSERT_EQ(held.status, Status::kOk) << held.message;
  EXPECT_LT((logs(held.hyperparameters) - centre).cwiseAbs().maxCoeff(), 1e-3);

  // Slow motion: the kinetic parts hardly excited.
  ClassDraw slow = DrawOfItsClass(23, 90, 0);
  const LagrangianRegressorMap twin(n);
  slow.X.middleCols(n, 2 * n) *= 0.05;
  std::mt19937 rng(5);
  std::normal_distribution<double> normal;
  Vector w(2 * n);
  w << 0.5, 2.0, 1.0, 3.0, 1.0, 0.5;
  const Vector theta = Vector::NullaryExpr(twin.dim(), [&]() { return normal(rng); })
                           .cwiseProduct(twin.KernelPriorVariance(3.0, w).cwiseSqrt());
  slow.truth = TwinTorques(twin, theta, slow.X);
  const double noise = 0.05 * std::sqrt(slow.truth.squaredNorm() / slow.truth.size());
  slow.Y = slow.truth + Matrix::NullaryExpr(slow.X.rows(), n, [&]() { return noise * normal(rng); });
  EulerLagrangeGPOptions plain = options;
  plain.prior.family = HyperpriorFamily::kNone;
  const EulerLagrangeGPSummary ml = FitEulerLagrangeGP(slow.X, slow.Y, plain, nullptr);
  const EulerLagrangeGPSummary slow_map = FitEulerLagrangeGP(slow.X, slow.Y, options, nullptr);
  ASSERT_EQ(ml.status, Status::kOk) << ml.message;
  ASSERT_EQ(slow_map.status, Status::kOk) << slow_map.message;
  EXPECT_EQ(ml.log_prior, 0.0);
  const Vector slow_centre = logs(EulerLagrangeStart(slow.X, slow.Y, options, 3.0));
  const Vector d_ml = (logs(ml.hyperparameters) - slow_centre).head(n);  // kinetic parts
  const Vector d_map = (logs(slow_map.hyperparameters) - slow_centre).head(n);
  std::printf("slow motion, kinetic log weights from their start: ML-II %s; MAP %s\n",
              FormatRow(d_ml).c_str(), FormatRow(d_map).c_str());
  EXPECT_LT(d_ml.minCoeff(), -4.0 * width);
  EXPECT_GT(d_map.minCoeff(), d_ml.minCoeff() + width);
  EXPECT_LT(d_map.cwiseAbs().maxCoeff(), d_ml.cwiseAbs().maxCoeff());
  // And the MAP model's evidence is lower than ML-II's (it maximises another objective).
  EXPECT_LE(slow_map.log_evidence, ml.log_evidence + 1e-6 * std::abs(ml.log_evidence));

  // A prior that is not one is refused by name.
  EulerLagrangeGPOptions bad = options;
  bad.prior.noise_width = 0.0;
  try {
    FitEulerLagrangeGP(draw.X, draw.Y, bad, nullptr);
    ADD_FAILURE() << "a zero width was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("prior"), std::string::npos) << e.what();
  }
}

TEST(EulerLagrangeGP, RejectsBadInputWithAClearError) {
  std::mt19937 rng(2);
  const int n = 2;
  const EulerLagrangeGPHyperparameters h = RandomHyper(n, false, &rng);
  EulerLagrangeGP gp(h);
  const Matrix X = RandomStates(5, n, &rng);
  const Matrix Y = Matrix::Ones(5, n);
  Matrix mean;
  EXPECT_THROW(gp.Predict(X, &mean), std::logic_error);
  auto message = [](auto&& f) {
    try {
      f();
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no exception");
  };
  EXPECT_NE(message([&] { gp.Condition(X, Matrix::Ones(5, 3)); }).find("expected 2 torque columns, got 3"),
            std::string::npos);
  EXPECT_NE(message([&] { gp.Condition(X.topRows(4), Y); }).find("states have 4 rows, torques 5"),
            std::string::npos);
  Matrix bad = X;
  bad(2, 1) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NE(message([&] { gp.Condition(bad, Y); }).find("non-finite"), std::string::npos);
  EulerLagrangeGPHyperparameters wrong = h;
  wrong.part_weights.resize(3);
  EXPECT_NE(message([&] { EulerLagrangeGP g(wrong); }).find("expected 4 part weights, got 3"),
            std::string::npos);
  wrong = h;
  wrong.noise_std[0] = 0.0;
  EXPECT_THROW(EulerLagrangeGP{wrong}, std::invalid_argument);
  EulerLagrangeGPOptions options;
  options.sigmas = {1.0, -1.0};
  std::optional<EulerLagrangeGP> out;
  EXPECT_THROW(FitEulerLagrangeGP(X, Y, options, &out), std::invalid_argument);
  ASSERT_EQ(gp.Condition(X, Y), Status::kOk);
  EXPECT_EQ(gp.Predict(bad, &mean), Status::kInvalidInput);
  EXPECT_EQ(gp.Predict(Matrix::Zero(2, 5), &mean), Status::kInvalidInput);
}

}  // namespace
}  // namespace structgp
