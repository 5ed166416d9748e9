// RunDiagnosisLoop against the same steps by hand (Diagnose with the training data, FitModel
// with the suggestions, Diagnose again), on a two-link arm whose joint 2 has Coulomb and
// viscous friction the starting model does not know; the improved model predicts the fast
// log, unseen, better; the loop stops when a round suggests nothing; bad input is refused.

#include "structgp/diagnose/diagnosis_loop.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "structgp/diagnose/diagnosis_report.h"
#include "structgp/rigid_body/dh_chain.h"
#include "structgp/rigid_body/rigid_body_chain.h"
#include "structgp/sim/hidden_effect.h"
#include "structgp/sim/trajectory.h"
#include "structgp/sim/urdf.h"
#include "ripple_log.h"

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

// rbd+fri on a chain IdentifyChain found from a slow log whose ripple it was not told of: the
// loop names the ripple, identifies the chain again with it beside the chain (what a user does by
// hand with `structgp identify --effects`), and refits on that chain; the result predicts a fast
// log of another path at least as well as the refit on the first chain. With reidentify_chain
// off, and for a URDF IdentifyChain did not write, the chain stays.
TEST(DiagnosisLoop, IdentifiesAChainFoundFromTheTorquesAgainWithTheAddedEffects) {
  using testing::RippleLog;
  using testing::TwoLinkRippleLog;
  const RippleLog train = TwoLinkRippleLog(sim::ViaPoints(2, 30.0, 0.01, 20, 1.0, 1.0, 1), 1);
  const RippleLog log = TwoLinkRippleLog(sim::ViaPoints(2, 8.0, 0.01, 8, 2.0, 1.0, 2), 2);
  const RippleLog eval = TwoLinkRippleLog(sim::ViaPoints(2, 8.0, 0.01, 8, 2.0, 1.0, 3), 3);
  ChainIdentificationOptions identify;
  identify.starts = 8;
  identify.kept_starts = 3;
  identify.max_rounds = 1;
  const ChainIdentificationSummary first = IdentifyChain(train.XT(), train.Y, identify);
  ASSERT_GT(first.residual_rms[1], 2.0 * train.noise[1]);  // the ripple is left over
  FitOptions fit;
  fit.model.rigid_body = std::make_shared<const RigidBodyChain>(
      RigidBodyChain::FromUrdfString(first.urdf, {}, "first.urdf"));
  const FittedModel start = FitModel(ParseModelSpec("rbd+fri"), train.X, train.Y, train.t, fit);
  ASSERT_TRUE(start.summary.IsUsable()) << start.summary.message;

  DiagnosisLoopOptions options;
  options.max_rounds = 1;
  options.chain = identify;
  std::optional<RobotModel> improved;
  const DiagnosisLoopSummary s = RunDiagnosisLoop(options, start.model, train.X, train.Y, train.t,
                                                  log.X, log.Y, log.t, &improved);
  ASSERT_EQ(s.termination, DiagnosisLoopTermination::kMaxRounds) << s.BriefReport();
  ASSERT_TRUE(improved.has_value());
  const DiagnosisRound& r = s.rounds[0];
  bool cogging2 = false;
  for (const EffectSpec& e : r.added) {
    cogging2 |= e.name == "cogging" && e.joints == std::vector<int>{2};
  }
  EXPECT_TRUE(cogging2) << s.BriefReport();
  ASSERT_TRUE(r.identification.has_value()) << s.BriefReport();
  EXPECT_GT(r.identification_seconds, 0.0);
  EXPECT_EQ(improved->options().rigid_body->urdf(), r.identification->urdf);
  EXPECT_NE(r.identification->urdf, first.urdf);

  // By hand: IdentifyChain with the model's effects, from the first chain's kinematics.
  ChainIdentificationOptions by_hand = identify;
  by_hand.effects = s.spec.effects;
  const std::optional<Vector> first_kinematics = ChainKinematicsOfUrdf(first.urdf);
  ASSERT_TRUE(first_kinematics.has_value());
  by_hand.initial_kinematics = *first_kinematics;
  const ChainIdentificationSummary again = IdentifyChain(train.XT(), train.Y, by_hand);
  EXPECT_EQ(again.urdf, r.identification->urdf);
  EXPECT_EQ(again.start_costs, r.identification->start_costs);
  // The chain with the effect explains joint 2's slow log better than the first.
  EXPECT_LT(again.residual_rms[1], 0.8 * first.residual_rms[1]);

  // The same loop on the first chain as it is.
  options.reidentify_chain = false;
  std::optional<RobotModel> kept;
  const DiagnosisLoopSummary s_kept = RunDiagnosisLoop(options, start.model, train.X, train.Y,
                                                       train.t, log.X, log.Y, log.t, &kept);
  ASSERT_TRUE(kept.has_value()) << s_kept.BriefReport();
  EXPECT_FALSE(s_kept.rounds[0].identification.has_value());
  EXPECT_EQ(kept->options().rigid_body->urdf(), first.urdf);
  ASSERT_EQ(ToString(s_kept.rounds[0].added), ToString(r.added));

  // On the unseen fast log: the chain identified again predicts no worse on joint 1 and far
  // better on joint 2, whose ripple bent the first chain (RMS / noise 3.2 and 13.8 on the first
  // chain, 1.2 and 4.9 on the chain identified again; the diagnosis, on the chain identified
  // again on the training data and the log, names cogging@2 with a period of 0.284 rad).
  Matrix a, b;
  improved->PredictRows(ModelInputs(*improved, eval.X, eval.t), &a);
  kept->PredictRows(ModelInputs(*kept, eval.X, eval.t), &b);
  for (int j = 0; j < 2; ++j) {
    const double again_rms = Rms(a.col(j) - eval.Y.col(j));
    const double kept_rms = Rms(b.col(j) - eval.Y.col(j));
    std::printf("joint %d: eval RMS / noise: identified again %.3f, first chain %.3f\n", j + 1,
                again_rms / eval.noise[j], kept_rms / eval.noise[j]);
    EXPECT_LE(again_rms, (j == 1 ? 0.5 : 1.02) * kept_rms) << "joint " << j + 1;
  }

  // The JSON and the brief report carry the identification.
  const nlohmann::json j = nlohmann::json::parse(ToJson(s));
  const nlohmann::json& id = j.at("rounds").at(0).at("identification");
  ASSERT_TRUE(id.is_object());
  EXPECT_FALSE(id.contains("urdf"));
  EXPECT_EQ(id.at("rounds"), r.identification->rounds);
  EXPECT_EQ(id.at("cost").get<double>(), r.identification->refined_cost);
  EXPECT_EQ(id.at("joints").size(), 2u);
  const nlohmann::json kept_json = nlohmann::json::parse(ToJson(s_kept));
  EXPECT_TRUE(kept_json.at("rounds").at(0).at("identification").is_null());
  EXPECT_NE(s.BriefReport().find("chain identified again"), std::string::npos) << s.BriefReport();

  // A URDF IdentifyChain did not write (the same chain, its masses edited) is refitted as it is.
  std::string edited = first.urdf;
  edited.replace(edited.find("<mass value=\"1\"/>"), 17, "<mass value=\"2\"/>");
  FitOptions other = fit;
  other.model.rigid_body = std::make_shared<const RigidBodyChain>(
      RigidBodyChain::FromUrdfString(edited, {}, "edited.urdf"));
  const FittedModel manual = FitModel(ParseModelSpec("rbd+fri"), train.X, train.Y, train.t, other);
  ASSERT_TRUE(manual.summary.IsUsable()) << manual.summary.message;
  options.reidentify_chain = true;
  std::optional<RobotModel> as_is;
  const DiagnosisLoopSummary s_manual = RunDiagnosisLoop(options, manual.model, train.X, train.Y,
                                                         train.t, log.X, log.Y, log.t, &as_is);
  ASSERT_TRUE(as_is.has_value()) << s_manual.BriefReport();
  EXPECT_FALSE(s_manual.rounds[0].identification.has_value());
  EXPECT_EQ(as_is->options().rigid_body->urdf(), edited);
}

