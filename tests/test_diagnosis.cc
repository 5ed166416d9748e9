// The diagnosis loop on KDL-simulated robots with hidden effects, in the paper's setting
// (train on a slow trajectory, test on a fast one): a model lacking the effect gets it named
// on the right joint, adding it cuts the test RMS, and a clean log gives no suggestion.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "structgp/diagnose/diagnosis.h"
#include "structgp/fit/fit_model.h"
#include "structgp/model/model_spec.h"
#include "structgp/model/robot_model.h"
#include "structgp/sim/hidden_effect.h"

namespace structgp {
namespace {

using sim::HiddenEffect;

double Rms(const Matrix& a, const Matrix& b) { return std::sqrt((a - b).squaredNorm() / a.size()); }

struct Outcome {
  Diagnosis diagnosis;
  double rms_before = 0, rms_after = 0;  // test RMS of the joint with the effect
  // With exactly one suggestion on the test log: the residual RMS of its joint on that log
  // after an independent refit there of the base model plus the effect (-1 otherwise).
  double refit_residual_rms = -1;
};

// Fits `spec` on the slow log: noise and output scales by evidence, the base's default shape
// and block scales (the library's workflow with those groups held).
RobotModel FitModel(const ModelSpec& spec, const sim::Dataset& train) {
  FitOptions options;
  options.evidence.optimize_shape = false;
  options.evidence.optimize_block_scales = false;
  options.evidence.optimize_noise = false;
  FittedModel fit = structgp::FitModel(spec, train.X, train.Y, train.t, options);
  EXPECT_TRUE(fit.summary.IsUsable()) << fit.summary.message;
  return std::move(fit.model);
}

Matrix WithTime(const sim::Dataset& d, bool time) {
  if (!time) return d.X;
  Matrix X(d.X.rows(), d.X.cols() + 1);
  X << d.X, d.t;
  return X;
}

// Diagnoses on the fast test log, or on the whole log (train then test) when whole_log.
Outcome RunCase(HiddenEffect effect, int joint, double magnitude, bool whole_log = false) {
  sim::HiddenEffectOptions o;
  o.effect = effect;
  o.joint = joint;
  o.magnitude = magnitude;
  o.seed = 3;
  const auto scenario = sim::MakeHiddenEffectScenario(sim::TwoLinkArm(), o);
  const ModelSpec base = ParseModelSpec("pol");
  const RobotModel model = FitModel(base, scenario.train);
  Outcome out;
  if (whole_log) {
    Matrix X(scenario.train.X.rows() + scenario.test.X.rows(), scenario.test.X.cols());
    Matrix Y(X.rows(), scenario.test.Y.cols());
    Vector t(X.rows());
    X << scenario.train.X, scenario.test.X;
    Y << scenario.train.Y, scenario.test.Y;
    t << scenario.train.t, scenario.test.t;
    out.diagnosis = Diagnose(model, X, Y, t);
  } else {
    // As a user would: the log to diagnose and the data the model was trained on.
    DiagnosisOptions options;
    options.training_inputs = scenario.train.X;
    options.training_targets = scenario.train.Y;
    options.training_times = scenario.train.t;
    out.diagnosis = Diagnose(model, scenario.test.X, scenario.test.Y, scenario.test.t, options);
  }
  Matrix pred;
  model.PredictRows(scenario.test.X, &pred);
  out.rms_before = Rms(pred.col(joint - 1), scenario.test.Y.col(joint - 1));
  if (!out.diagnosis.suggestions.empty()) {
    ModelSpec fixed = base;
    for (const auto& s : out.diagnosis.suggestions) {
      fixed.effects.push_back(EffectSpec{s.effect, {s.joint}, s.params});
    }
    const RobotModel better = FitModel(fixed, scenario.train);
    better.PredictRows(WithTime(scenario.test, better.uses_time()), &pred);
    out.rms_after = Rms(pred.col(joint - 1), scenario.test.Y.col(joint - 1));
    if (!whole_log && out.diagnosis.suggestions.size() == 1) {
      const int j = out.diagnosis.suggestions.front().joint - 1;
      const RobotModel refit = FitModel(fixed, scenario.test);
      refit.PredictRows(WithTime(scenario.test, refit.uses_time()), &pred);
      out.refit_residual_rms = Rms(pred.col(j), scenario.test.Y.col(j));
    }
  }
  std::printf("%s\n%s", scenario.description.c_str(), ToJson(out.diagnosis).c_str());
  std::printf("test RMS of joint %d: %.4f -> %.4f\n", joint, out.rms_before, out.rms_after);
  return out;
}

void ExpectNamed(const Outcome& out, const std::string& effect, int joint) {
  ASSERT_FALSE(out.diagnosis.suggestions.empty()) << "no suggestion";
  const auto& top = out.diagnosis.suggestions.front();
  EXPECT_EQ(top.effect, effect);
  EXPECT_EQ(top.joint, joint);
  EXPECT_GT(top.score, 10.0);
  EXPECT_LT(top.rms_after, top.rms_before);
  EXPECT_LT(top.residual_rms_after, top.residual_rms_before);
  // What the diagnosis says the effect would leave on this log matches a refit with it (the
  // hyper-parameters of the two fits differ slightly, hence 15%).
  if (out.refit_residual_rms >= 0) {
    EXPECT_NEAR(top.residual_rms_after, out.refit_residual_rms, 0.15 * out.refit_residual_rms);
  }
  // Adding the named effect cuts the test RMS of that joint substantially.
  EXPECT_LT(out.rms_after, 0.7 * out.rms_before);
}

// The top suggestion's alternatives (Suggestion::alternatives) are effects of its joint that
// passed every bar in its round (some by their held-out fall, with a low evidence) with a lower
// score, and that the diagnosis then lists as refused because the suggestion explains them.
void ExpectAlternativesExplained(const Outcome& out) {
  ASSERT_FALSE(out.diagnosis.suggestions.empty());
  const Suggestion& top = out.diagnosis.suggestions.front();
  for (const AlternativeEffect& a : top.alternatives) {
    const std::vector<EffectSpec> parsed = ParseEffectList(a.spec);
    ASSERT_EQ(parsed.size(), 1u) << a.spec;
    EXPECT_EQ(parsed[0].joints, std::vector<int>{top.joint}) << a.spec;
    EXPECT_NE(parsed[0].name, top.effect) << a.spec;
    EXPECT_LE(a.score, top.score) << a.spec;
    const bool explained = std::any_of(
        out.diagnosis.refused.begin(), out.diagnosis.refused.end(), [&](const Refusal& r) {
          return r.candidate.effect == parsed[0].name && r.candidate.joint == top.joint &&
                 r.candidate.scope == a.scope && r.after_suggestions;
        });
    EXPECT_TRUE(explained) << a.spec << " is not refused as explained by the suggestions";
  }
}

bool HasAlternative(const Suggestion& s, const std::string& effect) {
  return std::any_of(s.alternatives.begin(), s.alternatives.end(), [&](const AlternativeEffect& a) {
    return ParseEffectList(a.spec).at(0).name == effect;
  });
}

TEST(Diagnosis, CleanLogGivesNoSuggestion) {
  const Outcome out = RunCase(HiddenEffect::kNone, 1, 0.0);
  EXPECT_TRUE(out.diagnosis.suggestions.empty());
}

TEST(Diagnosis, SinusoidalSpringIsNotMissingFromPol) {
  const Outcome out = RunCase(HiddenEffect::kSpring, 2, 0.2);
  for (const auto& s : out.diagnosis.suggestions) ADD_FAILURE() << "suggested " << s.spec;
}

TEST(Diagnosis, NamesCoulombOnTheRightJoint) {
  const Outcome out = RunCase(HiddenEffect::kCoulomb, 2, 0.1);
  ExpectNamed(out, "coulomb", 2);
  // A Stribeck term with a wide velocity scale is nearly a Coulomb step on this log: the
  // suggestion says so.
  ExpectAlternativesExplained(out);
  ASSERT_FALSE(out.diagnosis.suggestions.empty());
  EXPECT_TRUE(HasAlternative(out.diagnosis.suggestions.front(), "stribeck"));
}

TEST(Diagnosis, NamesViscous) { ExpectNamed(RunCase(HiddenEffect::kViscous, 1, 0.1), "viscous", 1); }

TEST(Diagnosis, NamesStribeck) {
  ExpectNamed(RunCase(HiddenEffect::kStribeck, 2, 0.1), "stribeck", 2);
}

TEST(Diagnosis, NamesCoggingWithItsPeriod) {
  const Outcome out = RunCase(HiddenEffect::kCogging, 1, 0.05);
  ExpectNamed(out, "cogging", 1);
  if (!out.diagnosis.suggestions.empty()) {
    EXPECT_NEAR(out.diagnosis.suggestions.front().params.at("period"), 0.3, 0.01);
    // A ripple with the angle's period: no other effect explains it.
    EXPECT_TRUE(out.diagnosis.suggestions.front().alternatives.empty());
  }
}

// A Coulomb friction that grows with time: on the whole log, both the friction and its drift
// are named on joint 2 (on a short window alone, drift looks like plain Coulomb friction).
TEST(Diagnosis, NamesDriftOnTheWholeLog) {
  const Outcome out = RunCase(HiddenEffect::kDrift, 2, 0.1, /*whole_log=*/true);
  bool named = false;
  for (const auto& s : out.diagnosis.suggestions) {
    EXPECT_EQ(s.joint, 2) << s.spec;
    named = named || s.effect == "drift";
  }
  EXPECT_TRUE(named);
  EXPECT_LT(out.rms_after, 0.7 * out.rms_before);
}

// ---- models in function space --------------------------------------------------------------

// From 4 joints on, pol runs on k_pol's formula (its explicit map has 8,830 features): the same
// model as the explicit map used as a kernel, at O(N) instead of O(D) per kernel value.
TEST(FunctionSpacePol, EqualsTheExplicitMapUsedAsAKernel) {
  sim::HiddenEffectOptions o;
  o.effect = HiddenEffect::kCoulomb;
  o.train_duration = 1.2;
  o.test_duration = 0.5;
  const auto scenario = sim::MakeHiddenEffectScenario(sim::RandomRobot(4, 5), o);
  const ModelSpec spec = ParseModelSpec("pol+fri");
  RobotModel formula(spec, 4);
  ASSERT_NE(formula.kernel(), nullptr);
  ASSERT_EQ(formula.feature_map(), nullptr);
  RobotModelOptions by_map;
  by_map.max_explicit_features = 1 << 30;
  by_map.form = Form::kFunctionSpace;
  RobotModel explicit_map(spec, 4, by_map);
  ASSERT_NE(explicit_map.feature_map(), nullptr);
  EXPECT_GT(explicit_map.feature_map()->dim(), 8830);

  const Matrix& X = scenario.train.X;
  const Matrix& Y = scenario.train.Y;
  ASSERT_EQ(formula.Fit(X, Y), Status::kOk);
  ASSERT_EQ(explicit_map.Fit(X, Y), Status::kOk);
  Matrix mean_a, mean_b, std_a, std_b;
  formula.PredictRows(scenario.test.X, &mean_a, &std_a);
  explicit_map.PredictRows(scenario.test.X, &mean_b, &std_b);
  const double scale = mean_b.cwiseAbs().maxCoeff();
  EXPECT_LT((mean_a - mean_b).cwiseAbs().maxCoeff(), 1e-8 * scale);
  EXPECT_LT((std_a - std_b).cwiseAbs().maxCoeff(), 1e-6 * std_b.cwiseAbs().maxCoeff());
}

// A time-dependent effect in function space (pol on k_pol's formula for 2 joints, forced):
// the base kernel sees the state alone (LeadingInputsKernel), the drift its features with t;
// predictions equal those of the explicit map (with the drift.s features) used as a kernel.
TEST(FunctionSpacePol, DriftInFunctionSpaceEqualsTheExplicitMapWithDrift) {
  sim::HiddenEffectOptions o;
  o.effect = HiddenEffect::kDrift;
  o.joint = 2;
  o.train_duration = 6.0;
  o.test_duration = 2.0;
  const auto scenario = sim::MakeHiddenEffectScenario(sim::TwoLinkArm(), o);
  const ModelSpec spec = ParseModelLabel("pol + drift@2:t0=0;span=8");
  RobotModelOptions by_formula;
  by_formula.max_explicit_features = 10;
  by_formula.form = Form::kFunctionSpace;
  RobotModel formula(spec, 2, by_formula);
  ASSERT_NE(formula.kernel(), nullptr);
  ASSERT_EQ(formula.feature_map(), nullptr);
  EXPECT_EQ(formula.input_dim(), 7);
  RobotModelOptions by_map;  // the explicit map as a kernel, with the drift's features
  by_map.form = Form::kFunctionSpace;
  RobotModel explicit_map(spec, 2, by_map);
  ASSERT_NE(explicit_map.feature_map(), nullptr);

  const Matrix X = WithTime(scenario.train, true), Xs = WithTime(scenario.test, true);
  const Matrix& Y = scenario.train.Y;
  ASSERT_EQ(explicit_map.Fit(X, Y), Status::kOk);
  ASSERT_EQ(formula.Fit(X, Y), Status::kOk);
  Matrix mean_a, mean_b;
  formula.PredictRows(Xs, &mean_a);
  explicit_map.PredictRows(Xs, &mean_b);
  const double scale = mean_b.cwiseAbs().maxCoeff();
  EXPECT_LT((mean_a - mean_b).cwiseAbs().maxCoeff(), 1e-6 * scale);
  // The drift matters: the same model without it predicts the later log differently.
  RobotModel no_drift(ParseModelSpec("pol"), 2, by_map);
  ASSERT_EQ(no_drift.Fit(scenario.train.X, Y), Status::kOk);
  Matrix mean_c;
  no_drift.PredictRows(scenario.test.X, &mean_c);
  EXPECT_GT((mean_c - mean_b).cwiseAbs().maxCoeff(), 100 * 1e-6 * scale);
}

// A 4-joint robot with a hidden Coulomb friction on joint 3, modelled by pol in function space:
// the diagnosis scores the candidates against Nystrom features of the model's kernel, names the
// effect on the right joint, and adding it (still in function space) cuts the test error.
TEST(FunctionSpacePol, DiagnosisNamesCoulombOnFourJoints) {
  sim::HiddenEffectOptions o;
  o.effect = HiddenEffect::kCoulomb;
  o.joint = 3;
  o.magnitude = 0.1;
  o.train_duration = 15.0;
  o.test_duration = 5.0;
  o.seed = 2;
  const auto scenario = sim::MakeHiddenEffectScenario(sim::RandomRobot(4, 7), o);
  auto fit = [&](const ModelSpec& spec) {
    auto model = std::make_unique<RobotModel>(spec, 4);
    EXPECT_EQ(model->feature_map(), nullptr);
    FitOptions options;
    // A third of the rows for the evidence: O(m^3) per evaluation.
    options.max_evidence_rows = static_cast<int>(scenario.train.X.rows()) / 3;
    options.evidence.max_iterations = 60;
    const FitSummary summary =
        FitModel(options, scenario.train.X, scenario.train.Y, scenario.train.t, model.get());
    EXPECT_TRUE(summary.IsUsable()) << summary.message;
    return model;
  };
  const ModelSpec base = ParseModelSpec("pol");
  const auto model = fit(base);
  DiagnosisOptions options;
  options.nystrom_features = 300;
  const Diagnosis d = Diagnose(*model, scenario.train.X, scenario.train.Y, scenario.train.t,
                               options);
  std::printf("%s\n%s", scenario.description.c_str(), ToJson(d).c_str());
  EXPECT_NE(d.features.find("Nystrom"), std::string::npos) << d.features;
  ASSERT_FALSE(d.suggestions.empty());
  EXPECT_EQ(d.suggestions.front().effect, "coulomb");
  EXPECT_EQ(d.suggestions.front().joint, 3);

  ModelSpec fixed = base;
  fixed.effects.push_back(EffectSpec{"coulomb", {3}, d.suggestions.front().params});
  const auto better = fit(fixed);
  Matrix before, after;
  model->PredictRows(scenario.test.X, &before);
  better->PredictRows(scenario.test.X, &after);
  const double rms_before = Rms(before.col(2), scenario.test.Y.col(2));
  const double rms_after = Rms(after.col(2), scenario.test.Y.col(2));
  std::printf("test RMS of joint 3: %.4f -> %.4f\n", rms_before, rms_after);
  EXPECT_LT(rms_after, 0.7 * rms_before);
}

}  // namespace
}  // namespace structgp
