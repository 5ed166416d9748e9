// The demo's simulated logs and the spec parser, shared by the tests of the fitting workflow.
#ifndef STRUCTGP_TESTS_DEMO_SCENARIO_H_
#define STRUCTGP_TESTS_DEMO_SCENARIO_H_

#include <string>

#include "structgp/model/model_spec.h"
#include "structgp/sim/hidden_effect.h"

namespace structgp {
namespace testing {

// A slow two-link log with Coulomb friction on joint 2 (seed 3), and its fast test log, as
// the demo simulates them.
inline const sim::HiddenEffectScenario& DemoScenario() {
  static const sim::HiddenEffectScenario scenario = [] {
    sim::HiddenEffectOptions o;
    o.effect = sim::HiddenEffect::kCoulomb;
    o.joint = 2;
    o.seed = 3;
    return sim::MakeHiddenEffectScenario(sim::TwoLinkArm(), o);
  }();
  return scenario;
}

// "pol+fri" with the effects "coulomb@2", as the command line takes them.
inline ModelSpec Spec(const std::string& model, const std::string& effects = "") {
  ModelSpec spec = ParseModelSpec(model);
  if (!effects.empty()) spec.effects = ParseEffectList(effects);
  return spec;
}

}  // namespace testing
}  // namespace structgp

#endif  // STRUCTGP_TESTS_DEMO_SCENARIO_H_
