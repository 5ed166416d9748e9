// The library's fitting workflow (fit/fit_model.h) against the same steps assembled by hand
// from the lower layers (statistics, evidence, LBFGS, cross-validation, RobotModel::Fit): the
// predictions must be bit-identical. Also the callback (progress, abort), the options'
// validation and the errors for caller mistakes.

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "demo_scenario.h"

#include "structgp/core/row_subset.h"
#include "structgp/fit/fit_check.h"
#include "structgp/fit/fit_model.h"
#include "structgp/hyper/cross_validation.h"
#include "structgp/hyper/evidence.h"
#include "structgp/hyper/marginal_likelihood.h"
#include "structgp/model/sufficient_statistics.h"
#include "structgp/sim/hidden_effect.h"

namespace structgp {
namespace {

using testing::Spec;

const sim::HiddenEffectScenario& Scenario() { return testing::DemoScenario(); }

// FitModel's last step by hand: the bands calibrated on the held-out check of h
// (FitOptions::calibrate_bands, on by default).
void Calibrate(const Hyperparameters& h, const Matrix& X, const Matrix& Y, RobotModel* model) {
  const FitCheck check = CheckOnHeldOutBlocks(*model, h, X, Y, FitCheckOptions());
  ASSERT_TRUE(check.ran);
  model->SetLatentVarianceScale(check.latent_variance_scale.cwiseMax(1.0));
}

Matrix Predictions(const RobotModel& model, const Matrix& X) {
  Matrix mean, std;
  model.PredictRows(X, &mean, &std);
  Matrix both(mean.rows(), 2 * mean.cols());
  both << mean, std;
  return both;
}

// The weight-space workflow by hand: Phi^T Phi, profile noise and scales, LBFGS, fit.
TEST(FitModel, EvidenceEqualsTheStepsByHand) {
  const sim::Dataset& d = Scenario().train;
  const ModelSpec spec = Spec("pol+fri");
  const FittedModel fit = FitModel(spec, d.X, d.Y, Vector());
  ASSERT_TRUE(fit.summary.IsUsable()) << fit.summary.message;
  EXPECT_EQ(fit.summary.method, HyperparameterMethod::kEvidence);
  EXPECT_GT(fit.summary.iterations, 0);
  EXPECT_EQ(fit.summary.rows, d.X.rows());
  EXPECT_EQ(fit.summary.model_rows, d.X.rows());
  EXPECT_LE(fit.summary.final_negative_log_evidence, fit.summary.initial_negative_log_evidence);

  RobotModel reference(spec, 2);
  const SufficientStatistics stats = AccumulateStatistics(*reference.feature_map(), d.X, d.Y);
  const WeightSpaceEvidence evidence(reference.feature_map(), stats);
  Hyperparameters h = ProfileNoiseAndScales(evidence, reference.DefaultHyperparameters(d.Y));
  const MaximumLikelihoodSummary s = FitHyperparameters(evidence, MaximumLikelihoodOptions(), &h);
  ASSERT_TRUE(s.usable());
  ASSERT_EQ(reference.Fit(d.X, d.Y, h), Status::kOk);
  EXPECT_EQ(fit.summary.iterations, s.iterations);
  EXPECT_EQ(fit.summary.final_negative_log_evidence, s.final_negative_log_likelihood);
  EXPECT_EQ(Predictions(fit.model, d.X), Predictions(reference, d.X));
}

// Unit output scales: no profile, the scales stay 1, LBFGS from the defaults.
TEST(FitModel, UnitOutputScalesEqualTheStepsByHand) {
  const sim::Dataset& d = Scenario().train;
  const ModelSpec spec = Spec("pol");
  FitOptions options;
  options.output_scaling = OutputScaling::kUnit;
  // pol without the friction the data hold fails the held-out check here (its Coriolis block
  // absorbs the Coulomb step and swings off the path), which would refit with a tighter prior;
  // this test compares the search itself with the steps by hand.
  options.check.enabled = false;
  const FittedModel fit = FitModel(spec, d.X, d.Y, Vector(), options);
  ASSERT_TRUE(fit.summary.IsUsable()) << fit.summary.message;
  EXPECT_EQ(fit.model.hyperparameters().log_output_scale, Vector::Zero(2));

  RobotModel reference(spec, 2);
  const SufficientStatistics stats = AccumulateStatistics(*reference.feature_map(), d.X, d.Y);
  const WeightSpaceEvidence evidence(reference.feature_map(), stats);
  Hyperparameters h = reference.DefaultHyperparameters(d.Y);
  h.log_output_scale.setZero();
  ASSERT_TRUE(FitHyperparameters(evidence, MaximumLikelihoodOptions(), &h).usable());
  ASSERT_EQ(reference.Fit(d.X, d.Y, h), Status::kOk);
  EXPECT_EQ(Predictions(fit.model, d.X), Predictions(reference, d.X));
}

TEST(FitModel, CrossValidationEqualsTheStepsByHand) {
  const sim::Dataset& d = Scenario().train;
  const ModelSpec spec = Spec("pol");
  FitOptions options;
  options.method = HyperparameterMethod::kCrossValidation;
  options.cv_folds = 4;
  options.cv_shape_offsets = {-1.0, 0.0, 1.0};
  options.cv_noise_levels = {0.1, 0.01};
  const FittedModel fit = FitModel(spec, d.X, d.Y, Vector(), options);
  ASSERT_TRUE(fit.summary.IsUsable()) << fit.summary.message;
  EXPECT_EQ(fit.summary.cv_candidates, 6);

  RobotModel reference(spec, 2);
  const FeatureMap& map = *reference.feature_map();
  const Hyperparameters base = reference.DefaultHyperparameters(d.Y);
  const FoldStatistics folds(map, d.X, d.Y, 4);
  const auto candidates = HyperparameterGrid(
      base, {base.shape[0] - 1.0, base.shape[0], base.shape[0] + 1.0},
      {std::log(0.1), std::log(0.01)}, 0);
  std::vector<CrossValidationResult> results;
  int best = -1;
  const Hyperparameters h = SelectByCrossValidation(map, folds, candidates, &results, &best);
  ASSERT_GE(best, 0);
  ASSERT_EQ(reference.Fit(d.X, d.Y, h), Status::kOk);
  Calibrate(h, d.X, d.Y, &reference);
  EXPECT_EQ(fit.summary.cv_mean_nmse, results[static_cast<size_t>(best)].mean_nmse);
  EXPECT_EQ(Predictions(fit.model, d.X), Predictions(reference, d.X));
}

TEST(FitModel, FixedIsTheModelsDefaults) {
  const sim::Dataset& d = Scenario().train;
  FitOptions options;
  options.method = HyperparameterMethod::kFixed;
  const FittedModel fit = FitModel(Spec("motor+fri"), d.X, d.Y, Vector(), options);
  ASSERT_EQ(fit.summary.termination, FitTermination::kConverged);
  RobotModel reference(Spec("motor+fri"), 2);
  ASSERT_EQ(reference.Fit(d.X, d.Y), Status::kOk);
  Calibrate(reference.DefaultHyperparameters(d.Y), d.X, d.Y, &reference);
  EXPECT_EQ(Predictions(fit.model, d.X), Predictions(reference, d.X));
}

// Kernel models: the kernel's hyper-parameters by evidence on the evenly spaced subset, then
// the model on every row.
TEST(FitModel, KernelEvidenceOnTheEvenlySpacedSubset) {
  // The first 400 rows: the function-space fit costs O(m^3).
  sim::Dataset d = Scenario().train;
  d.X = d.X.topRows(400).eval();
  d.Y = d.Y.topRows(400).eval();
  const ModelSpec spec = Spec("rbf");
  FitOptions options;
  options.max_evidence_rows = 120;
  options.evidence.max_iterations = 15;
  const FittedModel fit = FitModel(spec, d.X, d.Y, Vector(), options);
  ASSERT_TRUE(fit.summary.IsUsable()) << fit.summary.message;
  EXPECT_EQ(fit.summary.hyperparameter_rows, 120);

  RobotModel reference(spec, 2);
  // The kernel's default parameters in h.shape; the fit replaces them.
  Hyperparameters h = reference.DefaultHyperparameters(d.Y);
  const std::vector<int> rows = EvenlySpacedRows(d.X.rows(), 120);
  ASSERT_EQ(rows[3], 10);  // floor(k m / M) = floor(3 * 400 / 120)
  const MaximumLikelihoodSummary s =
      FitKernelHyperparameters(*reference.kernel(), SelectRows(d.X, rows), SelectRows(d.Y, rows),
                               options.evidence, &h);
  ASSERT_TRUE(s.usable());
  ASSERT_EQ(reference.Fit(d.X, d.Y, h), Status::kOk);
  Calibrate(h, d.X, d.Y, &reference);
  EXPECT_EQ(Predictions(fit.model, d.X), Predictions(reference, d.X));
}

TEST(FitModel, CallbackSeesProgressAndIterations) {
  const sim::Dataset& d = Scenario().train;
  FitOptions options;
  std::vector<std::string> messages;
  int iterations = 0;
  options.callback = [&](const FitProgress& p) {
    if (p.message.empty()) {
      ++iterations;
      EXPECT_TRUE(std::isfinite(p.negative_log_evidence));
    } else {
      messages.push_back(p.message);
    }
    return FitCallbackReturn::kContinue;
  };
  const FittedModel fit = FitModel(Spec("pol"), d.X, d.Y, Vector(), options);
  ASSERT_TRUE(fit.summary.IsUsable());
  EXPECT_GE(iterations, fit.summary.iterations);
  ASSERT_GE(messages.size(), 4u);
  EXPECT_NE(messages.front().find("accumulating Phi^T Phi"), std::string::npos);
  // The last lines: the fit to every row, then (FitOptions::calibrate_bands) the bands.
  const auto fitting = std::find_if(messages.begin(), messages.end(), [](const std::string& m) {
    return m.find("fitting the model to") != std::string::npos;
  });
  ASSERT_NE(fitting, messages.end());
  EXPECT_LE(messages.end() - fitting, 2);
}

TEST(FitModel, CallbackAbortLeavesTheModelUnfitted) {
  const sim::Dataset& d = Scenario().train;
  for (int stop_after : {0, 2}) {
    FitOptions options;
    int calls = 0;
    options.callback = [&](const FitProgress& p) {
      if (!p.message.empty()) return FitCallbackReturn::kContinue;
      return ++calls > stop_after ? FitCallbackReturn::kAbort : FitCallbackReturn::kContinue;
    };
    const FittedModel fit = FitModel(Spec("pol"), d.X, d.Y, Vector(), options);
    EXPECT_EQ(fit.summary.termination, FitTermination::kUserAbort) << stop_after;
    EXPECT_FALSE(fit.summary.IsUsable());
    EXPECT_FALSE(fit.model.fitted());
  }
  // A stop asked by the evidence options' own iteration callback is a user abort too.
  {
    FitOptions options;
    options.evidence.iteration_callback = [](int, double) { return false; };
    const FittedModel fit = FitModel(Spec("pol"), d.X, d.Y, Vector(), options);
    EXPECT_EQ(fit.summary.termination, FitTermination::kUserAbort);
    EXPECT_FALSE(fit.model.fitted());
  }
  // Abort at the first progress line: nothing is computed.
  FitOptions options;
  options.callback = [](const FitProgress&) { return FitCallbackReturn::kAbort; };
  RobotModel model(Spec("pol"), 2);
  const FitSummary summary = FitModel(options, d.X, d.Y, Vector(), &model);
  EXPECT_EQ(summary.termination, FitTermination::kUserAbort);
  EXPECT_FALSE(model.fitted());
}

TEST(FitOptions, IsValidNamesTheBadOption) {
  std::string error;
  EXPECT_TRUE(FitOptions().IsValid(&error));
  struct Case {
    const char* name;
    void (*change)(FitOptions*);
  };
  const Case cases[] = {
      {"cv_folds", [](FitOptions* o) { o->cv_folds = 1; }},
      {"max_evidence_rows", [](FitOptions* o) { o->max_evidence_rows = -1; }},
      {"cv_noise_levels", [](FitOptions* o) { o->cv_noise_levels = {0.1, -0.1}; }},
      {"cv_shape_offsets", [](FitOptions* o) { o->cv_shape_offsets = {NAN}; }},
      {"num_threads", [](FitOptions* o) { o->num_threads = 0; }},
      {"evidence", [](FitOptions* o) { o->evidence.max_iterations = -1; }},
  };
  for (const Case& c : cases) {
    FitOptions o;
    c.change(&o);
    error.clear();
    EXPECT_FALSE(o.IsValid(&error)) << c.name;
    EXPECT_NE(error.find(c.name), std::string::npos) << error;
    const sim::Dataset& d = Scenario().train;
    EXPECT_THROW(FitModel(Spec("motor"), d.X, d.Y, Vector(), o), std::invalid_argument);
  }
}

TEST(FitModel, CallerMistakesThrowWithWhatIsWrong) {
  const sim::Dataset& d = Scenario().train;
  auto message = [](auto&& f) {
    try {
      f();
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no exception");
  };
  // Torques of the wrong width.
  EXPECT_NE(message([&] { FitModel(Spec("pol"), d.X, d.Y.leftCols(1), Vector()); })
                .find("columns"),
            std::string::npos);
  // NaN in the states.
  Matrix X = d.X;
  X(3, 1) = NAN;
  EXPECT_NE(message([&] { FitModel(Spec("pol"), X, d.Y, Vector()); }).find("states"),
            std::string::npos);
  // A time effect without times.
  EXPECT_NE(message([&] { FitModel(Spec("pol", "drift@1"), d.X, d.Y, Vector()); })
                .find("no times were given"),
            std::string::npos);
  // Cross-validation on a kernel model.
  FitOptions cv;
  cv.method = HyperparameterMethod::kCrossValidation;
  EXPECT_NE(message([&] { FitModel(Spec("rbf"), d.X, d.Y, Vector(), cv); })
                .find("explicit feature map"),
            std::string::npos);
  // More folds than rows.
  cv.cv_folds = 50;
  EXPECT_NE(message([&] {
              FitModel(Spec("motor"), d.X.topRows(20), d.Y.topRows(20), Vector(), cv);
            }).find("folds"),
            std::string::npos);
}

TEST(FitModel, TimeEffectsUseTheTimes) {
  const sim::Dataset& d = Scenario().train;
  FitOptions options;
  options.method = HyperparameterMethod::kFixed;
  const FittedModel fit = FitModel(Spec("pol", "drift@2"), d.X, d.Y, d.t, options);
  ASSERT_TRUE(fit.summary.IsUsable());
  RobotModel reference(Spec("pol", "drift@2"), 2);
  Matrix X(d.X.rows(), d.X.cols() + 1);
  X << d.X, d.t;
  ASSERT_EQ(reference.Fit(X, d.Y), Status::kOk);
  EXPECT_EQ(Predictions(fit.model, X), Predictions(reference, X));
  EXPECT_EQ(ModelInputs(fit.model, d.X, d.t), X);
}

TEST(FitReport, ListsHyperparametersEvidenceAndCoefficients) {
  const sim::Dataset& d = Scenario().train;
  const FittedModel fit = FitModel(Spec("pol", "coulomb@2"), d.X, d.Y, Vector());
  const std::string report = FitReport(fit.model, fit.summary);
  for (const char* part : {"features     D = ", "type-II maximum likelihood", "log_noise_std",
                           "log marginal likelihood", "coulomb@2"}) {
    EXPECT_NE(report.find(part), std::string::npos) << part << "\n" << report;
  }
  EXPECT_NE(fit.summary.BriefReport().find("converged"), std::string::npos);
}

// The summary's warnings that contain `text`.
int WarningsWith(const FitSummary& summary, const std::string& text) {
  int count = 0;
  for (const auto& w : summary.warnings) count += w.find(text) != std::string::npos ? 1 : 0;
  return count;
}

// A log that never moves a joint (static poses, or rows that all fall on via points) shows
// none of the torques of its motion: the fit says which joints, for every model form.
TEST(FitModel, WarnsOfJointsTheLogNeverMovesOrAccelerates) {
  const sim::Dataset& d = Scenario().train;
  FitOptions options;
  options.method = HyperparameterMethod::kFixed;
  const auto fit = [&options](const Matrix& X, const Matrix& Y) {
    const FittedModel f = FitModel(Spec("motor+fri"), X, Y, Vector(), options);
    EXPECT_TRUE(f.summary.IsUsable()) << f.summary.message;
    return f.summary;
  };
  const FitSummary moving = fit(d.X, d.Y);
  EXPECT_EQ(WarningsWith(moving, "never"), 0);

  Matrix still2 = d.X;  // joint 2: qd and qdd zero
  still2.col(3).setZero();
  still2.col(5).setZero();
  const FitSummary s2 = fit(still2, d.Y);
  EXPECT_EQ(
      WarningsWith(s2, "joint 2 never moves in the 4000 rows (velocity zero on every row)"), 1)
      << ::testing::PrintToString(s2.warnings);
  EXPECT_EQ(WarningsWith(s2, "joint 1"), 0);
  EXPECT_EQ(WarningsWith(s2, "accelerate"), 0);  // never moving says it

  Matrix unaccelerated1 = d.X;  // joint 1: qdd at rounding level, qd as it was
  unaccelerated1.col(4).setConstant(1e-15);
  const FitSummary s1 = fit(unaccelerated1, d.Y);
  EXPECT_EQ(WarningsWith(s1, "joint 1 never accelerates in the 4000 rows (acceleration RMS at "
                             "most 1e-15 rad/s^2)"),
            1)
      << ::testing::PrintToString(s1.warnings);
  EXPECT_EQ(WarningsWith(s1, "never moves"), 0);

  Matrix still = d.X;  // static poses
  still.rightCols(4).setZero();
  const FitSummary s12 = fit(still, d.Y);
  EXPECT_EQ(WarningsWith(s12, "joints 1 and 2 never move"), 1)
      << ::testing::PrintToString(s12.warnings);
  EXPECT_EQ(WarningsWith(s12, "never"), 1);  // one line for both joints
}

// The text report of a regressor model (rbd, lag) prints the search's warnings and held-out
// check as every other model's does.
TEST(FitReport, PrintsTheWarningsOfRegressorModels) {
  const sim::Dataset& d = Scenario().train;
  Matrix X = d.X;
  X.col(3).setZero();
  X.col(5).setZero();
  const FittedModel fit = FitModel(Spec("lag+fri"), X, d.Y, Vector());
  ASSERT_TRUE(fit.summary.IsUsable()) << fit.summary.message;
  ASSERT_NE(fit.model.regressor_map(), nullptr);
  ASSERT_EQ(WarningsWith(fit.summary, "joint 2 never moves"), 1);
  const std::string report = FitReport(fit.model, fit.summary);
  EXPECT_NE(report.find("warning      joint 2 never moves"), std::string::npos) << report;
  ASSERT_TRUE(fit.summary.check.ran);
  EXPECT_NE(report.find("check        " + fit.summary.check.message), std::string::npos)
      << report;
}

TEST(RowSubset, FloorOfKmOverM) {
  EXPECT_EQ(EvenlySpacedRows(10, 4), (std::vector<int>{0, 2, 5, 7}));
  EXPECT_EQ(EvenlySpacedRows(3, 5), (std::vector<int>{0, 1, 2}));
  EXPECT_EQ(EvenlySpacedRows(4, 0), (std::vector<int>{0, 1, 2, 3}));
  EXPECT_THROW(EvenlySpacedRows(-1, 2), std::invalid_argument);
  const Matrix X = (Matrix(3, 1) << 1, 2, 3).finished();
  EXPECT_THROW(SelectRows(X, {0, 3}), std::invalid_argument);
}

TEST(RowSubset, FarthestStatesCoverWhereAStrideAliases) {
  Matrix line(10, 2);
  for (int r = 0; r < 10; ++r) line.row(r) << r, 7.0;  // the constant column is ignored
  EXPECT_EQ(FarthestStateRows(line, 2), (std::vector<int>{0, 9}));
  EXPECT_EQ(FarthestStateRows(line, 3), (std::vector<int>{0, 4, 9}));
  EXPECT_EQ(FarthestStateRows(line, 0).size(), 10u);
  EXPECT_EQ(FarthestStateRows(line, 12).size(), 10u);
  // A periodic log (period 4 rows, at rest at every 4th): the stride of 4 sees only the rest
  // state; the farthest states reach both extremes.
  Matrix periodic(40, 2);
  for (int r = 0; r < 40; ++r) {
    const double phase = 2.0 * M_PI * r / 4.0;
    periodic.row(r) << std::sin(phase), std::cos(phase);
  }
  const Matrix strided = SelectRows(periodic, EvenlySpacedRows(40, 10));
  EXPECT_EQ(strided.col(0).cwiseAbs().maxCoeff() < 1e-9 && strided.col(1).minCoeff() > 0.99, true);
  const Matrix covered = SelectRows(periodic, FarthestStateRows(periodic, 4));
  EXPECT_GT(covered.col(0).maxCoeff(), 0.99);
  EXPECT_LT(covered.col(0).minCoeff(), -0.99);
  EXPECT_LT(covered.col(1).minCoeff(), -0.99);
}

}  // namespace
}  // namespace structgp
