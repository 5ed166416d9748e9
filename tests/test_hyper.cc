// Hyper-parameter selection: type-II maximum likelihood (weight space and kernel form) and
// blocked cross-validation, against independent references: data drawn from a known model,
// central finite differences of the objective, the kernel form of the same likelihood, and
// cross-validation by refitting every fold from its raw rows.

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <iostream>
#include <memory>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "structgp/feature/pol_feature_map.h"
#include "structgp/feature/random_feature_map.h"
#include "structgp/hyper/cross_validation.h"
#include "structgp/hyper/evidence.h"
#include "structgp/hyper/hyperparameter_layout.h"
#include "structgp/hyper/marginal_likelihood.h"
#include "structgp/kernel/feature_kernel.h"
#include "structgp/kernel/rbf_kernel.h"
#include "structgp/model/kernel_gp.h"
#include "structgp/model/weight_space_gp.h"

namespace structgp {
namespace {

// Seeds are fixed; each test prints the seeds it uses so a failure can be replayed.
std::mt19937_64 SeededRng(std::uint64_t seed) {
  std::cout << "[ seed     ] " << seed << std::endl;
  return std::mt19937_64(seed);
}

Matrix RandomMatrix(int rows, int cols, double scale, std::mt19937_64* rng) {
  std::normal_distribution<double> normal(0.0, scale);
  return Matrix::NullaryExpr(rows, cols, [&]() { return normal(*rng); });
}

struct Data {
  Matrix X;  // m x input_dim
  Matrix Y;  // m x P
};

// Targets drawn from the model itself: w_j ~ N(0, s_j^2 Lambda), y = phi^T w_j + s_j sigma_n e.
Data SampleFromModel(const FeatureMap& map, const Hyperparameters& truth, const Matrix& X,
                     std::mt19937_64* rng) {
  const int P = static_cast<int>(truth.log_output_scale.size());
  const Vector lambda = PriorVariance(map, truth);
  Matrix Phi;
  map.EvaluateRows(X, &Phi);
  Matrix W = RandomMatrix(map.dim(), P, 1.0, rng);
  W = lambda.cwiseSqrt().asDiagonal() * W;
  Data d;
  d.X = X;
  d.Y = Phi * W +
        std::sqrt(truth.noise_variance()) * RandomMatrix(static_cast<int>(X.rows()), P, 1.0, rng);
  d.Y = d.Y * truth.output_scales().asDiagonal();
  return d;
}

// Robot-like states of N joints: q uniform in [-pi, pi], qd and qdd standard normal.
Matrix RandomStates(int m, int num_joints, std::mt19937_64* rng) {
  std::uniform_real_distribution<double> angle(-M_PI, M_PI);
  Matrix X = RandomMatrix(m, 3 * num_joints, 1.0, rng);
  for (int i = 0; i < m; ++i) {
    for (int n = 0; n < num_joints; ++n) X(i, n) = angle(*rng);
  }
  return X;
}

std::shared_ptr<const FeatureMap> Random(int input_dim, int D, int blocks, std::uint64_t seed) {
  return std::make_shared<RandomFeatureMap>(input_dim, D, blocks, seed);
}

WeightSpaceEvidence MakeEvidence(std::shared_ptr<const FeatureMap> map, const Data& d) {
  SufficientStatistics stats(map->dim(), static_cast<int>(d.Y.cols()));
  Matrix Phi;
  map->EvaluateRows(d.X, &Phi);
  stats.Accumulate(Phi, d.Y);
  return WeightSpaceEvidence(std::move(map), std::move(stats));
}

// Central differences of an objective with the EvidenceObjective::Evaluate signature.
template <typename Objective>
Vector CentralDifferences(const Objective& objective, const Vector& x, double h) {
  Vector g(x.size());
  for (Eigen::Index i = 0; i < x.size(); ++i) {
    Vector plus = x, minus = x;
    plus[i] += h;
    minus[i] -= h;
    double f_plus = 0.0, f_minus = 0.0;
    EXPECT_TRUE(objective.Evaluate(plus.data(), &f_plus, nullptr));
    EXPECT_TRUE(objective.Evaluate(minus.data(), &f_minus, nullptr));
    g[i] = (f_plus - f_minus) / (2.0 * h);
  }
  return g;
}

// ---- layout -----------------------------------------------------------------------------------

TEST(HyperparameterLayout, NamesOrderAndRoundTrip) {
  const RandomFeatureMap map(3, 20, 3, 11);
  FreeHyperparameters all;
  all.output_scales = true;
  const HyperparameterLayout layout(map, 2, all);
  const std::vector<std::string> expected = {
      "log_decay",     "log_scale_b0",       "log_scale_b1",      "log_scale_b2",
      "log_noise_std", "log_output_scale_1", "log_output_scale_2"};
  EXPECT_EQ(layout.names(), expected);
  EXPECT_EQ(layout.group(0), HyperparameterGroup::kShape);
  EXPECT_EQ(layout.group(4), HyperparameterGroup::kNoise);

  Hyperparameters h = DefaultHyperparameters(map, 2);
  h.shape << 0.5;
  h.log_block_scale << 1.0, 2.0, 3.0;
  h.log_noise_std = -1.5;
  h.log_output_scale << 0.25, -0.75;
  const Vector x = layout.Flatten(h);
  Vector expected_x(7);
  expected_x << 0.5, 1.0, 2.0, 3.0, -1.5, 0.25, -0.75;
  EXPECT_EQ(x, expected_x);
  Hyperparameters back = DefaultHyperparameters(map, 2);
  layout.Unflatten(x, &back);
  EXPECT_EQ(layout.Flatten(back), x);

  // Only the noise free: the other entries keep their values.
  FreeHyperparameters noise_only;
  noise_only.shape = noise_only.block_scales = false;
  const HyperparameterLayout noise_layout(map, 2, noise_only);
  ASSERT_EQ(noise_layout.size(), 1);
  EXPECT_EQ(noise_layout.names()[0], "log_noise_std");
  Hyperparameters partial = h;
  noise_layout.Unflatten(Vector::Constant(1, 0.125), &partial);
  EXPECT_EQ(partial.log_noise_std, 0.125);
  EXPECT_EQ(partial.shape, h.shape);
  EXPECT_EQ(partial.log_block_scale, h.log_block_scale);
  EXPECT_EQ(partial.log_output_scale, h.log_output_scale);

  EXPECT_THROW(layout.Unflatten(Vector::Zero(3), &back), std::invalid_argument);
  Hyperparameters wrong = h;
  wrong.log_block_scale.resize(2);
  EXPECT_THROW(layout.Flatten(wrong), std::invalid_argument);
}

TEST(HyperparameterLayout, PolNames) {
  const PolFeatureMap map(2);
  const HyperparameterLayout layout(map, 2);
  const std::vector<std::string> expected = {"log_sigma", "log_scale_inertial",
                                             "log_scale_coriolis", "log_scale_gravity",
                                             "log_noise_std"};
  EXPECT_EQ(layout.names(), expected);
}

// ---- options ----------------------------------------------------------------------------------

TEST(MaximumLikelihoodOptions, Validation) {
  MaximumLikelihoodOptions options;
  std::string error;
  EXPECT_TRUE(options.IsValid(&error)) << error;
  EXPECT_EQ(options.max_iterations, 200);
  EXPECT_EQ(options.noise_bounds.lower, -12.0);
  EXPECT_EQ(options.noise_bounds.upper, 3.0);

  MaximumLikelihoodOptions bad = options;
  bad.noise_bounds = {1.0, -1.0};
  EXPECT_FALSE(bad.IsValid(&error));
  EXPECT_NE(error.find("noise_bounds"), std::string::npos) << error;
  EXPECT_THROW(bad.Validate(), std::invalid_argument);
  bad = options;
  bad.noise_bounds = {-60.0, 3.0};  // the evidence accepts log sigma_n in (-50, 50) only
  EXPECT_FALSE(bad.IsValid(nullptr));
  bad = options;
  bad.max_iterations = 0;
  EXPECT_FALSE(bad.IsValid(&error));
  EXPECT_NE(error.find("max_iterations"), std::string::npos) << error;
  bad = options;
  bad.gradient_tolerance = -1.0;
  EXPECT_FALSE(bad.IsValid(nullptr));
  bad = options;
  bad.shape_bounds.upper = HUGE_VAL;
  EXPECT_FALSE(bad.IsValid(nullptr));

  EXPECT_STREQ(ToString(MaximumLikelihoodTermination::kConverged), "converged");
  EXPECT_STREQ(ToString(MaximumLikelihoodTermination::kInitialPointFailed), "initial_point_failed");
}

// ---- the objective and its gradient -------------------------------------------------------------

// The function Ceres minimises, through the flattened vector with every group free (shape
// parameter of RandomFeatureMap included), against central differences.
TEST(EvidenceObjective, GradientMatchesCentralDifferences) {
  auto rng = SeededRng(101);
  const auto map = Random(2, 24, 3, 7);
  Hyperparameters truth = DefaultHyperparameters(*map, 2);
  truth.shape << 0.4;
  truth.log_output_scale << 0.3, -0.2;
  const Data d = SampleFromModel(*map, truth, RandomMatrix(200, 2, 1.0, &rng), &rng);
  const WeightSpaceEvidence evidence = MakeEvidence(map, d);

  MaximumLikelihoodOptions options;
  options.optimize_output_scales = true;
  Hyperparameters start = truth;
  start.shape << -0.3;
  start.log_block_scale << 0.2, -0.3, 0.1;
  start.log_noise_std = std::log(0.25);
  start.log_output_scale << 0.1, -0.4;
  const EvidenceObjective objective(evidence, options, start);
  ASSERT_EQ(objective.num_parameters(), 1 + 3 + 1 + 2);
  EXPECT_EQ(objective.num_observations(), 400.0);

  const Vector x = objective.layout().Flatten(start);
  double cost = 0.0;
  Vector gradient(x.size());
  ASSERT_TRUE(objective.Evaluate(x.data(), &cost, gradient.data()));
  // The cost is -log p / (m P), with log p from the evidence itself.
  double lml = 0.0;
  ASSERT_EQ(evidence.Evaluate(start, &lml), Status::kOk);
  EXPECT_NEAR(cost, -lml / 400.0, 1e-14 * std::abs(lml));

  // Truncation error h^2 |f'''| ~ 1e-10 and rounding eps |f| / h ~ 1e-11 for f of order one.
  const Vector fd = CentralDifferences(objective, x, 1e-5);
  for (Eigen::Index i = 0; i < x.size(); ++i) {
    EXPECT_NEAR(gradient[i], fd[i], 1e-7 * std::max(1.0, std::abs(fd[i])))
        << objective.layout().names()[static_cast<size_t>(i)];
  }
  // The gradient is not trivially small here (so the comparison means something).
  EXPECT_GT(gradient.lpNorm<Eigen::Infinity>(), 1e-2);
}

TEST(EvidenceObjective, PolGradientMatchesCentralDifferences) {
  auto rng = SeededRng(102);
  const auto map = std::make_shared<PolFeatureMap>(1);
  Hyperparameters truth = DefaultHyperparameters(*map, 1);
  const Data d = SampleFromModel(*map, truth, RandomStates(150, 1, &rng), &rng);
  const WeightSpaceEvidence evidence = MakeEvidence(map, d);
  Hyperparameters start = truth;
  start.shape << 0.7;
  start.log_block_scale << -0.2, 0.4, 0.1;
  start.log_noise_std = std::log(0.05);
  const EvidenceObjective objective(evidence, MaximumLikelihoodOptions(), start);
  const Vector x = objective.layout().Flatten(start);
  double cost = 0.0;
  Vector gradient(x.size());
  ASSERT_TRUE(objective.Evaluate(x.data(), &cost, gradient.data()));
  const Vector fd = CentralDifferences(objective, x, 1e-5);
  for (Eigen::Index i = 0; i < x.size(); ++i) {
    EXPECT_NEAR(gradient[i], fd[i], 1e-7 * std::max(1.0, std::abs(fd[i])))
        << objective.layout().names()[static_cast<size_t>(i)];
  }
}

TEST(EvidenceObjective, DeclinesOutsideBoundsAndCounts) {
  auto rng = SeededRng(103);
  const auto map = Random(2, 10, 1, 3);
  const Hyperparameters h = DefaultHyperparameters(*map, 1);
  const Data d = SampleFromModel(*map, h, RandomMatrix(50, 2, 1.0, &rng), &rng);
  const WeightSpaceEvidence evidence = MakeEvidence(map, d);
  const EvidenceObjective objective(evidence, MaximumLikelihoodOptions(), h);
  Vector x = objective.layout().Flatten(h);
  double cost = 12345.0;
  Vector gradient = Vector::Constant(x.size(), 7.0);
  x[x.size() - 1] = 3.5;  // log sigma_n above the default upper bound 3
  EXPECT_FALSE(objective.Evaluate(x.data(), &cost, gradient.data()));
  x[x.size() - 1] = std::nan("");
  EXPECT_FALSE(objective.Evaluate(x.data(), &cost, gradient.data()));
  EXPECT_EQ(cost, 12345.0);  // nothing written
  EXPECT_EQ(gradient, Vector::Constant(x.size(), 7.0));
  EXPECT_EQ(objective.num_out_of_bounds_evaluations(), 2);
  EXPECT_EQ(objective.num_failed_evaluations(), 0);
  EXPECT_EQ(objective.num_evaluations(), 2);
}

// ---- ML-II in weight space ----------------------------------------------------------------------

// Data from a known model, sigma_n = 0.1, m = 2000, P = 2: the fit recovers sigma_n within 10%
// (its standard error is about 1 / sqrt(2 m P) ~ 1.1%), ends at a stationary point and
// improves the evidence, also against the true hyper-parameters.
TEST(FitHyperparameters, RecoversNoiseLevel) {
  auto rng = SeededRng(201);
  const auto map = Random(3, 30, 2, 21);
  Hyperparameters truth = DefaultHyperparameters(*map, 2);
  truth.shape << 0.5;
  truth.log_block_scale << 0.3, -0.4;
  truth.log_noise_std = std::log(0.1);
  const Data d = SampleFromModel(*map, truth, RandomMatrix(2000, 3, 1.0, &rng), &rng);
  const WeightSpaceEvidence evidence = MakeEvidence(map, d);

  Hyperparameters hyper = DefaultHyperparameters(*map, 2);
  hyper.log_noise_std = std::log(0.5);
  const MaximumLikelihoodOptions options;
  const MaximumLikelihoodSummary summary = FitHyperparameters(evidence, options, &hyper);
  std::cout << summary.BriefReport() << std::endl;
  std::cout << "sigma_n = " << std::exp(hyper.log_noise_std) << ", log_decay = " << hyper.shape[0]
            << ", block scales = " << hyper.log_block_scale.transpose() << std::endl;

  EXPECT_EQ(summary.termination, MaximumLikelihoodTermination::kConverged) << summary.message;
  EXPECT_NEAR(std::exp(hyper.log_noise_std), 0.1, 0.01);
  EXPECT_LE(summary.final_negative_log_likelihood, summary.initial_negative_log_likelihood);
  EXPECT_EQ(summary.num_failed_evaluations, 0);
  EXPECT_TRUE(summary.at_bounds.empty());
  // Stationary: |d log p / d x| is tiny against n = 4000 observations.
  ASSERT_EQ(summary.final_gradient.size(), 4);
  EXPECT_LT(summary.final_gradient.lpNorm<Eigen::Infinity>(), 1e-4);
  // The result's evidence is what the summary says, and at least that of the truth.
  double lml = 0.0, lml_truth = 0.0;
  ASSERT_EQ(evidence.Evaluate(hyper, &lml), Status::kOk);
  ASSERT_EQ(evidence.Evaluate(truth, &lml_truth), Status::kOk);
  EXPECT_NEAR(-lml, summary.final_negative_log_likelihood, 1e-9 * std::abs(lml));
  EXPECT_GE(lml, lml_truth);
}

// k_pol features of a 2-joint robot (D = 133), m = 500: also prints the cost of a fit.
TEST(FitHyperparameters, PolMapRecoversNoiseLevel) {
  auto rng = SeededRng(202);
  const auto map = std::make_shared<PolFeatureMap>(2);
  ASSERT_EQ(map->dim(), 133);
  Hyperparameters truth = DefaultHyperparameters(*map, 2);
  truth.shape << 0.3;
  truth.log_noise_std = std::log(0.1);
  const Data d = SampleFromModel(*map, truth, RandomStates(500, 2, &rng), &rng);
  const auto t0 = std::chrono::steady_clock::now();
  const WeightSpaceEvidence evidence = MakeEvidence(map, d);
  const double stats_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  Hyperparameters hyper = DefaultHyperparameters(*map, 2);
  hyper.log_noise_std = std::log(0.3);
  const MaximumLikelihoodSummary summary =
      FitHyperparameters(evidence, MaximumLikelihoodOptions(), &hyper);
  std::cout << "D = 133, m = 500: statistics " << stats_seconds << " s; " << summary.BriefReport()
            << std::endl;
  std::cout << "sigma_n = " << std::exp(hyper.log_noise_std) << ", log_sigma = " << hyper.shape[0]
            << std::endl;
  EXPECT_TRUE(summary.termination == MaximumLikelihoodTermination::kConverged) << summary.message;
  // Standard error of sigma_n ~ 1 / sqrt(2 (m P - effective parameters)) ~ 3%.
  EXPECT_NEAR(std::exp(hyper.log_noise_std), 0.1, 0.01);
  EXPECT_LT(summary.final_negative_log_likelihood, summary.initial_negative_log_likelihood);
}

// Noise-free data that the features fit exactly, with fewer samples than features: the
// evidence keeps rising as sigma_n -> 0 until the posterior precision can no longer be
// factorised. With absurdly wide bounds the line search runs into that wall; every such
// evaluation is reported as failed, and nothing comes out NaN.
TEST(FitHyperparameters, FailedFactorisationsAreReportedNeverNaN) {
  auto rng = SeededRng(203);
  const auto map = Random(2, 40, 1, 5);
  const Matrix X = RandomMatrix(20, 2, 1.0, &rng);
  Matrix Phi;
  map->EvaluateRows(X, &Phi);
  Data d;
  d.X = X;
  d.Y = Phi * RandomMatrix(40, 1, 1.0, &rng);
  const WeightSpaceEvidence evidence = MakeEvidence(map, d);

  MaximumLikelihoodOptions options;
  // Plain ML-II: noise-free targets drive sigma_n towards 0 and the posterior into the wall
  // (the prior on log sigma_n would stop it well before).
  options.prior.family = HyperpriorFamily::kNone;
  options.optimize_shape = false;
  options.noise_bounds = {-49.0, 3.0};
  options.block_scale_bounds = {-40.0, 40.0};
  Hyperparameters hyper = DefaultHyperparameters(*map, 1);
  const MaximumLikelihoodSummary summary = FitHyperparameters(evidence, options, &hyper);
  std::cout << summary.BriefReport() << std::endl;
  std::cout << "log sigma_n = " << hyper.log_noise_std
            << ", log block scale = " << hyper.log_block_scale.transpose() << std::endl;
  EXPECT_GT(summary.num_failed_evaluations, 0);
  EXPECT_TRUE(summary.usable());
  EXPECT_TRUE(std::isfinite(summary.initial_negative_log_likelihood));
  EXPECT_TRUE(std::isfinite(summary.final_negative_log_likelihood));
  EXPECT_TRUE(summary.final_gradient.allFinite());
  EXPECT_TRUE(std::isfinite(hyper.log_noise_std));
  EXPECT_TRUE(hyper.log_block_scale.allFinite());
  EXPECT_LE(summary.final_negative_log_likelihood, summary.initial_negative_log_likelihood);
  EXPECT_LT(hyper.log_noise_std, std::log(0.1));  // it did move towards the wall
  // The result itself can be evaluated.
  double lml = 0.0;
  EXPECT_EQ(evidence.Evaluate(hyper, &lml), Status::kOk);
  EXPECT_TRUE(std::isfinite(lml));
}

TEST(FitHyperparameters, StartThatCannotBeEvaluatedLeavesHyperUnchanged) {
  auto rng = SeededRng(204);
  const auto map = Random(2, 40, 1, 5);
  const Matrix X = RandomMatrix(20, 2, 1.0, &rng);
  Matrix Phi;
  map->EvaluateRows(X, &Phi);
  Data d;
  d.X = X;
  d.Y = Phi * RandomMatrix(40, 1, 1.0, &rng);
  const WeightSpaceEvidence evidence = MakeEvidence(map, d);
  MaximumLikelihoodOptions options;
  options.noise_bounds = {-49.0, 3.0};
  options.block_scale_bounds = {-40.0, 40.0};
  Hyperparameters hyper = DefaultHyperparameters(*map, 1);
  hyper.log_noise_std = -45.0;  // sigma_n^2 = 1e-39: A = Phi^T Phi (rank 20 of 40) + ~0
  hyper.log_block_scale << 35.0;
  double lml = 0.0;
  ASSERT_NE(evidence.Evaluate(hyper, &lml), Status::kOk) << "the start is meant to fail";
  const Hyperparameters before = hyper;
  const MaximumLikelihoodSummary summary = FitHyperparameters(evidence, options, &hyper);
  EXPECT_EQ(summary.termination, MaximumLikelihoodTermination::kInitialPointFailed);
  EXPECT_FALSE(summary.usable());
  EXPECT_EQ(summary.num_failed_evaluations, 1);
  EXPECT_EQ(hyper.log_noise_std, before.log_noise_std);
  EXPECT_EQ(hyper.log_block_scale, before.log_block_scale);
  EXPECT_EQ(summary.final_negative_log_likelihood, HUGE_VAL);
}

TEST(FitHyperparameters, NothingFreeAndBadStarts) {
  auto rng = SeededRng(205);
  const auto map = Random(2, 10, 2, 9);
  Hyperparameters hyper = DefaultHyperparameters(*map, 1);
  const Data d = SampleFromModel(*map, hyper, RandomMatrix(60, 2, 1.0, &rng), &rng);
  const WeightSpaceEvidence evidence = MakeEvidence(map, d);

  MaximumLikelihoodOptions none;
  none.optimize_shape = none.optimize_block_scales = none.optimize_noise = false;
  const MaximumLikelihoodSummary summary = FitHyperparameters(evidence, none, &hyper);
  EXPECT_EQ(summary.termination, MaximumLikelihoodTermination::kNoFreeParameters);
  double lml = 0.0;
  ASSERT_EQ(evidence.Evaluate(hyper, &lml), Status::kOk);
  EXPECT_DOUBLE_EQ(summary.initial_negative_log_likelihood, -lml);
  EXPECT_DOUBLE_EQ(summary.final_negative_log_likelihood, -lml);

  Hyperparameters outside = hyper;
  outside.log_noise_std = -13.0;  // below the default bound -12
  try {
    FitHyperparameters(evidence, MaximumLikelihoodOptions(), &outside);
    ADD_FAILURE() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("log_noise_std"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("noise_bounds"), std::string::npos) << e.what();
  }
  Hyperparameters wrong_size = hyper;
  wrong_size.log_block_scale.resize(3);
  EXPECT_THROW(FitHyperparameters(evidence, MaximumLikelihoodOptions(), &wrong_size),
               std::invalid_argument);
  MaximumLikelihoodOptions bad;
  bad.max_iterations = -1;
  EXPECT_THROW(FitHyperparameters(evidence, bad, &hyper), std::invalid_argument);
  EXPECT_THROW(FitHyperparameters(evidence, MaximumLikelihoodOptions(), nullptr),
               std::invalid_argument);
}

TEST(FitHyperparameters, MaxIterationsIsReported) {
  auto rng = SeededRng(206);
  const auto map = Random(3, 30, 2, 21);
  Hyperparameters truth = DefaultHyperparameters(*map, 1);
  truth.shape << 0.5;
  const Data d = SampleFromModel(*map, truth, RandomMatrix(300, 3, 1.0, &rng), &rng);
  const WeightSpaceEvidence evidence = MakeEvidence(map, d);
  Hyperparameters hyper = DefaultHyperparameters(*map, 1);
  hyper.log_noise_std = std::log(2.0);
  MaximumLikelihoodOptions options;
  options.max_iterations = 2;
  options.verbose = true;  // progress lines on stderr
  const MaximumLikelihoodSummary summary = FitHyperparameters(evidence, options, &hyper);
  EXPECT_EQ(summary.termination, MaximumLikelihoodTermination::kMaxIterations)
      << summary.BriefReport();
  EXPECT_LE(summary.iterations, 2);
  EXPECT_LT(summary.final_negative_log_likelihood, summary.initial_negative_log_likelihood);
}

// ---- ML-II in function space ------------------------------------------------------------------

TEST(KernelEvidenceObjective, GradientMatchesCentralDifferences) {
  auto rng = SeededRng(301);
  const auto map = Random(2, 16, 2, 13);
  Hyperparameters truth = DefaultHyperparameters(*map, 2);
  truth.shape << 0.3;
  const Data d = SampleFromModel(*map, truth, RandomMatrix(60, 2, 1.0, &rng), &rng);
  Hyperparameters kernel_hyper = truth;
  kernel_hyper.shape << -0.2;
  kernel_hyper.log_block_scale << 0.3, -0.1;
  const FeatureKernel kernel(map, kernel_hyper);
  MaximumLikelihoodOptions options;
  options.optimize_output_scales = true;
  Hyperparameters start = DefaultHyperparameters(kernel, 2);
  start.log_noise_std = std::log(0.2);
  start.log_output_scale << 0.2, -0.1;
  const KernelEvidenceObjective objective(kernel, d.X, d.Y, options, start);
  const std::vector<std::string> expected = {"log_decay",          "log_scale_b0",
                                             "log_scale_b1",       "log_noise_std",
                                             "log_output_scale_1", "log_output_scale_2"};
  EXPECT_EQ(objective.names(), expected);
  const Vector x = objective.Flatten(start);
  double cost = 0.0;
  Vector gradient(x.size());
  ASSERT_TRUE(objective.Evaluate(x.data(), &cost, gradient.data()));
  const Vector fd = CentralDifferences(objective, x, 1e-5);
  for (Eigen::Index i = 0; i < x.size(); ++i) {
    EXPECT_NEAR(gradient[i], fd[i], 1e-7 * std::max(1.0, std::abs(fd[i])))
        << objective.names()[static_cast<size_t>(i)];
  }
}

// rbf on noisy samples of a smooth function, from a poor start (length scale 5, sigma_n 0.5).
TEST(FitKernelHyperparameters, RbfImprovesEvidence) {
  auto rng = SeededRng(302);
  const int m = 120;
  Data d;
  d.X = RandomMatrix(m, 1, 1.5, &rng);
  d.Y = (2.0 * d.X).array().sin().matrix() + RandomMatrix(m, 1, 0.1, &rng);
  const RbfKernel kernel(1, false, 5.0, 1.0);
  Hyperparameters hyper = DefaultHyperparameters(kernel, 1);
  hyper.log_noise_std = std::log(0.5);
  const MaximumLikelihoodSummary summary =
      FitKernelHyperparameters(kernel, d.X, d.Y, MaximumLikelihoodOptions(), &hyper);
  std::cout << summary.BriefReport() << std::endl;
  std::cout << "log l, log sf = " << hyper.shape.transpose()
            << ", sigma_n = " << std::exp(hyper.log_noise_std) << std::endl;
  const std::vector<std::string> expected = {"log_length_scale", "log_signal_std", "log_noise_std"};
  EXPECT_EQ(summary.parameter_names, expected);
  EXPECT_EQ(summary.termination, MaximumLikelihoodTermination::kConverged) << summary.message;
  EXPECT_LT(summary.final_negative_log_likelihood, summary.initial_negative_log_likelihood - 50.0);
  EXPECT_LT(summary.final_gradient.lpNorm<Eigen::Infinity>(), 1e-4);
  EXPECT_EQ(kernel.parameters()[0], std::log(5.0));  // the kernel passed in is not modified
  // The summary's value is the evidence of a KernelGP built from the result.
  std::unique_ptr<Kernel> fitted = kernel.Clone();
  fitted = fitted->WithParameters(hyper.shape);
  KernelGP model(*fitted, std::exp(2.0 * hyper.log_noise_std), 1);
  ASSERT_EQ(model.Fit(d.X, d.Y), Status::kOk);
  EXPECT_NEAR(-model.LogMarginalLikelihood(), summary.final_negative_log_likelihood,
              1e-9 * std::abs(summary.final_negative_log_likelihood));
  // True sigma_n = 0.1 from m = 120: within 25% (standard error ~ 7%).
  EXPECT_NEAR(std::exp(hyper.log_noise_std), 0.1, 0.025);
}

// With a FeatureKernel, the kernel form has the weight-space likelihood: both fits reach the
// same optimum.
TEST(FitKernelHyperparameters, FeatureKernelMatchesWeightSpace) {
  auto rng = SeededRng(303);
  const auto map = Random(2, 12, 2, 17);
  Hyperparameters truth = DefaultHyperparameters(*map, 2);
  truth.shape << 0.6;
  truth.log_block_scale << 0.4, -0.5;
  truth.log_noise_std = std::log(0.1);
  const Data d = SampleFromModel(*map, truth, RandomMatrix(150, 2, 1.0, &rng), &rng);
  const WeightSpaceEvidence evidence = MakeEvidence(map, d);

  Hyperparameters weight_hyper = DefaultHyperparameters(*map, 2);
  weight_hyper.log_noise_std = std::log(0.3);
  MaximumLikelihoodOptions options;
  const MaximumLikelihoodSummary weight_summary =
      FitHyperparameters(evidence, options, &weight_hyper);

  const FeatureKernel kernel(map, DefaultHyperparameters(*map, 2));
  Hyperparameters kernel_hyper = DefaultHyperparameters(kernel, 2);
  kernel_hyper.log_noise_std = std::log(0.3);
  const MaximumLikelihoodSummary kernel_summary =
      FitKernelHyperparameters(kernel, d.X, d.Y, options, &kernel_hyper);
  std::cout << "weight space: " << weight_summary.BriefReport() << std::endl;
  std::cout << "kernel form:  " << kernel_summary.BriefReport() << std::endl;

  EXPECT_EQ(weight_summary.parameter_names, kernel_summary.parameter_names);
  ASSERT_EQ(weight_summary.termination, MaximumLikelihoodTermination::kConverged);
  ASSERT_EQ(kernel_summary.termination, MaximumLikelihoodTermination::kConverged);
  // Same function at the same start: the two forms agree to rounding (O(m eps cond)).
  EXPECT_NEAR(weight_summary.initial_negative_log_likelihood,
              kernel_summary.initial_negative_log_likelihood,
              1e-9 * std::abs(weight_summary.initial_negative_log_likelihood));
  EXPECT_NEAR(weight_summary.final_negative_log_likelihood,
              kernel_summary.final_negative_log_likelihood,
              1e-8 * std::abs(weight_summary.final_negative_log_likelihood));
  Vector weight_x(4), kernel_x(4);
  weight_x << weight_hyper.shape, weight_hyper.log_block_scale, weight_hyper.log_noise_std;
  kernel_x << kernel_hyper.shape, kernel_hyper.log_noise_std;
  std::cout << "weight space x = " << weight_x.transpose() << std::endl;
  std::cout << "kernel form  x = " << kernel_x.transpose() << std::endl;
  // Both are stationary to |gradient| <~ 1e-5 of an objective whose curvature is of order n:
  // the optima agree far better than 1e-3.
  EXPECT_LT((weight_x - kernel_x).lpNorm<Eigen::Infinity>(), 1e-3);
}

// ---- cross-validation ---------------------------------------------------------------------------

TEST(SegmentFolds, HoldOutWholeTrajectoriesWhenThereAreEnough) {
  // Trajectories of unequal length: 0..29, 30..39, 40..99, 100..119, 120..149, 150..199.
  const std::vector<int> starts = {0, 30, 40, 100, 120, 150};
  for (int k : {2, 3, 4, 5, 6}) {
    const auto folds = SegmentFolds(200, k, starts);
    ASSERT_EQ(folds.size(), static_cast<size_t>(k));
    EXPECT_EQ(folds.front().first, 0);
    EXPECT_EQ(folds.back().second, 200);
    for (size_t f = 0; f < folds.size(); ++f) {
      EXPECT_LT(folds[f].first, folds[f].second) << "k " << k << " fold " << f;
      if (f > 0) {
        EXPECT_EQ(folds[f].first, folds[f - 1].second);
      }
      // Every boundary is the start of a trajectory.
      EXPECT_NE(std::find(starts.begin(), starts.end(), folds[f].first), starts.end())
          << "k " << k << " fold " << f << " begins inside a trajectory at " << folds[f].first;
    }
  }
  // With as many folds as trajectories, each fold is one trajectory.
  const auto six = SegmentFolds(200, 6, starts);
  for (size_t f = 0; f < 6; ++f) EXPECT_EQ(six[f].first, starts[f]);
  // Fewer trajectories than folds: the plain contiguous blocks.
  EXPECT_EQ(SegmentFolds(200, 7, starts), ContiguousFolds(200, 7));
  EXPECT_EQ(SegmentFolds(200, 5, {0}), ContiguousFolds(200, 5));
  EXPECT_THROW(SegmentFolds(200, 3, {0, 50, 40}), std::invalid_argument);
  EXPECT_THROW(SegmentFolds(200, 3, {10, 50}), std::invalid_argument);
  EXPECT_EQ(SegmentStarts(Vector::LinSpaced(5, 0.0, 1.0)), (std::vector<int>{0}));
  Vector t(6);
  t << 0.0, 0.5, 0.5, 0.0, 1.0, 0.2;
  EXPECT_EQ(SegmentStarts(t), (std::vector<int>{0, 3, 5}));
}

TEST(ContiguousFolds, CoverEveryRowOnceInTimeOrder) {
  for (const auto& [m, k] :
       std::vector<std::pair<int, int>>{{10, 1}, {10, 3}, {10, 10}, {97, 5}, {1000, 7}, {5, 2}}) {
    const auto folds = ContiguousFolds(m, k);
    ASSERT_EQ(static_cast<int>(folds.size()), k);
    EXPECT_EQ(folds.front().first, 0);
    EXPECT_EQ(folds.back().second, m);
    int min_size = m, max_size = 0;
    for (size_t f = 0; f < folds.size(); ++f) {
      EXPECT_LT(folds[f].first, folds[f].second) << "empty fold " << f;
      if (f > 0) {
        EXPECT_EQ(folds[f].first, folds[f - 1].second) << "gap or overlap at " << f;
      }
      min_size = std::min(min_size, folds[f].second - folds[f].first);
      max_size = std::max(max_size, folds[f].second - folds[f].first);
    }
    EXPECT_LE(max_size - min_size, 1) << "m = " << m << ", k = " << k;
  }
  EXPECT_THROW(ContiguousFolds(5, 6), std::invalid_argument);
  EXPECT_THROW(ContiguousFolds(5, 0), std::invalid_argument);
}

// Reference: fit each fold from scratch on the raw rows of the other folds and predict the
// held-out rows one by one.
CrossValidationResult RefitEachFold(const FeatureMap& map, const Data& d, int k,
                                    const Hyperparameters& hyper) {
  const int m = static_cast<int>(d.X.rows());
  const int P = static_cast<int>(d.Y.cols());
  Matrix Phi;
  map.EvaluateRows(d.X, &Phi);
  CrossValidationResult result;
  Vector sse_total = Vector::Zero(P);
  for (const auto& [begin, end] : ContiguousFolds(m, k)) {
    std::vector<int> train;
    for (int i = 0; i < m; ++i) {
      if (i < begin || i >= end) train.push_back(i);
    }
    WeightSpaceGP model(PriorVariance(map, hyper), hyper.noise_variance(), P,
                        hyper.output_scales());
    EXPECT_EQ(model.Fit(SelectRows(Phi, train), SelectRows(d.Y, train)), Status::kOk);
    const Matrix held_out = d.Y.middleRows(begin, end - begin);
    Matrix prediction(end - begin, P);
    Vector mean(P);
    for (int i = begin; i < end; ++i) {
      EXPECT_EQ(model.Predict(Phi.row(i).transpose(), mean), Status::kOk);
      prediction.row(i - begin) = mean.transpose();
    }
    FoldError fold;
    fold.begin = begin;
    fold.end = end;
    const Vector sse = (held_out - prediction).colwise().squaredNorm().transpose();
    sse_total += sse;
    const Vector variance =
        (held_out.rowwise() - held_out.colwise().mean()).colwise().squaredNorm().transpose() /
        (end - begin);
    fold.rms = (sse / (end - begin)).cwiseSqrt();
    fold.nmse = (sse / (end - begin)).cwiseQuotient(variance);
    result.folds.push_back(fold);
  }
  const Vector variance =
      (d.Y.rowwise() - d.Y.colwise().mean()).colwise().squaredNorm().transpose() / m;
  result.rms = (sse_total / m).cwiseSqrt();
  result.nmse = (sse_total / m).cwiseQuotient(variance);
  result.mean_nmse = result.nmse.mean();
  return result;
}

TEST(BlockedCrossValidation, SubtractedStatisticsEqualRefittingEachFold) {
  auto rng = SeededRng(401);
  const auto map = Random(3, 25, 2, 31);
  Hyperparameters truth = DefaultHyperparameters(*map, 2);
  truth.shape << 0.2;
  const Data d = SampleFromModel(*map, truth, RandomMatrix(1100, 3, 1.0, &rng), &rng);
  Hyperparameters hyper = truth;
  hyper.log_noise_std = std::log(0.3);
  hyper.log_output_scale << 0.5, -0.5;  // changes nothing in the posterior mean
  for (int k : {2, 5, 7}) {
    const CrossValidationResult fast = BlockedCrossValidation(*map, d.X, d.Y, k, hyper);
    const CrossValidationResult reference = RefitEachFold(*map, d, k, hyper);
    ASSERT_EQ(fast.folds.size(), reference.folds.size());
    EXPECT_EQ(fast.num_failed_folds, 0);
    for (size_t f = 0; f < fast.folds.size(); ++f) {
      EXPECT_EQ(fast.folds[f].begin, reference.folds[f].begin);
      EXPECT_EQ(fast.folds[f].end, reference.folds[f].end);
      EXPECT_EQ(fast.folds[f].status, Status::kOk);
      for (int j = 0; j < 2; ++j) {
        EXPECT_NEAR(fast.folds[f].rms[j], reference.folds[f].rms[j],
                    1e-9 * reference.folds[f].rms[j])
            << "k " << k << " fold " << f;
        EXPECT_NEAR(fast.folds[f].nmse[j], reference.folds[f].nmse[j],
                    1e-9 * reference.folds[f].nmse[j])
            << "k " << k << " fold " << f;
      }
    }
    for (int j = 0; j < 2; ++j) {
      EXPECT_NEAR(fast.rms[j], reference.rms[j], 1e-9 * reference.rms[j]);
      EXPECT_NEAR(fast.nmse[j], reference.nmse[j], 1e-9 * reference.nmse[j]);
    }
    EXPECT_NEAR(fast.mean_nmse, reference.mean_nmse, 1e-9 * reference.mean_nmse);
  }
}

TEST(FoldStatistics, FoldsSumToTotal) {
  auto rng = SeededRng(402);
  const auto map = Random(2, 8, 1, 3);
  const Data d = SampleFromModel(*map, DefaultHyperparameters(*map, 1),
                                 RandomMatrix(1300, 2, 1.0, &rng), &rng);  // > 2 chunks/fold
  const FoldStatistics data(*map, d.X, d.Y, 2);
  Matrix Phi;
  map->EvaluateRows(d.X, &Phi);
  const Matrix gram = Phi.transpose() * Phi;
  const Matrix lower_total = data.total().gram.triangularView<Eigen::Lower>();
  const Matrix lower_gram = gram.triangularView<Eigen::Lower>();
  EXPECT_LT((lower_total - lower_gram).norm(), 1e-11 * gram.norm());
  EXPECT_EQ(data.total().count, 1300.0);
  EXPECT_EQ(data.fold(1).count, 650.0);
  const SufficientStatistics training = data.Training(0);
  EXPECT_EQ(training.count, 650.0);
  const Matrix lower_training = training.gram.triangularView<Eigen::Lower>();
  const Matrix lower_fold1 = data.fold(1).gram.triangularView<Eigen::Lower>();
  EXPECT_LT((lower_training - lower_fold1).norm(), 1e-11 * gram.norm());
  EXPECT_NEAR(data.target_sum(0)[0], d.Y.topRows(650).sum(), 1e-9);
  EXPECT_THROW(FoldStatistics(*map, d.X, d.Y, 1), std::invalid_argument);
  EXPECT_THROW(FoldStatistics(*map, d.X, d.Y.topRows(10), 3), std::invalid_argument);
}

TEST(SelectByCrossValidation, PicksTheLowestErrorOfAGrid) {
  auto rng = SeededRng(403);
  const auto map = std::make_shared<PolFeatureMap>(1);
  Hyperparameters truth = DefaultHyperparameters(*map, 1);
  truth.shape << 0.5;
  truth.log_noise_std = std::log(0.05);
  const Data d = SampleFromModel(*map, truth, RandomStates(400, 1, &rng), &rng);
  const FoldStatistics data(*map, d.X, d.Y, 5);
  const std::vector<Hyperparameters> grid = HyperparameterGrid(
      truth, {-1.0, 0.0, 0.5, 1.0}, {std::log(0.05), std::log(5.0), std::log(50.0)});
  ASSERT_EQ(grid.size(), 12u);
  EXPECT_EQ(grid[1].shape[0], -1.0);
  EXPECT_EQ(grid[1].log_noise_std, std::log(5.0));
  std::vector<CrossValidationResult> results;
  int best = -2;
  const Hyperparameters selected = SelectByCrossValidation(*map, data, grid, &results, &best);
  ASSERT_EQ(results.size(), grid.size());
  ASSERT_GE(best, 0);
  for (const CrossValidationResult& r : results) EXPECT_GE(r.mean_nmse, results[best].mean_nmse);
  EXPECT_EQ(selected.shape, grid[static_cast<size_t>(best)].shape);
  EXPECT_EQ(selected.log_noise_std, grid[static_cast<size_t>(best)].log_noise_std);
  // Heavy over-regularisation (sigma_n 100 and 1000 times the truth) loses.
  EXPECT_EQ(selected.log_noise_std, std::log(0.05));
  EXPECT_LT(results[best].mean_nmse, 0.1);
  EXPECT_THROW(SelectByCrossValidation(*map, data, {}), std::invalid_argument);
}

TEST(TrainTestSplit, FirstThirdOfEachTrajectory) {
  // Trajectory 7 has 6 rows, 3 has 3 rows (interleaved with 7), 9 has 4 rows.
  const std::vector<int> ids = {7, 7, 3, 7, 3, 3, 7, 7, 7, 9, 9, 9, 9};
  const TrainTestSplit split = TrainTestSplitPerTrajectory(ids);
  // 7: rows 0 1 3 6 7 8 -> train 0 1; 3: rows 2 4 5 -> train 2; 9: rows 9..12 -> train 9.
  EXPECT_EQ(split.train, (std::vector<int>{0, 1, 2, 9}));
  EXPECT_EQ(split.test, (std::vector<int>{3, 4, 5, 6, 7, 8, 10, 11, 12}));

  const TrainTestSplit segments = TrainTestSplitPerSegment({{10, 19}, {0, 10}}, 1.0 / 3.0);
  EXPECT_EQ(segments.train, (std::vector<int>{0, 1, 2, 10, 11, 12}));
  EXPECT_EQ(segments.test.size(), 13u);
  EXPECT_EQ(segments.test.front(), 3);
  EXPECT_EQ(segments.test.back(), 18);
  const TrainTestSplit all = TrainTestSplitPerSegment({{0, 4}}, 1.0);
  EXPECT_EQ(all.train.size(), 4u);
  EXPECT_TRUE(all.test.empty());
  EXPECT_THROW(TrainTestSplitPerSegment({{0, 5}, {4, 8}}), std::invalid_argument);
  EXPECT_THROW(TrainTestSplitPerTrajectory(ids, 1.5), std::invalid_argument);

  Matrix X(4, 2);
  X << 0, 1, 2, 3, 4, 5, 6, 7;
  const Matrix rows = SelectRows(X, {3, 1});
  EXPECT_EQ(rows(0, 0), 6.0);
  EXPECT_EQ(rows(1, 1), 3.0);
  EXPECT_THROW(SelectRows(X, {4}), std::invalid_argument);
}

}  // namespace
}  // namespace structgp
