// RunDiagnosisLoop against the same steps by hand (Diagnose with the training data, FitModel
// with the suggestions, Diagnose again), on a two-link arm whose joint 2 has Coulomb and
// viscous friction the starting model does not know; the improved model predicts the fast
// log, unseen, better; the loop stops when a round suggests nothing; bad input is refused.

#include "structgp/diagnose/diagnosis_loop.h"

#include <cmath>
#include <optional>
#include <stdexcept>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "structgp/sim/hidden_effect.h"

namespace structgp {
namespace {

// A slow log (the training data) and a 2.5x faster one (diagnosed, then predicted), with
// Coulomb friction and a viscous friction of 10% of the torque scale on joint 2.
const sim::HiddenEffectScenario& Scenario() {
  static const sim::HiddenEffectScenario scenario = [] {
    sim::HiddenEffectOptions o;
    o.effect = sim::HiddenEffect::kCoulomb;
    o.joint = 2;
    o.seed = 3;
    o.train_duration = 20.0;
    o.test_duration = 8.0;
    o.dt = 0.02;
    o.num_vias = 12;
    sim::HiddenEffectScenario s = sim::MakeHiddenEffectScenario(sim::TwoLinkArm(), o);
    double qd_max = 0.0;
    for (const sim::Dataset* d : {&s.train, &s.test}) {
      qd_max = std::max(qd_max, d->X.col(3).cwiseAbs().maxCoeff());
    }
    for (sim::Dataset* d : {&s.train, &s.test}) d->Y.col(1) += 0.1 * d->X.col(3) / qd_max;
    return s;
  }();
  return scenario;
}

double Rms(const Vector& v) { return std::sqrt(v.squaredNorm() / static_cast<double>(v.size())); }

TEST(DiagnosisLoop, EqualsTheStepsByHandAndImprovesTheUnseenLog) {
  const sim::Dataset& train = Scenario().train;
  const sim::Dataset& log = Scenario().test;
  const FittedModel start = FitModel(ParseModelSpec("pol"), train.X, train.Y, train.t, {});
  ASSERT_TRUE(start.summary.IsUsable()) << start.summary.message;

  DiagnosisLoopOptions options;
  std::optional<RobotModel> improved;
  const DiagnosisLoopSummary s = RunDiagnosisLoop(options, start.model, train.X, train.Y, train.t,
                                                  log.X, log.Y, log.t, &improved);
  ASSERT_TRUE(s.termination == DiagnosisLoopTermination::kNothingNew ||
              s.termination == DiagnosisLoopTermination::kMaxRounds)
      << s.BriefReport();
  ASSERT_GE(s.rounds.size(), 2u) << s.BriefReport();
  ASSERT_TRUE(improved.has_value());
  EXPECT_EQ(ModelLabel(improved->spec()), ModelLabel(s.spec));
  EXPECT_EQ(s.Added().size(), s.spec.effects.size());
  // Every suggestion on joint 2, and the friction there named.
  for (const EffectSpec& e : s.Added()) {
    ASSERT_EQ(e.joints.size(), 1u) << ToString(e);
    EXPECT_EQ(e.joints[0], 2) << ToString(e);
  }
  if (s.termination == DiagnosisLoopTermination::kNothingNew) {
    EXPECT_TRUE(s.rounds.back().diagnosis.suggestions.empty());
    EXPECT_FALSE(s.rounds.back().refit.has_value());
  }

  // Round 1 by hand: the same suggestions, and the same refitted model.
  DiagnosisOptions by_hand;
  by_hand.training_inputs = train.X;
  by_hand.training_targets = train.Y;
  by_hand.training_times = train.t;
  const Diagnosis d1 = Diagnose(start.model, log.X, log.Y, log.t, by_hand);
  ASSERT_EQ(d1.status, DiagnosisStatus::kOk) << d1.message;
  ASSERT_EQ(d1.suggestions.size(), s.rounds[0].diagnosis.suggestions.size());
  ModelSpec spec = start.model.spec();
  for (size_t k = 0; k < d1.suggestions.size(); ++k) {
    EXPECT_EQ(d1.suggestions[k].spec, s.rounds[0].diagnosis.suggestions[k].spec);
    for (const EffectSpec& e : ParseEffectList(d1.suggestions[k].spec)) spec.effects.push_back(e);
  }
  const FittedModel refit = FitModel(spec, train.X, train.Y, train.t, {});
  ASSERT_TRUE(refit.summary.IsUsable()) << refit.summary.message;
  EXPECT_EQ(ModelLabel(spec), s.rounds[1].model);
  if (s.rounds.size() == 2 && s.termination == DiagnosisLoopTermination::kNothingNew) {
    Matrix a, b;
    refit.model.PredictRows(ModelInputs(refit.model, log.X, log.t), &a);
    improved->PredictRows(ModelInputs(*improved, log.X, log.t), &b);
    EXPECT_EQ(a, b);
  }

  // The improved model predicts joint 2 of the fast log better than the starting model, and
  // at least as well as one round alone.
  Matrix before, one_round, after;
  start.model.PredictRows(log.X, &before);
  refit.model.PredictRows(ModelInputs(refit.model, log.X, log.t), &one_round);
  improved->PredictRows(ModelInputs(*improved, log.X, log.t), &after);
  const double rms_before = Rms(before.col(1) - log.Y.col(1));
  const double rms_one = Rms(one_round.col(1) - log.Y.col(1));
  const double rms_after = Rms(after.col(1) - log.Y.col(1));
  EXPECT_LT(rms_after, 0.5 * rms_before) << s.BriefReport();
  EXPECT_LE(rms_after, 1.05 * rms_one) << s.BriefReport();
  // The JSON holds every round with its findings.
  const nlohmann::json j = nlohmann::json::parse(ToJson(s));
  EXPECT_EQ(j["termination"], ToString(s.termination));
  ASSERT_EQ(j["rounds"].size(), s.rounds.size());
  EXPECT_EQ(j["rounds"][0]["added"], ToString(s.rounds[0].added));
  EXPECT_EQ(j["rounds"][0]["findings"]["suggestions"].size(),
            s.rounds[0].diagnosis.suggestions.size());
  EXPECT_TRUE(j["rounds"][0]["refit"]["usable"].get<bool>());
  EXPECT_EQ(j["model"], ModelLabel(s.spec));
  const std::string report = s.BriefReport();
  EXPECT_NE(report.find("round 1: pol: add "), std::string::npos) << report;
  EXPECT_NE(report.find("stopped: "), std::string::npos) << report;
}

TEST(DiagnosisLoop, OneRoundStopsAfterItsRefitAndBadInputIsRefused) {
  const sim::Dataset& train = Scenario().train;
  const sim::Dataset& log = Scenario().test;
  const FittedModel start = FitModel(ParseModelSpec("pol"), train.X, train.Y, train.t, {});
  ASSERT_TRUE(start.summary.IsUsable()) << start.summary.message;
  DiagnosisLoopOptions options;
  options.max_rounds = 1;
  std::optional<RobotModel> improved;
  const DiagnosisLoopSummary s = RunDiagnosisLoop(options, start.model, train.X, train.Y, train.t,
                                                  log.X, log.Y, log.t, &improved);
  EXPECT_EQ(s.termination, DiagnosisLoopTermination::kMaxRounds) << s.BriefReport();
  ASSERT_EQ(s.rounds.size(), 1u);
  ASSERT_TRUE(s.rounds[0].refit.has_value());
  EXPECT_TRUE(improved.has_value());

  options.max_rounds = 0;
  EXPECT_THROW(RunDiagnosisLoop(options, start.model, train.X, train.Y, train.t, log.X, log.Y,
                                log.t, &improved),
               std::invalid_argument);
  options.max_rounds = 2;
  try {
    RunDiagnosisLoop(options, start.model, train.X, train.Y, Vector(), log.X, log.Y, log.t,
                     &improved);
    ADD_FAILURE() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("times"), std::string::npos) << e.what();
  }
  const RobotModel unfitted(ParseModelSpec("pol"), 2);
  EXPECT_THROW(RunDiagnosisLoop(options, unfitted, train.X, train.Y, train.t, log.X, log.Y, log.t,
                                &improved),
               std::invalid_argument);
}

// lagk is one GP of every joint: its refits start from the current model's hyper-parameters,
// at its sigma (the default), and equal FitModel by hand with that start; with
// refit_from_model off they equal a fit from scratch over the whole sigma grid.
TEST(DiagnosisLoop, RefitsLagkFromTheModelsOwnHyperparameters) {
  const sim::Dataset& train = Scenario().train;
  const sim::Dataset& log = Scenario().test;
  FitOptions fit;
  fit.euler_lagrange.sigmas = {1.0, 10.0, 100.0};
  fit.euler_lagrange.hyperparameter_rows = 150;
  const FittedModel start = FitModel(ParseModelSpec("lagk"), train.X, train.Y, train.t, fit);
  ASSERT_TRUE(start.summary.IsUsable()) << start.summary.message;
  const EulerLagrangeGPHyperparameters& h0 = start.model.gp().euler_lagrange()->hyperparameters();

  DiagnosisLoopOptions options;
  options.max_rounds = 1;
  options.fit = fit;
  std::optional<RobotModel> improved;
  const DiagnosisLoopSummary s = RunDiagnosisLoop(options, start.model, train.X, train.Y, train.t,
                                                  log.X, log.Y, log.t, &improved);
  ASSERT_EQ(s.rounds.size(), 1u) << s.BriefReport();
  ASSERT_FALSE(s.rounds[0].added.empty()) << s.BriefReport();
  ASSERT_TRUE(improved.has_value()) << s.BriefReport();
  EXPECT_EQ(improved->gp().euler_lagrange()->hyperparameters().sigma, h0.sigma);

  ModelSpec spec = start.model.spec();
  spec.effects = s.rounds[0].added;
  FitOptions from_model = fit;
  from_model.euler_lagrange.start = h0;
  const FittedModel by_hand = FitModel(spec, train.X, train.Y, train.t, from_model);
  ASSERT_TRUE(by_hand.summary.IsUsable()) << by_hand.summary.message;
  Matrix a, b;
  by_hand.model.PredictRows(ModelInputs(by_hand.model, log.X, log.t), &a);
  improved->PredictRows(ModelInputs(*improved, log.X, log.t), &b);
  EXPECT_EQ(a, b);

  options.refit_from_model = false;
  std::optional<RobotModel> scratch;
  const DiagnosisLoopSummary s2 = RunDiagnosisLoop(options, start.model, train.X, train.Y,
                                                   train.t, log.X, log.Y, log.t, &scratch);
  ASSERT_TRUE(scratch.has_value()) << s2.BriefReport();
  ASSERT_EQ(ToString(s2.rounds[0].added), ToString(s.rounds[0].added));
  const FittedModel grid = FitModel(spec, train.X, train.Y, train.t, fit);
  ASSERT_TRUE(grid.summary.IsUsable()) << grid.summary.message;
  grid.model.PredictRows(ModelInputs(grid.model, log.X, log.t), &a);
  scratch->PredictRows(ModelInputs(*scratch, log.X, log.t), &b);
  EXPECT_EQ(a, b);
  EXPECT_NE(s.rounds[0].refit->method_description, s2.rounds[0].refit->method_description);
}

}  // namespace
}  // namespace structgp
