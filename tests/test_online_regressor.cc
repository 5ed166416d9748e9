// The regressor form of OnlineLearner (rbd at 7 joints: the rigid-body regressor of a random
// URDF chain with friction, P = 98) against batch RegressorGP fits of the same samples, with
// the statistics accumulated here independently (per-sample regressor evaluations, weights
// from forgetting, the prior broadened by forgetting^-n): with and without forgetting and a
// window, one call per joint row (max_batch = 1) and bursts (max_batch = 16), with and
// without the learner thread, and continuing from a fitted posterior.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <memory>
#include <random>
#include <stdexcept>
#include <string>

#include "structgp/feature/rigid_body_regressor_map.h"
#include "structgp/feature/semi_parametric_regressor_map.h"
#include "structgp/model/regressor_gp.h"
#include "structgp/online/online_learner.h"
#include "structgp/rigid_body/rigid_body_chain.h"
#include "urdf_test_util.h"

namespace structgp {
namespace {

constexpr int kJoints = 7;
constexpr double kNoiseStd = 0.05;  // N m
constexpr std::uint64_t kUrdfSeed = 3;
constexpr std::uint64_t kDataSeed = 11;

std::shared_ptr<const SemiParametricRegressorMap> Rbd7() {
  testing::RandomUrdfOptions o;
  o.num_joints = kJoints;
  o.seed = kUrdfSeed;
  auto chain = std::make_shared<const RigidBodyRegressorMap>(
      RigidBodyChain::FromUrdfString(testing::RandomUrdf(o)));
  SemiParametricOptions sp;
  sp.friction = true;
  return std::make_shared<const SemiParametricRegressorMap>(chain, sp);
}

struct Samples {
  Matrix X, Y;  // m x 3N, m x N
};

// Random states; torques of the chain with its parameters off by up to 30%, friction and
// noise (the model's prior is centred on the unperturbed parameters).
Samples MakeSamples(const RegressorMap& map, int m, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::normal_distribution<double> noise(0.0, kNoiseStd);
  Vector theta = map.prior_mean();
  std::mt19937_64 prng(99);
  std::uniform_real_distribution<double> off(-0.3, 0.3);
  for (Eigen::Index k = 0; k < theta.size(); ++k) theta[k] *= 1.0 + off(prng);
  theta.tail(3 * kJoints).setConstant(0.3);  // viscous, Coulomb and offset
  Samples s;
  s.X = Matrix::NullaryExpr(m, map.input_dim(), [&]() { return 1.5 * u(rng); });
  s.Y.resize(m, kJoints);
  Matrix psi(kJoints, map.dim());
  for (int i = 0; i < m; ++i) {
    map.Evaluate(s.X.row(i).transpose(), psi);
    s.Y.row(i) = (psi * theta).transpose();
    for (int j = 0; j < kJoints; ++j) s.Y(i, j) += noise(rng);
  }
  return s;
}

// The statistics of rows [begin, end) with sample i weighted weight(i), summed here sample by
// sample (an independent path from the learner's and from RegressorStatistics::Accumulate).
template <typename Weight>
RegressorStatistics Weighted(const RegressorMap& map, const Samples& s, int begin, int end,
                             Weight weight) {
  RegressorStatistics st(map.dim(), kJoints);
  Matrix psi(kJoints, map.dim());
  for (int i = begin; i < end; ++i) {
    map.Evaluate(s.X.row(i).transpose(), psi);
    const double w = weight(i);
    for (int j = 0; j < kJoints; ++j) {
      const Vector a = psi.row(j).transpose();
      st.gram[static_cast<size_t>(j)] += w * a * a.transpose();
      st.cross.col(j) += w * s.Y(i, j) * a;
      st.y_squared[j] += w * s.Y(i, j) * s.Y(i, j);
    }
    st.count += w;
  }
  return st;
}

double MaxRel(const Vector& a, const Vector& b) {
  return (a - b).cwiseAbs().maxCoeff() / std::max(1e-300, b.cwiseAbs().maxCoeff());
}

// The learner's predictions (mean and latent variance) and its regressor_model() against the
// batch posterior, at test states.
void ExpectMatchesBatch(OnlineLearner& learner, const RegressorGP& batch, const RegressorMap& map,
                        const Samples& test, double tolerance) {
  Vector mean(kJoints), var(kJoints), bm(kJoints), bl(kJoints), bn(kJoints);
  Matrix psi(kJoints, map.dim());
  RegressorGP::Workspace ws = batch.MakeWorkspace();
  for (int i = 0; i < test.X.rows(); ++i) {
    const Vector x = test.X.row(i).transpose();
    map.Evaluate(x, psi);
    ASSERT_EQ(batch.PredictWithVariance(psi, bm, bl, bn, ws), Status::kOk);
    ASSERT_EQ(learner.PredictWithVariance(x, mean, var), Status::kOk);
    EXPECT_LT(MaxRel(mean, bm), tolerance) << "state " << i << ": " << mean.transpose()
                                            << " vs batch " << bm.transpose();
    EXPECT_LT(MaxRel(var, bl), tolerance) << "state " << i << ": " << var.transpose()
                                           << " vs batch " << bl.transpose();
  }
  const RegressorGP online = learner.regressor_model();
  EXPECT_LT(MaxRel(online.parameters(), batch.parameters()), tolerance);
}

struct Case {
  std::string name;
  double forgetting;
  int window;
  int max_batch;
  bool thread;
};
// The case's name in test listings (gtest would print the raw bytes of the struct, which
// change from run to run and so would the ctest names).
void PrintTo(const Case& c, std::ostream* os) { *os << c.name; }


class OnlineRegressor : public ::testing::TestWithParam<Case> {};

TEST_P(OnlineRegressor, EqualsTheBatchFitOfTheSameSamples) {
  const Case& c = GetParam();
  std::cout << "[ seeds    ] urdf " << kUrdfSeed << ", data " << kDataSeed << "\n";
  const auto map = Rbd7();
  ASSERT_EQ(map->dim(), 98);
  const int n = 600;
  const Samples data = MakeSamples(*map, n, kDataSeed);
  const Samples test = MakeSamples(*map, 20, kDataSeed + 1);
  OnlineLearnerOptions o;
  o.regressor_map = map;
  o.noise_variance = kNoiseStd * kNoiseStd;
  o.forgetting = c.forgetting;
  o.window_length = c.window;
  o.max_batch = c.max_batch;
  o.start_thread = c.thread;
  o.covariance_publish_period = 10;
  o.queue_capacity = 1024;
  OnlineLearner learner(o);
  EXPECT_TRUE(learner.regressor_form());
  EXPECT_EQ(learner.num_outputs(), kJoints);
  EXPECT_EQ(learner.num_features(), 98);
  for (int i = 0; i < n; ++i) {
    ASSERT_EQ(learner.Submit(data.X.row(i).transpose(), data.Y.row(i).transpose()),
              SubmitResult::kAccepted);
    if (!c.thread && i % 23 == 22) learner.ProcessPending();  // bursts of 23
  }
  ASSERT_TRUE(learner.WaitUntilIdle());
  // Sample i has weight lambda^(n-1-i); the prior variance is broadened to Lambda / lambda^n.
  const int begin = c.window > 0 ? n - c.window : 0;
  const double lambda = c.forgetting;
  const RegressorStatistics st =
      Weighted(*map, data, begin, n, [&](int i) { return std::pow(lambda, n - 1 - i); });
  const Vector prior_variance = map->prior_std().cwiseAbs2() / std::pow(lambda, n);
  RegressorGP batch(map->prior_mean(), prior_variance,
                    Vector::Constant(kJoints, o.noise_variance));
  ASSERT_EQ(batch.Fit(st), Status::kOk);
  // With forgetting every update rescales the posterior (the prior variance ends broadened by
  // lambda^-n, 20 times here), which adds rounding per update: 1.5e-8 seen with clang -O1.
  ExpectMatchesBatch(learner, batch, *map, test, c.forgetting < 1.0 ? 1e-7 : 1e-8);
  const OnlineLearnerSummary s = learner.summary();
  EXPECT_EQ(s.updates, n);
  EXPECT_EQ(s.status_failures(), 0);
  EXPECT_EQ(s.samples_in_model, c.window > 0 ? c.window : n);
  EXPECT_EQ(s.downdates, c.window > 0 ? n - c.window : 0);
  std::cout << s.Report();
  if (c.forgetting == 1.0 && c.window == 0) {
    // Without weights the library's own batch path gives the same posterior.
    RegressorStatistics plain(map->dim(), kJoints);
    plain.Accumulate(*map, data.X, data.Y);
    RegressorGP library(map->prior_mean(), map->prior_std().cwiseAbs2(),
                        Vector::Constant(kJoints, o.noise_variance));
    ASSERT_EQ(library.Fit(plain), Status::kOk);
    ExpectMatchesBatch(learner, library, *map, test, 1e-8);
  }
}

INSTANTIATE_TEST_SUITE_P(
    Cases, OnlineRegressor,
    ::testing::Values(Case{"rows_manual", 1.0, 0, 1, false},
                      Case{"bursts_manual", 1.0, 0, 16, false},
                      Case{"bursts_thread", 1.0, 0, 16, true},
                      Case{"forgetting_bursts_manual", 0.995, 0, 16, false},
                      Case{"forgetting_rows_thread", 0.995, 0, 1, true},
                      Case{"window_bursts_manual", 1.0, 200, 16, false},
                      Case{"window_forgetting_bursts_thread", 0.998, 200, 16, true}),
    [](const ::testing::TestParamInfo<Case>& p) { return p.param.name; });

// Continuing from a batch fit of the first half equals the batch fit of all samples.
TEST(OnlineRegressor, ContinuesFromAFittedPosterior) {
  const auto map = Rbd7();
  const Samples data = MakeSamples(*map, 400, kDataSeed);
  const Samples test = MakeSamples(*map, 20, kDataSeed + 1);
  const Vector noise = Vector::LinSpaced(kJoints, 0.03, 0.08).cwiseAbs2();
  RegressorStatistics first(map->dim(), kJoints);
  first.Accumulate(*map, data.X.topRows(200), data.Y.topRows(200));
  auto fitted = std::make_shared<RegressorGP>(map->prior_mean(), map->prior_std().cwiseAbs2(),
                                              noise);
  ASSERT_EQ(fitted->Fit(first), Status::kOk);
  OnlineLearnerOptions o;
  o.regressor_map = map;
  o.initial_regressor = fitted;
  o.covariance_publish_period = 1;
  o.start_thread = false;
  OnlineLearner learner(o);
  // Before any sample: the fitted model.
  ExpectMatchesBatch(learner, *fitted, *map, test, 1e-8);
  for (int i = 200; i < 400; ++i) {
    ASSERT_EQ(learner.Submit(data.X.row(i).transpose(), data.Y.row(i).transpose()),
              SubmitResult::kAccepted);
  }
  ASSERT_TRUE(learner.WaitUntilIdle());
  RegressorStatistics all(map->dim(), kJoints);
  all.Accumulate(*map, data.X, data.Y);
  RegressorGP batch(map->prior_mean(), map->prior_std().cwiseAbs2(), noise);
  ASSERT_EQ(batch.Fit(all), Status::kOk);
  ExpectMatchesBatch(learner, batch, *map, test, 1e-8);
  EXPECT_NEAR(learner.regressor_model().statistics().count, 400.0, 1e-9);
}

TEST(OnlineRegressor, OptionsAreValidated) {
  const auto map = Rbd7();
  std::string error;
  OnlineLearnerOptions o;
  o.regressor_map = map;
  EXPECT_TRUE(o.IsValid(&error)) << error;
  o.num_outputs = 6;
  EXPECT_FALSE(o.IsValid(&error));
  EXPECT_NE(error.find("num_outputs"), std::string::npos) << error;
  o.num_outputs = kJoints;
  EXPECT_TRUE(o.IsValid(&error)) << error;
  o.prior_mean = Vector::Zero(5);
  EXPECT_FALSE(o.IsValid(&error));
  EXPECT_NE(error.find("expected 98 entries, got 5"), std::string::npos) << error;
  o.prior_mean.resize(0);
  o.feature_map = nullptr;
  o.regressor_map = nullptr;
  EXPECT_FALSE(o.IsValid(&error));
  EXPECT_NE(error.find("exactly one of feature_map and regressor_map"), std::string::npos);
  o.regressor_map = map;
  o.max_batch = 0;
  EXPECT_FALSE(o.IsValid(&error));
  EXPECT_NE(error.find("max_batch"), std::string::npos) << error;
  o.max_batch = 4;
  o.output_scales = Vector::Ones(3);
  EXPECT_THROW(OnlineLearner{o}, std::invalid_argument);
  o.output_scales.resize(0);
  // At the prior, regressor_model() is the prior (no statistics).
  OnlineLearner learner(o);
  const RegressorGP prior = learner.regressor_model();
  EXPECT_LT(MaxRel(prior.parameters(), map->prior_mean()), 1e-15);
  EXPECT_EQ(prior.statistics().count, 0.0);
}

}  // namespace
}  // namespace structgp
