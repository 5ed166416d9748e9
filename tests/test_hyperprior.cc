// The prior on the log hyper-parameters (type-II MAP) and the multi-start search, against
// independent references: the density written out by hand, central finite differences of the
// penalised objective (weight space and kernel form, Gaussian and Student-t, away from the
// prior's centre), the objective without a prior plus the prior, and single-start runs from
// the same points.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <iostream>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "structgp/feature/random_feature_map.h"
#include "structgp/feature/sum_feature_map.h"
#include "structgp/hyper/evidence.h"
#include "structgp/hyper/hyperprior.h"
#include "structgp/hyper/marginal_likelihood.h"
#include "structgp/kernel/feature_kernel.h"
#include "structgp/kernel/rbf_kernel.h"
#include "structgp/model/weight_space_gp.h"

namespace structgp {
namespace {

std::mt19937_64 SeededRng(std::uint64_t seed) {
  std::cout << "[ seed     ] " << seed << std::endl;
  return std::mt19937_64(seed);
}

Matrix RandomMatrix(int rows, int cols, double scale, std::mt19937_64* rng) {
  std::normal_distribution<double> normal(0.0, scale);
  return Matrix::NullaryExpr(rows, cols, [&]() { return normal(*rng); });
}

WeightSpaceEvidence MakeEvidence(std::shared_ptr<const FeatureMap> map, const Matrix& X,
                                 const Matrix& Y) {
  SufficientStatistics stats(map->dim(), static_cast<int>(Y.cols()));
  Matrix Phi;
  map->EvaluateRows(X, &Phi);
  stats.Accumulate(Phi, Y);
  return WeightSpaceEvidence(std::move(map), std::move(stats));
}

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

// ---- the density ----------------------------------------------------------------------------

TEST(LogHyperprior, DensityAndGradientByHand) {
  Vector centre(3), width(3), x(3);
  centre << 0.0, -2.0, 1.0;
  width << 1.0, 0.5, 2.0;
  x << 0.7, -3.0, 1.0;
  const LogHyperprior gaussian(HyperpriorFamily::kGaussian, centre, width);
  Vector g = Vector::Zero(3);
  const double value = gaussian.NegativeLogDensity(x, g.data());
  // z = 0.7, -2, 0.
  EXPECT_NEAR(value, 0.5 * (0.49 + 4.0), 1e-15);
  EXPECT_NEAR(g[0], 0.7, 1e-15);
  EXPECT_NEAR(g[1], -2.0 / 0.5, 1e-15);
  EXPECT_EQ(g[2], 0.0);
  EXPECT_NEAR(gaussian.Terms(x).sum(), value, 1e-15);

  const double nu = 3.0;
  const LogHyperprior t(HyperpriorFamily::kStudentT, centre, width, nu);
  g.setZero();
  const double tv = t.NegativeLogDensity(x, g.data());
  const double expected = 0.5 * (nu + 1.0) * (std::log(1.0 + 0.49 / nu) + std::log(1.0 + 4.0 / nu));
  EXPECT_NEAR(tv, expected, 1e-14);
  // Gradient against central differences of the density itself.
  for (int i = 0; i < 3; ++i) {
    Vector plus = x, minus = x;
    plus[i] += 1e-6;
    minus[i] -= 1e-6;
    const double fd = (t.NegativeLogDensity(plus) - t.NegativeLogDensity(minus)) / 2e-6;
    EXPECT_NEAR(g[i], fd, 1e-8) << i;
  }
  // Heavier tails: far from the centre the t costs less than the Gaussian.
  Vector far = centre;
  far[0] += 6.0;
  EXPECT_LT(t.NegativeLogDensity(far), gaussian.NegativeLogDensity(far));

  const LogHyperprior none;
  EXPECT_FALSE(none.active());
  EXPECT_EQ(none.NegativeLogDensity(x), 0.0);
  EXPECT_THROW(LogHyperprior(HyperpriorFamily::kGaussian, centre, Vector::Zero(3)),
               std::invalid_argument);
  EXPECT_THROW(LogHyperprior(HyperpriorFamily::kGaussian, centre, Vector::Ones(2)),
               std::invalid_argument);
}

TEST(HyperpriorOptions, ValidationAndTightening) {
  HyperpriorOptions o;
  std::string error;
  EXPECT_TRUE(o.IsValid(&error)) << error;
  EXPECT_EQ(o.family, HyperpriorFamily::kGaussian);
  EXPECT_NEAR(std::exp(2.0 * o.block_scale_width), 10.0, 1e-12);  // a decade at two widths
  HyperpriorOptions bad = o;
  bad.noise_width = 0.0;
  EXPECT_FALSE(bad.IsValid(&error));
  EXPECT_NE(error.find("noise_width"), std::string::npos) << error;
  bad.family = HyperpriorFamily::kNone;  // no prior: widths are not used
  EXPECT_TRUE(bad.IsValid(nullptr));
  const HyperpriorOptions tight = o.Tightened(4.0);
  EXPECT_EQ(tight.kernel_parameter_width, o.kernel_parameter_width / 4.0);
  EXPECT_EQ(tight.shape_width, o.shape_width / 4.0);
  EXPECT_THROW(o.Tightened(0.0), std::invalid_argument);
  MaximumLikelihoodOptions ml;
  ml.prior.block_scale_width = -1.0;
  EXPECT_FALSE(ml.IsValid(&error));
  EXPECT_NE(error.find("prior"), std::string::npos) << error;
  ml = MaximumLikelihoodOptions();
  ml.num_starts = 0;
  EXPECT_FALSE(ml.IsValid(&error));
  EXPECT_NE(error.find("num_starts"), std::string::npos) << error;

  HyperpriorFamily family;
  EXPECT_TRUE(FromString("student_t", &family));
  EXPECT_EQ(family, HyperpriorFamily::kStudentT);
  EXPECT_FALSE(FromString("cauchy", &family));
}

// ---- the penalised objective ----------------------------------------------------------------

struct Problem {
  std::shared_ptr<const FeatureMap> map;
  Matrix X, Y;
  Hyperparameters start;  // the prior's centre
};

Problem SmallProblem(std::mt19937_64* rng) {
  Problem p;
  p.map = std::make_shared<RandomFeatureMap>(2, 24, 3, 7);
  p.X = RandomMatrix(150, 2, 1.0, rng);
  Matrix Phi;
  p.map->EvaluateRows(p.X, &Phi);
  p.Y = Phi * RandomMatrix(24, 2, 0.5, rng) + RandomMatrix(150, 2, 0.1, rng);
  p.start = DefaultHyperparameters(*p.map, 2);
  p.start.log_block_scale << 0.2, -0.3, 0.1;
  p.start.log_noise_std = std::log(0.25);
  p.start.log_output_scale << 0.1, -0.4;
  return p;
}

// Cost = objective without a prior + prior by hand, and the gradient against central
// differences, at a point away from the centre (where the prior's gradient is not zero).
TEST(EvidenceObjective, PenalisedCostAndGradient) {
  for (HyperpriorFamily family : {HyperpriorFamily::kGaussian, HyperpriorFamily::kStudentT}) {
    SCOPED_TRACE(ToString(family));
    auto rng = SeededRng(501);
    const Problem p = SmallProblem(&rng);
    const WeightSpaceEvidence evidence = MakeEvidence(p.map, p.X, p.Y);
    MaximumLikelihoodOptions options;
    options.optimize_output_scales = true;
    options.prior.family = family;
    options.prior.shape_width = 0.7;
    options.prior.block_scale_width = 0.4;
    options.prior.noise_width = 0.9;
    options.prior.output_scale_width = 1.3;
    options.prior.degrees_of_freedom = 2.5;
    MaximumLikelihoodOptions plain = options;
    plain.prior.family = HyperpriorFamily::kNone;
    const EvidenceObjective objective(evidence, options, p.start);
    const EvidenceObjective without(evidence, plain, p.start);
    ASSERT_EQ(objective.num_parameters(), 1 + 3 + 1 + 2);
    const Vector centre = objective.layout().Flatten(p.start);
    EXPECT_EQ(objective.prior().centre(), centre);
    Vector width(7);
    width << 0.7, 0.4, 0.4, 0.4, 0.9, 1.3, 1.3;
    EXPECT_EQ(objective.prior().width(), width);

    Vector x = centre;
    x << 0.3, 0.5, -0.9, 0.4, std::log(0.15), 0.3, -0.1;
    double cost = 0.0, cost_plain = 0.0;
    Vector gradient(7);
    ASSERT_TRUE(objective.Evaluate(x.data(), &cost, gradient.data()));
    ASSERT_TRUE(without.Evaluate(x.data(), &cost_plain, nullptr));
    double prior = 0.0;
    for (int i = 0; i < 7; ++i) {
      const double z = (x[i] - centre[i]) / width[i];
      const double nu = 2.5;
      prior += family == HyperpriorFamily::kGaussian ? 0.5 * z * z
                                                     : 0.5 * (nu + 1.0) * std::log1p(z * z / nu);
    }
    EXPECT_GT(prior, 1.0);  // the prior term matters at this point
    EXPECT_NEAR(cost, cost_plain + prior / objective.num_observations(), 1e-14 * (1.0 + cost));

    const Vector fd = CentralDifferences(objective, x, 1e-5);
    for (Eigen::Index i = 0; i < x.size(); ++i) {
      EXPECT_NEAR(gradient[i], fd[i], 1e-7 * std::max(1.0, std::abs(fd[i])))
          << objective.layout().names()[static_cast<size_t>(i)];
    }
  }
}

TEST(KernelEvidenceObjective, PenalisedCostAndGradient) {
  for (HyperpriorFamily family : {HyperpriorFamily::kGaussian, HyperpriorFamily::kStudentT}) {
    SCOPED_TRACE(ToString(family));
    auto rng = SeededRng(502);
    Problem p = SmallProblem(&rng);
    p.X.conservativeResize(60, Eigen::NoChange);
    p.Y.conservativeResize(60, Eigen::NoChange);
    const FeatureKernel kernel(p.map, p.start);
    MaximumLikelihoodOptions options;
    options.optimize_output_scales = true;
    options.prior.family = family;
    options.prior.kernel_parameter_width = 0.5;
    options.prior.noise_width = 0.8;
    options.prior.output_scale_width = 1.1;
    MaximumLikelihoodOptions plain = options;
    plain.prior.family = HyperpriorFamily::kNone;
    Hyperparameters start = DefaultHyperparameters(kernel, 2);
    start.log_noise_std = std::log(0.2);
    start.log_output_scale << 0.2, -0.1;
    const KernelEvidenceObjective objective(kernel, p.X, p.Y, options, start);
    const KernelEvidenceObjective without(kernel, p.X, p.Y, plain, start);
    const Vector centre = objective.Flatten(start);
    EXPECT_EQ(objective.prior().centre(), centre);
    Vector x = centre;
    x.array() += Vector::LinSpaced(x.size(), -0.6, 0.5).array();
    double cost = 0.0, cost_plain = 0.0;
    Vector gradient(x.size());
    ASSERT_TRUE(objective.Evaluate(x.data(), &cost, gradient.data()));
    ASSERT_TRUE(without.Evaluate(x.data(), &cost_plain, nullptr));
    const double prior = objective.prior().NegativeLogDensity(x);
    EXPECT_GT(prior, 0.5);
    EXPECT_NEAR(cost, cost_plain + prior / objective.num_observations(), 1e-14 * (1.0 + cost));
    const Vector fd = CentralDifferences(objective, x, 1e-5);
    for (Eigen::Index i = 0; i < x.size(); ++i) {
      EXPECT_NEAR(gradient[i], fd[i], 1e-7 * std::max(1.0, std::abs(fd[i])))
          << objective.names()[static_cast<size_t>(i)];
    }
  }
}

// ---- multi-start ------------------------------------------------------------------------------

// A one-dimensional rbf problem with two optima of the evidence: a short length scale that
// follows a fast sinusoid, and a long one that calls it noise. From a long length scale one
// LBFGS run stays in the worse optimum; the multi-start search must return the best of its
// runs, and every run must equal a single-start search from the same point.
TEST(FitKernelHyperparameters, MultiStartKeepsTheBestRun) {
  auto rng = SeededRng(503);
  const int m = 80;
  Matrix X = RandomMatrix(m, 1, 2.0, &rng);
  Matrix Y = (3.0 * X).array().sin().matrix() + RandomMatrix(m, 1, 0.2, &rng);
  const RbfKernel kernel(1, false, 20.0, 1.0);
  MaximumLikelihoodOptions options;
  options.prior.family = HyperpriorFamily::kNone;
  options.num_starts = 6;
  options.start_perturbation = 2.0;
  options.seed = 7;
  Hyperparameters start = DefaultHyperparameters(kernel, 1);
  start.log_noise_std = std::log(0.8);
  Hyperparameters hyper = start;
  const MaximumLikelihoodSummary summary =
      FitKernelHyperparameters(kernel, X, Y, options, &hyper);
  std::cout << summary.BriefReport() << std::endl;
  ASSERT_EQ(summary.starts.size(), 6u);
  ASSERT_GE(summary.best_start, 0);
  double lowest = HUGE_VAL;
  for (const MaximumLikelihoodStart& s : summary.starts) {
    if (s.usable) lowest = std::min(lowest, s.objective);
  }
  EXPECT_EQ(summary.starts[static_cast<size_t>(summary.best_start)].objective, lowest);
  EXPECT_EQ(summary.final_negative_log_likelihood, lowest);  // no prior
  EXPECT_EQ(hyper.shape, summary.starts[static_cast<size_t>(summary.best_start)].hyperparameters.shape);
  EXPECT_EQ(summary.StartsByObjective().front(), summary.best_start);

  // Each run is the single-start search from its own starting point.
  MaximumLikelihoodOptions single = options;
  single.num_starts = 1;
  for (size_t k = 0; k < summary.starts.size(); ++k) {
    const MaximumLikelihoodStart& s = summary.starts[k];
    Hyperparameters from = start;
    from.shape << s.initial_x[0], s.initial_x[1];
    from.log_noise_std = s.initial_x[2];
    const MaximumLikelihoodSummary one = FitKernelHyperparameters(kernel, X, Y, single, &from);
    EXPECT_EQ(one.final_negative_log_likelihood, s.negative_log_likelihood) << "start " << k + 1;
  }
  // The given start alone ends in the worse optimum (noise explains the sinusoid): the
  // search found a better one by at least tens of nats.
  EXPECT_LT(lowest, summary.starts[0].objective - 10.0);
  EXPECT_NE(summary.best_start, 0);
  // The winner follows the sinusoid: sigma_n near the 0.2 of the data.
  EXPECT_NEAR(std::exp(hyper.log_noise_std), 0.2, 0.06);
}

}  // namespace
}  // namespace structgp
