// The diagnosis at 6 joints (KDL-simulated PUMA 560, slow training, fast log diagnosed with the
// training data): nothing suggested when nothing is missing (a clean log, a sinusoidal spring
// that pol spans), the missing effect named on its joint when it is.

#include <cmath>
#include <chrono>
#include <cstdio>
#include <string>

#include <gtest/gtest.h>

#include "structgp/diagnose/diagnosis.h"
#include "structgp/fit/fit_model.h"
#include "structgp/model/robot_model.h"
#include "structgp/sim/hidden_effect.h"

namespace structgp {
namespace {

using sim::HiddenEffect;

struct Case {
  Diagnosis diagnosis;
  double seconds = 0;
};

Case RunPuma(HiddenEffect effect, int joint) {
  sim::HiddenEffectOptions o;
  o.effect = effect;
  o.joint = joint;
  o.magnitude = 0.1;
  o.train_duration = 20.0;
  o.test_duration = 5.0;
  o.seed = 4;
  const auto scenario = sim::MakeHiddenEffectScenario(sim::Puma560(), o);
  const auto start = std::chrono::steady_clock::now();
  FitOptions fit_options;
  fit_options.max_evidence_rows = 500;
  FittedModel fit = FitModel(ParseModelSpec("pol"), scenario.train.X, scenario.train.Y,
                             scenario.train.t, fit_options);
  EXPECT_TRUE(fit.summary.IsUsable()) << fit.summary.message;
  DiagnosisOptions options;
  options.training_inputs = scenario.train.X;
  options.training_targets = scenario.train.Y;
  options.training_times = scenario.train.t;
  options.nystrom_features = 400;
  Case out;
  out.diagnosis = Diagnose(fit.model, scenario.test.X, scenario.test.Y, scenario.test.t, options);
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("%s (%.1f s)\n%s", scenario.description.c_str(), out.seconds,
              ToJson(out.diagnosis).c_str());
  return out;
}

TEST(DiagnosisAt6Joints, NothingMissingGivesNoSuggestion) {
  for (const HiddenEffect e : {HiddenEffect::kNone, HiddenEffect::kSpring}) {
    const Case c = RunPuma(e, 2);
    EXPECT_TRUE(c.diagnosis.suggestions.empty()) << sim::ToString(e);
    EXPECT_NE(c.diagnosis.coverage.verdict, Verdict::kMissingEffect) << sim::ToString(e);
  }
}

TEST(DiagnosisAt6Joints, NamesCoulombOnItsJoint) {
  const Case c = RunPuma(HiddenEffect::kCoulomb, 2);
  ASSERT_FALSE(c.diagnosis.suggestions.empty());
  EXPECT_EQ(c.diagnosis.suggestions.front().effect, "coulomb");
  EXPECT_EQ(c.diagnosis.suggestions.front().joint, 2);
}

}  // namespace
}  // namespace structgp
