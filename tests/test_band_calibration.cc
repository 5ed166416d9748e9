// The calibration of the 2 sigma bands on held-out blocks (FitCheck::latent_variance_scale,
// FitOptions::calibrate_bands, RobotModel::latent_variance_scale): the scale is recomputed
// here from folds fitted by hand, the calibrated model is compared with the uncalibrated one
// (same means, latent variance times the scale), and the scale survives the model file and
// reaches the online learner.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdint>
#include <fstream>
#include <iostream>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "alloc_counter.h"
#include "demo_scenario.h"
#include "model_file_checksum.h"
#include "structgp/core/row_subset.h"
#include "structgp/fit/fit_check.h"
#include "structgp/fit/fit_model.h"
#include "structgp/hyper/cross_validation.h"
#include "structgp/io/model_file.h"
#include "structgp/model/model_spec.h"
#include "structgp/model/robot_model.h"
#include "structgp/online/online_learner.h"
#include "structgp/online/replay.h"
#include "structgp/report/report_data.h"
#include "temp_files.h"

namespace structgp {
namespace {

// Two joints, 400 rows in time order. Joint j's torque is c_j qdd_j + d_j qd_j plus a
// quadratic term the linear motor model does not have, and noise of 0.01. The accelerations'
// amplitude changes from block to block (1, 2.5, 1, 3, 1.5), so the model, fitted without a
// block, extrapolates its linear fit to larger accelerations there: its error grows with
// qdd^2 while its latent std grows with |qdd|, and its band is too narrow on the held-out
// blocks of large amplitude.
struct Log {
  Matrix X;  // q1 q2, qd1 qd2, qdd1 qdd2
  Matrix Y;
};

Log MisspecifiedLog(std::uint64_t seed) {
  std::cout << "[ seed     ] " << seed << std::endl;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  const int m = 400;
  const double amplitude[] = {1.0, 2.5, 1.0, 3.0, 1.5};
  Log log;
  log.X.resize(m, 6);
  log.Y.resize(m, 2);
  for (int i = 0; i < m; ++i) {
    const double a = amplitude[i * 5 / m];
    for (int j = 0; j < 2; ++j) {
      const double qd = 0.5 * normal(rng);
      const double qdd = a * normal(rng);
      log.X(i, j) = 0.01 * i;
      log.X(i, 2 + j) = qd;
      log.X(i, 4 + j) = qdd;
      log.Y(i, j) = (1.0 + j) * qdd + 0.5 * qd + 0.05 * (1.0 + j) * qdd * std::abs(qdd) +
                    0.01 * normal(rng);
    }
  }
  return log;
}

Hyperparameters MotorHyper(const RobotModel& model, const Matrix& Y) {
  Hyperparameters h = model.DefaultHyperparameters(Y);
  h.log_noise_std = std::log(0.02);
  return h;
}

using Rows = std::vector<std::vector<std::pair<double, double>>>;  // per joint: (e^2, v)

// The model fitted on the rows `train` of the log, and per joint the squared errors and latent
// variances of its predictions of the rows `test`, appended to *rows.
void FitAndPredict(const RobotModel& model, const Hyperparameters& h, const Log& log,
                   const std::vector<int>& train, const std::vector<int>& test, Rows* rows) {
  Matrix X(static_cast<Eigen::Index>(train.size()), log.X.cols()), Y(X.rows(), 2);
  for (size_t k = 0; k < train.size(); ++k) {
    X.row(static_cast<Eigen::Index>(k)) = log.X.row(train[k]);
    Y.row(static_cast<Eigen::Index>(k)) = log.Y.row(train[k]);
  }
  RobotModel fold(model.spec(), 2);
  EXPECT_EQ(fold.Fit(X, Y, h), Status::kOk);
  for (int i : test) {
    Vector mean(2), latent(2), noisy(2);
    EXPECT_EQ(fold.PredictWithVariance(log.X.row(i).transpose(), mean, latent, noisy),
              Status::kOk);
    for (int j = 0; j < 2; ++j) {
      const double e = log.Y(i, j) - mean[j];
      (*rows)[static_cast<size_t>(j)].emplace_back(e * e, latent[j]);
    }
  }
}

// The held-out predictions of the check's blocks (ContiguousFolds of the rows), every fold
// fitted here.
Rows HeldOut(const RobotModel& model, const Hyperparameters& h, const Log& log, int folds) {
  const int m = static_cast<int>(log.X.rows());
  Rows rows(2);
  for (const auto& [begin, end] : ContiguousFolds(m, folds)) {
    std::vector<int> train, test;
    for (int i = 0; i < m; ++i) (i >= begin && i < end ? test : train).push_back(i);
    FitAndPredict(model, h, log, train, test, &rows);
  }
  return rows;
}

// The same for the fastest 1/folds of the rows (by |qd|), predicted by the model fitted on
// the slower ones.
Rows Fastest(const RobotModel& model, const Hyperparameters& h, const Log& log, int folds) {
  const int m = static_cast<int>(log.X.rows());
  std::vector<std::pair<double, int>> speed;
  for (int i = 0; i < m; ++i) speed.emplace_back(log.X.row(i).segment(2, 2).squaredNorm(), i);
  std::stable_sort(speed.begin(), speed.end(),
                   [](const auto& a, const auto& b) { return a.first < b.first; });
  const int held = (m + folds - 1) / folds;
  std::vector<int> train, test;
  for (int k = 0; k < m; ++k) (k < m - held ? train : test).push_back(speed[k].second);
  std::sort(train.begin(), train.end());
  std::sort(test.begin(), test.end());
  Rows rows(2);
  FitAndPredict(model, h, log, train, test, &rows);
  return rows;
}

double Coverage(const std::vector<std::pair<double, double>>& rows, double kappa,
                double noise_var) {
  int inside = 0;
  for (const auto& [e, v] : rows) {
    if (std::sqrt(e) <= 2.0 * std::sqrt(kappa * v + noise_var)) ++inside;
  }
  return static_cast<double>(inside) / static_cast<double>(rows.size());
}

TEST(LatentVarianceScale, IsTheSmallestScaleWithWhichTheHeldOutBandCoversTheTarget) {
  const Log log = MisspecifiedLog(11);
  const RobotModel model(ParseModelSpec("motor"), 2);
  const Hyperparameters h = MotorHyper(model, log.Y);
  FitCheckOptions options;
  options.folds = 5;
  const FitCheck check = CheckOnHeldOutBlocks(model, h, log.X, log.Y, options);
  std::cout << check.message << "; scale " << check.latent_variance_scale.transpose()
            << std::endl;
  ASSERT_TRUE(check.ran);
  ASSERT_EQ(check.latent_variance_scale.size(), 2);

  const auto blocks = HeldOut(model, h, log, options.folds);
  const auto fastest = Fastest(model, h, log, options.folds);
  const Vector noise_std = h.noise_stds();
  ASSERT_EQ(check.fastest_coverage.size(), 2);
  for (int j = 0; j < 2; ++j) {
    SCOPED_TRACE("joint " + std::to_string(j + 1));
    const double kappa = check.latent_variance_scale[j];
    const double noise_var = noise_std[j] * noise_std[j];
    const auto& b = blocks[static_cast<size_t>(j)];
    const auto& f = fastest[static_cast<size_t>(j)];
    // The bands are too narrow as the posterior gives them, so the scale is above 1 ...
    EXPECT_LT(Coverage(b, 1.0, noise_var), options.target_coverage);
    EXPECT_NEAR(Coverage(b, 1.0, noise_var), check.coverage[j], 1e-12);
    EXPECT_NEAR(Coverage(f, 1.0, noise_var), check.fastest_coverage[j], 1e-12);
    EXPECT_GT(kappa, 1.0);
    EXPECT_LT(kappa, kMaxLatentVarianceScale);
    // ... with it both the blocks and the fastest rows are covered to the target, and with a
    // slightly smaller one at least one of them is not.
    EXPECT_GE(Coverage(b, kappa * (1.0 + 1e-9), noise_var), options.target_coverage);
    EXPECT_GE(Coverage(f, kappa * (1.0 + 1e-9), noise_var), options.target_coverage);
    const double less = kappa * (1.0 - 1e-6);
    EXPECT_TRUE(Coverage(b, less, noise_var) < options.target_coverage ||
                Coverage(f, less, noise_var) < options.target_coverage);
  }
  // Without the fastest rows' fold: the blocks' own smallest factor.
  options.fastest_rows_fold = false;
  const FitCheck blocks_only = CheckOnHeldOutBlocks(model, h, log.X, log.Y, options);
  EXPECT_EQ(blocks_only.fastest_coverage.size(), 0);
  for (int j = 0; j < 2; ++j) {
    const double kappa = blocks_only.latent_variance_scale[j];
    const double noise_var = noise_std[j] * noise_std[j];
    EXPECT_LE(kappa, check.latent_variance_scale[j]);
    EXPECT_GE(Coverage(blocks[static_cast<size_t>(j)], kappa * (1.0 + 1e-9), noise_var),
              options.target_coverage);
    EXPECT_LT(Coverage(blocks[static_cast<size_t>(j)], kappa * (1.0 - 1e-6), noise_var),
              options.target_coverage);
  }
}

TEST(LatentVarianceScale, IsOneWhereTheBandAlreadyCoversTheTarget) {
  const Log log = MisspecifiedLog(12);
  const RobotModel model(ParseModelSpec("motor"), 2);
  FitCheckOptions options;
  options.target_coverage = 0.3;  // every joint's band covers more than that
  const FitCheck check = CheckOnHeldOutBlocks(model, MotorHyper(model, log.Y), log.X, log.Y,
                                              options);
  ASSERT_TRUE(check.ran);
  for (int j = 0; j < 2; ++j) {
    ASSERT_GT(check.coverage[j], 0.3);
    EXPECT_EQ(check.latent_variance_scale[j], 1.0);
  }
  // Only the joint the check counts gets a scale.
  const FitCheck one = CheckOnHeldOutBlocks(model, MotorHyper(model, log.Y), log.X, log.Y,
                                            FitCheckOptions(), /*only_joint=*/2);
  EXPECT_TRUE(std::isnan(one.latent_variance_scale[0]));
  EXPECT_GT(one.latent_variance_scale[1], 1.0);

  FitCheckOptions bad;
  bad.target_coverage = 1.0;
  EXPECT_THROW(CheckOnHeldOutBlocks(model, MotorHyper(model, log.Y), log.X, log.Y, bad),
               std::invalid_argument);
}

// The demo's slow two-link log (a Coulomb friction on joint 2 that pol does not model),
// fitted by FitModel with its defaults (type-II MAP, the held-out check), calibrated or not:
// joint 2's held-out band is too narrow.
const sim::Dataset& Slow() { return testing::DemoScenario().train; }

FittedModel FitPol(bool calibrate) {
  FitOptions options;
  options.calibrate_bands = calibrate;
  options.check.min_coverage = 0.95;  // a finding for every band short of the target
  return FitModel(ParseModelSpec("pol"), Slow().X, Slow().Y, Vector(), options);
}

TEST(CalibrateBands, ScalesTheLatentVarianceAndNothingElse) {
  const FittedModel plain = FitPol(false);
  const FittedModel calibrated = FitPol(true);
  ASSERT_TRUE(plain.summary.IsUsable() && calibrated.summary.IsUsable());
  const Vector kappa = calibrated.model.latent_variance_scale();
  std::cout << "scale " << kappa.transpose() << std::endl;
  EXPECT_TRUE(plain.model.latent_variance_scale().isOnes(0.0));
  ASSERT_TRUE(calibrated.summary.check.ran);
  for (int j = 0; j < 2; ++j) {
    EXPECT_EQ(kappa[j], std::max(1.0, calibrated.summary.check.latent_variance_scale[j]));
  }
  ASSERT_GT(kappa.maxCoeff(), 1.0);
  auto says = [](const std::vector<std::string>& lines, const std::string& text) {
    for (const std::string& line : lines) {
      if (line.find(text) != std::string::npos) return true;
    }
    return false;
  };
  // Calibrated, the narrow band is a note on the bands before their calibration; not
  // calibrated, a warning.
  EXPECT_TRUE(says(calibrated.summary.notes, "2 sigma bands calibrated"));
  EXPECT_TRUE(says(calibrated.summary.notes, "before their calibration"));
  EXPECT_FALSE(says(calibrated.summary.warnings, "claims more certainty"));
  EXPECT_TRUE(says(plain.summary.warnings, "claims more certainty"));
  // The fastest rows' band is named when it is short of the bar too.
  const Vector& fastest = plain.summary.check.fastest_coverage;
  ASSERT_EQ(fastest.size(), 2);
  std::cout << "fastest rows' coverage " << fastest.transpose() << std::endl;
  EXPECT_EQ(says(plain.summary.warnings, "of the fastest rows' torques"),
            fastest.minCoeff() < 0.95);
  EXPECT_FALSE(says(plain.summary.notes, "2 sigma bands calibrated"));
  // The same search either way.
  EXPECT_EQ(calibrated.model.hyperparameters().shape, plain.model.hyperparameters().shape);
  EXPECT_EQ(calibrated.model.hyperparameters().log_noise_std,
            plain.model.hyperparameters().log_noise_std);

  // Near the data and far from it (accelerations up to 10 times the largest), where the
  // latent part dominates.
  const Vector noise_std = calibrated.model.hyperparameters().noise_stds();
  const double largest = Slow().X.rightCols(2).cwiseAbs().maxCoeff();
  for (double qdd : {0.1 * largest, largest, 10.0 * largest}) {
    Vector x(6);
    x << 0.1, 0.2, 0.3, -0.2, qdd, -qdd;
    Vector m0(2), l0(2), n0(2), m1(2), l1(2), n1(2);
    ASSERT_EQ(plain.model.PredictWithVariance(x, m0, l0, n0), Status::kOk);
    ASSERT_EQ(calibrated.model.PredictWithVariance(x, m1, l1, n1), Status::kOk);
    for (int j = 0; j < 2; ++j) {
      EXPECT_EQ(m1[j], m0[j]);
      EXPECT_NEAR(l1[j], kappa[j] * l0[j], 1e-12 * kappa[j] * l0[j]);
      EXPECT_NEAR(n1[j], kappa[j] * l0[j] + noise_std[j] * noise_std[j], 1e-12 * n1[j]);
    }
  }
  // PredictRows gives the same latent standard deviations.
  Matrix mean, latent_std;
  calibrated.model.PredictRows(Slow().X.topRows(3), &mean, &latent_std);
  for (int i = 0; i < 3; ++i) {
    Vector m(2), l(2), n(2);
    ASSERT_EQ(calibrated.model.PredictWithVariance(Slow().X.row(i).transpose(), m, l, n),
              Status::kOk);
    EXPECT_EQ(latent_std.row(i).transpose(), l.cwiseSqrt());
  }
  // A report says so (report::CalibratedBandsNote, in diagnose's and compare's reports).
  char factor[32];
  std::snprintf(factor, sizeof factor, "%.3g", kappa[1]);
  const std::string note = report::CalibratedBandsNote(calibrated.model);
  EXPECT_NE(note.find(std::string("joint") + (kappa[0] > 1.0 ? "s 1 and 2" : " 2") + " scaled by"),
            std::string::npos)
      << note;
  EXPECT_NE(note.find(factor), std::string::npos) << note;
  EXPECT_TRUE(report::CalibratedBandsNote(plain.model).empty());
  // On the fast log (2.5 times the speed, unseen) the calibrated band covers more of the
  // torques where it was widened.
  const sim::Dataset& fast = testing::DemoScenario().test;
  Matrix m0, s0, m1, s1;
  plain.model.PredictRows(fast.X, &m0, &s0);
  calibrated.model.PredictRows(fast.X, &m1, &s1);
  const Vector before = BandCoverage(m0, s0, noise_std, fast.Y);
  const Vector after = BandCoverage(m1, s1, noise_std, fast.Y);
  std::cout << "coverage on the fast log: " << before.transpose() << " -> "
            << after.transpose() << std::endl;
  for (int j = 0; j < 2; ++j) {
    if (kappa[j] > 1.0) {
      EXPECT_GT(after[j], before[j]);
    } else {
      EXPECT_EQ(after[j], before[j]);
    }
  }
}

TEST(CalibrateBands, TheModelsScaleIsValidatedAndResetByAFit) {
  FittedModel fitted = FitPol(true);
  RobotModel& model = fitted.model;
  ASSERT_GT(model.latent_variance_scale().maxCoeff(), 1.0);
  EXPECT_THROW(model.SetLatentVarianceScale(Vector::Ones(3)), std::invalid_argument);
  EXPECT_THROW(model.SetLatentVarianceScale(Vector::Zero(2)), std::invalid_argument);
  Vector nan = Vector::Ones(2);
  nan[1] = std::nan("");
  EXPECT_THROW(model.SetLatentVarianceScale(nan), std::invalid_argument);

  // The prediction with a scale allocates nothing (the real-time path).
  RobotModel::Workspace workspace = model.MakeWorkspace();
  Vector x = Slow().X.row(7).transpose(), mean(2), latent(2), noisy(2);
  {
    testing::AllocationCounter guard;
    for (int i = 0; i < 100; ++i) {
      x[4] = 0.01 * i;
      ASSERT_EQ(model.PredictWithVariance(x, mean, latent, noisy, workspace), Status::kOk);
    }
    if (testing::CountsEveryAllocation()) {
      EXPECT_EQ(guard.count(), 0u);
    }
  }
  // A fit with new hyper-parameters is a new model: its bands are the posterior's own.
  ASSERT_EQ(model.Fit(Slow().X, Slow().Y, model.hyperparameters()), Status::kOk);
  EXPECT_TRUE(model.latent_variance_scale().isOnes(0.0));
}

TEST(CalibrateBands, TheModelFileKeepsTheScale) {
  const FittedModel calibrated = FitPol(true);
  const FittedModel plain = FitPol(false);
  ASSERT_GT(calibrated.model.latent_variance_scale().maxCoeff(), 1.0);
  testing::TempDir dir("band_calibration");
  const std::string path = dir.File("calibrated.json");
  const std::string plain_path = dir.File("plain.json");
  SaveModel(path, calibrated.model);
  SaveModel(plain_path, plain.model);
  const RobotModel loaded = LoadModel(path);
  EXPECT_EQ(loaded.latent_variance_scale(), calibrated.model.latent_variance_scale());
  Vector x = Slow().X.row(3).transpose();
  x[4] *= 5.0;
  Vector m0(2), l0(2), n0(2), m1(2), l1(2), n1(2);
  ASSERT_EQ(calibrated.model.PredictWithVariance(x, m0, l0, n0), Status::kOk);
  ASSERT_EQ(loaded.PredictWithVariance(x, m1, l1, n1), Status::kOk);
  EXPECT_EQ(m0, m1);
  EXPECT_EQ(l0, l1);
  EXPECT_EQ(n0, n1);

  auto read = [](const std::string& file) {
    std::ifstream in(file);
    return nlohmann::json::parse(in);
  };
  nlohmann::json doc = read(path);
  EXPECT_EQ(doc["version"].get<int>(), kModelFileVersion);
  ASSERT_TRUE(doc.contains("latent_variance_scale"));
  // Uncalibrated files stay as builds that read version 2 know them.
  const nlohmann::json plain_doc = read(plain_path);
  EXPECT_EQ(plain_doc["version"].get<int>(), kSharedModelFileVersion);
  EXPECT_FALSE(plain_doc.contains("latent_variance_scale"));
  EXPECT_TRUE(LoadModel(plain_path).latent_variance_scale().isOnes(0.0));

  // A bad scale is refused, naming the field.
  for (const nlohmann::json& bad : {nlohmann::json::array({1.0, -2.0}),
                                    nlohmann::json::array({1.0}),
                                    nlohmann::json::array({1.0, 0.0})}) {
    doc["latent_variance_scale"] = bad;
    testing::SetValidChecksum(&doc);
    const std::string bad_path = dir.File("bad.json");
    std::ofstream(bad_path) << doc.dump();
    try {
      LoadModel(bad_path);
      ADD_FAILURE() << "accepted " << bad.dump();
    } catch (const DataError& e) {
      EXPECT_NE(std::string(e.what()).find("latent_variance_scale"), std::string::npos)
          << e.what();
    }
  }
}

TEST(CalibrateBands, TheOnlineLearnerScalesItsLatentVarianceAndReplayKeepsIt) {
  const FittedModel calibrated = FitPol(true);
  const Vector kappa = calibrated.model.latent_variance_scale();
  ASSERT_GT(kappa.maxCoeff(), 1.0);
  OnlineLearnerOptions options = OnlineLearnerOptionsFor(calibrated.model);
  EXPECT_EQ(options.latent_variance_scale, kappa);
  options.start_thread = false;
  options.covariance_publish_period = 1;
  OnlineLearnerOptions unscaled = options;
  unscaled.latent_variance_scale = Vector();
  OnlineLearner scaled_learner(options);
  OnlineLearner plain_learner(unscaled);
  for (int i = 0; i < 50; ++i) {
    const Vector x = Slow().X.row(i).transpose(), y = Slow().Y.row(i).transpose();
    ASSERT_EQ(scaled_learner.Submit(x, y), SubmitResult::kAccepted);
    ASSERT_EQ(plain_learner.Submit(x, y), SubmitResult::kAccepted);
  }
  scaled_learner.ProcessPending();
  plain_learner.ProcessPending();
  Vector x = Slow().X.row(60).transpose(), m0(2), v0(2), m1(2), v1(2);
  ASSERT_EQ(plain_learner.PredictWithVariance(x, m0, v0), Status::kOk);
  ASSERT_EQ(scaled_learner.PredictWithVariance(x, m1, v1), Status::kOk);
  EXPECT_EQ(m0, m1);
  for (int j = 0; j < 2; ++j) EXPECT_DOUBLE_EQ(v1[j], kappa[j] * v0[j]);

  // A replay from the calibrated model keeps its calibration in the model it learns.
  const ReplaySummary replayed =
      Replay(calibrated.model, Slow().X.topRows(200), Slow().Y.topRows(200), Slow().t.head(200),
             ReplayOptions());
  ASSERT_NE(replayed.model, nullptr);
  EXPECT_EQ(replayed.model->latent_variance_scale(), kappa);
  const ReplaySummary plain_replay =
      Replay(FitPol(false).model, Slow().X.topRows(200), Slow().Y.topRows(200),
             Slow().t.head(200), ReplayOptions());
  EXPECT_TRUE(plain_replay.model->latent_variance_scale().isOnes(0.0));

  OnlineLearnerOptions bad = unscaled;
  bad.latent_variance_scale = Vector::Ones(3);
  std::string error;
  EXPECT_FALSE(bad.IsValid(&error));
  EXPECT_NE(error.find("latent_variance_scale"), std::string::npos) << error;
}

}  // namespace
}  // namespace structgp
