// The held-out check of fitted hyper-parameters (fit/fit_check.h) on models built to be
// confidently absurd and on sane ones, with the expected verdicts computed from the data
// independently of the check; and FitModel's fallback when a search result fails it.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <iostream>
#include <random>
#include <stdexcept>

#include "structgp/fit/fit_check.h"
#include "structgp/fit/fit_model.h"
#include "structgp/model/model_spec.h"
#include "structgp/model/robot_model.h"

namespace structgp {
namespace {

// One joint, 250 rows in time order, motor model tau = c1 qdd + c2 qd. Torques saturate:
// tau = tanh(qdd) + small noise. In the last fifth of the log (the last held-out block)
// qdd is 100 times larger, so a linear model fitted on the other blocks predicts torques far
// outside the training range there, with a small variance (its two coefficients are well
// determined by 200 rows).
struct Log {
  Matrix X;  // q, qd, qdd
  Matrix Y;
};

Log SaturatingLog(bool spike_at_end, std::uint64_t seed) {
  std::cout << "[ seed     ] " << seed << std::endl;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  const int m = 250;
  Log log;
  log.X.resize(m, 3);
  log.Y.resize(m, 1);
  for (int i = 0; i < m; ++i) {
    const double qdd = (spike_at_end && i >= 200 ? 100.0 : 1.0) * normal(rng);
    log.X(i, 0) = 0.01 * i;
    log.X(i, 1) = 0.3 * normal(rng);
    log.X(i, 2) = qdd;
    log.Y(i, 0) = std::tanh(qdd) + 0.01 * normal(rng);
  }
  return log;
}

Hyperparameters MotorHyper(const RobotModel& model, const Matrix& Y, double noise) {
  Hyperparameters h = model.DefaultHyperparameters(Y);
  h.log_noise_std = std::log(noise);
  return h;
}

TEST(CheckOnHeldOutBlocks, FlagsAConfidentlyAbsurdModel) {
  const Log log = SaturatingLog(/*spike_at_end=*/true, 601);
  const RobotModel model(ParseModelSpec("motor"), 1);
  FitCheckOptions options;
  options.folds = 5;
  const FitCheck check = CheckOnHeldOutBlocks(model, MotorHyper(model, log.Y, 0.05), log.X, log.Y,
                                              options);
  std::cout << check.message << std::endl;
  ASSERT_TRUE(check.ran);
  EXPECT_EQ(check.rows, 250);
  EXPECT_FALSE(check.passed);
  EXPECT_EQ(check.worst_joint, 1);

  // The verdict by hand: the model fitted on rows 0..199 and its predictions of rows 200..249.
  RobotModel first(ParseModelSpec("motor"), 1);
  ASSERT_EQ(first.Fit(log.X.topRows(200), log.Y.topRows(200), MotorHyper(model, log.Y, 0.05)),
            Status::kOk);
  Matrix mean, std;
  first.PredictRows(log.X.bottomRows(50), &mean, &std);
  const double lo = log.Y.minCoeff(), hi = log.Y.maxCoeff(), span = hi - lo;
  int outside = 0, confident = 0;
  for (int i = 0; i < 50; ++i) {
    const double d = std::max({0.0, mean(i, 0) - (hi + span), (lo - span) - mean(i, 0)});
    const double s = std::hypot(std(i, 0), 0.05 * std::exp(model.DefaultHyperparameters(log.Y)
                                                              .log_output_scale[0]));
    if (d > 0.0) ++outside;
    if (d > 2.0 * s) ++confident;
  }
  EXPECT_GT(outside, 10);           // many, so the test means something
  EXPECT_EQ(confident, outside);    // all of them with a small variance
  // Folds 1-4 hold ordinary rows, predicted inside the range by a model fitted with the
  // spike block, whose large qdd pin the slope near 0: none of them counts.
  EXPECT_NEAR(check.worst_fraction, outside / 250.0, 1e-12);
  EXPECT_NEAR(check.worst_confident_fraction, confident / 250.0, 1e-12);
  EXPECT_GT(check.worst_excursion, 1.0);

  // Only confident ones counted: the same verdict here.
  options.count_only_confident = true;
  EXPECT_FALSE(CheckOnHeldOutBlocks(model, MotorHyper(model, log.Y, 0.05), log.X, log.Y, options)
                   .passed);
}

TEST(CheckOnHeldOutBlocks, PassesSaneModels) {
  const RobotModel model(ParseModelSpec("motor"), 1);
  // The same saturating torques without the spike: a linear fit stays inside the range.
  const Log log = SaturatingLog(/*spike_at_end=*/false, 602);
  const FitCheck check = CheckOnHeldOutBlocks(model, MotorHyper(model, log.Y, 0.05), log.X, log.Y);
  std::cout << check.message << std::endl;
  EXPECT_TRUE(check.ran);
  EXPECT_TRUE(check.passed);
  EXPECT_EQ(check.worst_fraction, 0.0);

  // Too few rows: not run, passes.
  const FitCheck tiny =
      CheckOnHeldOutBlocks(model, MotorHyper(model, log.Y, 0.05), log.X.topRows(6),
                           log.Y.topRows(6));
  EXPECT_FALSE(tiny.ran);
  EXPECT_TRUE(tiny.passed);

  FitCheckOptions bad;
  bad.folds = 1;
  EXPECT_THROW(CheckOnHeldOutBlocks(model, MotorHyper(model, log.Y, 0.05), log.X, log.Y, bad),
               std::invalid_argument);
}

// FitModel on the absurd log: the check fails for every start and every prior, so the best
// search result with the prior as given is kept and the summary warns; with the check off, no
// warning and the same hyper-parameters.
TEST(FitModel, WarnsWhenTheCheckFails) {
  const Log log = SaturatingLog(/*spike_at_end=*/true, 603);
  FitOptions options;
  options.max_prior_tightenings = 1;
  const FittedModel fit = FitModel(ParseModelSpec("motor"), log.X, log.Y, Vector(), options);
  std::cout << FitReport(fit.model, fit.summary);
  ASSERT_TRUE(fit.summary.IsUsable()) << fit.summary.message;
  EXPECT_TRUE(fit.summary.check.ran);
  EXPECT_FALSE(fit.summary.check.passed);
  ASSERT_EQ(fit.summary.warnings.size(), 1u);
  EXPECT_NE(fit.summary.warnings[0].find("held-out check failed"), std::string::npos);
  EXPECT_EQ(fit.summary.prior_tightenings, 1);
  EXPECT_NE(FitReport(fit.model, fit.summary).find("warning"), std::string::npos);
  // The result is the search with the prior as given (three starts); the tightened one,
  // which failed too, was not kept.
  EXPECT_EQ(fit.summary.starts.size(), 3u);

  options.check.enabled = false;
  const FittedModel unchecked = FitModel(ParseModelSpec("motor"), log.X, log.Y, Vector(), options);
  EXPECT_FALSE(unchecked.summary.check.ran);
  EXPECT_TRUE(unchecked.summary.warnings.empty());
  EXPECT_EQ(unchecked.summary.starts.size(), 3u);
  EXPECT_EQ(unchecked.summary.prior_tightenings, 0);
  EXPECT_EQ(unchecked.model.hyperparameters().log_noise_std,
            fit.model.hyperparameters().log_noise_std);
  EXPECT_EQ(unchecked.model.hyperparameters().log_block_scale,
            fit.model.hyperparameters().log_block_scale);
}

// The held-out coverage: per joint, the fraction of held-out torques within 2 predictive
// (noisy) std of the held-out mean, counted here by hand over the same five blocks of 50 rows
// (each predicted by the model fitted on the other four); a noise level far too small makes
// the band too narrow, a far too large one covers everything.
TEST(CheckOnHeldOutBlocks, CoverageCountsTheHeldOutTorquesInsideTheBand) {
  const Log log = SaturatingLog(/*spike_at_end=*/false, 604);
  const RobotModel model(ParseModelSpec("motor"), 1);
  for (const double noise : {1e-4, 0.05, 10.0}) {
    SCOPED_TRACE("noise " + std::to_string(noise));
    const Hyperparameters h = MotorHyper(model, log.Y, noise);
    const FitCheck check = CheckOnHeldOutBlocks(model, h, log.X, log.Y);
    std::cout << check.message << std::endl;
    ASSERT_TRUE(check.ran);
    ASSERT_EQ(check.coverage.size(), 1);
    const double noise_std = noise * std::exp(h.log_output_scale[0]);
    int inside = 0;
    for (int block = 0; block < 5; ++block) {
      Matrix X(200, 3), Y(200, 1);
      X << log.X.topRows(50 * block), log.X.bottomRows(200 - 50 * block);
      Y << log.Y.topRows(50 * block), log.Y.bottomRows(200 - 50 * block);
      RobotModel fold(ParseModelSpec("motor"), 1);
      ASSERT_EQ(fold.Fit(X, Y, h), Status::kOk);
      Matrix mean, std;
      fold.PredictRows(log.X.middleRows(50 * block, 50), &mean, &std);
      for (int i = 0; i < 50; ++i) {
        const double band = 2.0 * std::hypot(std(i, 0), noise_std);
        if (std::abs(log.Y(50 * block + i, 0) - mean(i, 0)) <= band) ++inside;
      }
    }
    EXPECT_DOUBLE_EQ(check.coverage[0], inside / 250.0);
    if (noise == 1e-4) {
      EXPECT_LT(check.coverage[0], 0.5);
    }
    if (noise == 10.0) {
      EXPECT_EQ(check.coverage[0], 1.0);
    }
    EXPECT_NE(check.message.find("2 sigma band covers"), std::string::npos);
  }
  FitCheckOptions bad;
  bad.min_coverage = 1.5;
  EXPECT_FALSE(bad.IsValid(nullptr));
}

// BandCoverage against a count by hand: the band is 2 sqrt(latent^2 + noise^2) per joint, its
// edge inside, a NaN mean outside; sizes are checked.
TEST(BandCoverage, CountsTheTorquesWithinTwoNoisyStdOfTheMean) {
  Matrix mean(4, 2), latent(4, 2), measured(4, 2);
  mean << 0, 10, 0, 10, 0, 10, std::nan(""), 10;
  latent << 3, 0, 3, 0, 0, 0, 3, 0;
  Vector noise(2);
  noise << 4, 0.5;
  // Joint 1: band 2 * 5 = 10 on rows 1, 2 and 4, 2 * 4 = 8 on row 3 (no latent std).
  // Joint 2: band 2 * 0.5 = 1.
  measured << 10, 11, -10.5, 9.5, 9, 10, 0, 12;
  const Vector c = BandCoverage(mean, latent, noise, measured);
  ASSERT_EQ(c.size(), 2);
  EXPECT_EQ(c[0], 1.0 / 4.0);  // row 1 on the edge; row 2 beyond; row 3 beyond 8; row 4 NaN
  EXPECT_EQ(c[1], 3.0 / 4.0);  // rows 1-3 within 1 (row 1 on the edge), row 4 not
  EXPECT_EQ(BandCoverage(Matrix(0, 2), Matrix(0, 2), noise, Matrix(0, 2)), Vector::Zero(2));
  EXPECT_THROW(BandCoverage(mean, latent, Vector::Ones(3), measured), std::invalid_argument);
  EXPECT_THROW(BandCoverage(mean, latent.topRows(3), noise, measured), std::invalid_argument);
  EXPECT_THROW(BandCoverage(mean, latent, noise, measured.leftCols(1)), std::invalid_argument);
}

// FitModel warns of a joint whose held-out coverage is below FitCheckOptions::min_coverage,
// naming it and its coverage; below a bar of 0 nothing is.
TEST(FitModel, WarnsOfBandsTooNarrowOnTheHeldOutBlocks) {
  const Log log = SaturatingLog(/*spike_at_end=*/false, 605);
  FitOptions options;
  options.check.min_coverage = 1.0;  // every joint under 100% is named
  options.calibrate_bands = false;   // with the calibration the finding is a note (below)
  const FittedModel fit = FitModel(ParseModelSpec("motor"), log.X, log.Y, Vector(), options);
  ASSERT_TRUE(fit.summary.IsUsable()) << fit.summary.message;
  ASSERT_TRUE(fit.summary.check.ran);
  ASSERT_EQ(fit.summary.check.coverage.size(), 1);
  const double coverage = fit.summary.check.coverage[0];
  ASSERT_LT(coverage, 1.0);
  ASSERT_EQ(fit.summary.warnings.size(), 1u);
  const std::string expected =
      "the 2 sigma band of joint 1 covered only " + std::to_string(static_cast<int>(
          std::lround(100.0 * coverage))) + "% of the held-out torques";
  EXPECT_NE(fit.summary.warnings[0].find(expected), std::string::npos) << fit.summary.warnings[0];
  EXPECT_NE(ToJson(fit.model, fit.summary).find("\"coverage\""), std::string::npos);

  // Calibrated (the default), the same finding is a note on the bands before calibration.
  options.calibrate_bands = true;
  const FittedModel calibrated =
      FitModel(ParseModelSpec("motor"), log.X, log.Y, Vector(), options);
  EXPECT_TRUE(calibrated.summary.warnings.empty());
  bool noted = false;
  for (const std::string& note : calibrated.summary.notes) {
    noted = noted || note.find("before their calibration, " + expected) !=
                         std::string::npos;
  }
  EXPECT_TRUE(noted);

  options.check.min_coverage = 0.0;
  const FittedModel quiet = FitModel(ParseModelSpec("motor"), log.X, log.Y, Vector(), options);
  EXPECT_TRUE(quiet.summary.warnings.empty());
  EXPECT_EQ(quiet.summary.check.coverage[0], coverage);
}

}  // namespace
}  // namespace structgp