// A chain wrong where a slow training log hides part of it: the diagnosis of a faster log
// identifies the chain again on both (a local search from the model's), and diagnoses the model
// on that chain when it explains the log better; its numbers are the search's by hand.
TEST(Diagnosis, IdentifiesTheModelsChainAgainOnTheTrainingDataAndTheLog) {
  using testing::RippleLog;
  using testing::TwoLinkRippleLog;
  // Friction only (the model's +fri): nothing is missing.
  const RippleLog train =
      TwoLinkRippleLog(sim::ViaPoints(2, 30.0, 0.01, 20, 1.0, 1.0, 1), 1, 0.0);
  const RippleLog log = TwoLinkRippleLog(sim::ViaPoints(2, 8.0, 0.01, 8, 2.5, 1.0, 2), 2, 0.0);
  ChainIdentificationOptions identify;
  identify.starts = 8;
  identify.kept_starts = 3;
  identify.max_rounds = 1;
  const ChainIdentificationSummary found = IdentifyChain(train.XT(), train.Y, identify);
  ASSERT_LT(found.residual_rms[1], 1.5 * train.noise[1]);
  const std::vector<std::string> names = ChainKinematicNames(2);
  auto index = [&](const char* name) {
    return static_cast<Eigen::Index>(std::find(names.begin(), names.end(), name) - names.begin());
  };
  // The model on the chain found, one of its kinematic numbers moved.
  auto model_on = [&](const char* name, double change) {
    Vector kinematics = found.kinematics;
    kinematics[index(name)] += change;
    FitOptions fit;
    fit.model.rigid_body = std::make_shared<const RigidBodyChain>(
        RigidBodyChain::FromUrdfString(ChainUrdf(2, kinematics, "two_link"), {}, "wrong.urdf"));
    FittedModel m = FitModel(ParseModelSpec("rbd+fri"), train.X, train.Y, train.t, fit);
    EXPECT_TRUE(m.summary.IsUsable()) << m.summary.message;
    return std::move(m.model);
  };
  DiagnosisOptions options;
  options.training_targets = train.Y;
  options.training_times = train.t;
  auto diagnose = [&](const RobotModel& model, bool reidentify) {
    options.training_inputs = ModelInputs(model, train.X, train.t);
    options.reidentify_chain = reidentify;
    const Diagnosis d = Diagnose(model, ModelInputs(model, log.X, log.t), log.Y, log.t, options);
    EXPECT_EQ(d.status, DiagnosisStatus::kOk) << d.message;
    return d;
  };

  // The distance between the two axes 5 cm off: the refit on both logs is 7 and 17 times the
  // noise on the model's chain; on the chain identified again 1.05 and 2.6 times.
  const RobotModel model = model_on("a2", 0.05);
  const Diagnosis as_is = diagnose(model, false);
  EXPECT_FALSE(as_is.chain.has_value());
  const Diagnosis d = diagnose(model, true);
  ASSERT_TRUE(d.chain.has_value());
  const ChainFinding& c = *d.chain;
  std::printf("%s\n", c.message.c_str());
  EXPECT_TRUE(c.changed) << c.message;
  EXPECT_EQ(c.joints, (std::vector<int>{1, 2}));
  for (int j = 0; j < 2; ++j) {
    std::printf("joint %d: refit RMS / noise on the log: model's chain %.2f, again %.2f\n", j + 1,
                c.refit_rms_before[j] / log.noise[j], c.refit_rms_after[j] / log.noise[j]);
    EXPECT_EQ(c.refit_rms_before[j], as_is.joints[static_cast<size_t>(j)].refit_rms);
    EXPECT_EQ(c.refit_rms_after[j], d.joints[static_cast<size_t>(j)].refit_rms);
    EXPECT_LT(c.refit_rms_after[j], 0.25 * c.refit_rms_before[j]) << "joint " << j + 1;
    // The model's own error on the log stays its own.
    EXPECT_EQ(d.joints[static_cast<size_t>(j)].rms, as_is.joints[static_cast<size_t>(j)].rms);
  }
  EXPECT_EQ(c.kinematics_before, *ChainKinematicsOf(*model.options().rigid_body));
  // By hand: a local search from the model's kinematics on the training rows and the log.
  ChainIdentificationOptions by_hand = options.chain;
  by_hand.initial_kinematics = c.kinematics_before;
  by_hand.robot_name = "two_link";
  Matrix both(train.X.rows() + log.X.rows(), 6), y(train.Y.rows() + log.Y.rows(), 2);
  Vector t(both.rows());
  both << train.X, log.X;
  y << train.Y, log.Y;
  t << train.t, log.t;
  const ChainIdentificationSummary again = IdentifyChain(both, t, y, by_hand);
  EXPECT_EQ(again.urdf, c.urdf);
  EXPECT_EQ(again.kinematics, c.kinematics);
  EXPECT_EQ(ChainIdentificationCost(again), c.cost);
  EXPECT_EQ(again.starts, std::vector<int>{-1});  // no random start
  const nlohmann::json j = nlohmann::json::parse(ToJson(d));
  EXPECT_TRUE(j.at("chain").at("changed").get<bool>());
  EXPECT_EQ(j.at("chain").at("urdf").get<std::string>(), c.urdf);
  EXPECT_EQ(j.at("chain").at("joints"), nlohmann::json::array({1, 2}));
  EXPECT_TRUE(nlohmann::json::parse(ToJson(as_is)).at("chain").is_null());
  EXPECT_NE(DiagnosisReport(d, model.spec(), options).find("chain: The chain identified from"),
            std::string::npos);

  // The second axis tilted by 0.2 rad, which these logs hardly tell from parallel: the chain
  // identified again fits the least squares as well but not the refit (joint 2: 1.2 -> 2.6
  // times the noise), so the findings stay against the model's own chain.
  const RobotModel tilted = model_on("alpha2", 0.2);
  const Diagnosis kept = diagnose(tilted, true);
  const Diagnosis kept_as_is = diagnose(tilted, false);
  ASSERT_TRUE(kept.chain.has_value());
  EXPECT_FALSE(kept.chain->changed) << kept.chain->message;
  EXPECT_TRUE(kept.chain->joints.empty());
  EXPECT_TRUE(kept.chain->explained.empty());
  EXPECT_GT(kept.chain->refit_rms_after[1], 1.5 * kept.chain->refit_rms_before[1]);
  nlohmann::json kept_json = nlohmann::json::parse(ToJson(kept));
  kept_json.erase("chain");
  nlohmann::json as_is_json = nlohmann::json::parse(ToJson(kept_as_is));
  as_is_json.erase("chain");
  EXPECT_EQ(kept_json, as_is_json);

  // A chain identify did not write (a manufacturer's URDF) is not identified again.
  FitOptions urdf;
  urdf.model.rigid_body = std::make_shared<const RigidBodyChain>(
      sim::ToRigidBodyChain(sim::TwoLinkArm()));
  const FittedModel manual = FitModel(ParseModelSpec("rbd+fri"), train.X, train.Y, train.t, urdf);
  ASSERT_TRUE(manual.summary.IsUsable()) << manual.summary.message;
  EXPECT_FALSE(diagnose(manual.model, true).chain.has_value());
}

}  // namespace
}  // namespace structgp
