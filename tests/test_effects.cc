// Typed effects: the registry's parameter checks and messages, the text round trip from a
// diagnosis's suggestion back to the same effect (every built-in effect whose parameters are
// estimated), each effect's own parameter proposal against values known by construction,
// the invariant battery on every built-in effect as a feature map (with kernels written out
// independently), and a user effect registered here that proposes its parameter by evidence
// and is found and suggested by Diagnose.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "battery_options.h"
#include "structgp/diagnose/diagnosis.h"
#include "structgp/diagnose/diagnosis_report.h"
#include "structgp/feature/effect_feature_map.h"
#include "structgp/feature/effects.h"
#include "structgp/feature/friction_feature_map.h"
#include "structgp/fit/fit_model.h"
#include "structgp/model/model_spec.h"
#include "structgp/sim/hidden_effect.h"

namespace structgp {
namespace {

constexpr double kTwoPi = 6.283185307179586;

const std::vector<std::string> kBuiltIn = {"viscous", "coulomb", "stribeck", "offset",
                                           "cogging", "spring",  "drift"};

std::string ErrorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "(no exception)";
}

// Features of `effect` on joint `joint` of a 2-joint state at several rows, for bitwise
// comparisons of two effects.
Matrix Features(const std::shared_ptr<const Effect>& effect, int joint) {
  EffectFeatureMap map(2, effect, {joint}, /*with_time=*/true);
  const Matrix X = testing::RandomStates(7, 20, 77);
  Matrix Phi;
  map.EvaluateRows(X, &Phi);
  return Phi;
}

// ---- the registry and the typed parameters ---------------------------------------------------

TEST(EffectRegistry, BuiltInEffectsInTheOrderOfTheTable) {
  const std::vector<std::string> names = EffectNames();
  ASSERT_GE(names.size(), kBuiltIn.size());
  EXPECT_TRUE(std::equal(kBuiltIn.begin(), kBuiltIn.end(), names.begin()));
}

// Each built-in effect knows its parameters: its description is the registry's, its values
// are exactly the described ones, and MakeEffect(name(), parameters()) gives it back.
TEST(EffectRegistry, EveryEffectKnowsItsParameters) {
  for (const std::string& name : kBuiltIn) {
    SCOPED_TRACE(name);
    const std::shared_ptr<const Effect> prototype = MakeEffectPrototype(name);
    EXPECT_EQ(prototype->name(), name);
    std::vector<std::string> registered, described, reported;
    for (const auto& p : EffectParameterInfo(name)) registered.push_back(p.name);
    for (const auto& p : prototype->parameter_info()) described.push_back(p.name);
    for (const auto& kv : prototype->parameters()) reported.push_back(kv.first);
    EXPECT_EQ(described, registered);
    std::sort(registered.begin(), registered.end());
    EXPECT_EQ(reported, registered);
    const std::shared_ptr<const Effect> again = MakeEffect(name, prototype->parameters());
    EXPECT_EQ(again->parameters(), prototype->parameters());
    EXPECT_TRUE((Features(again, 1).array() == Features(prototype, 1).array()).all());
  }
}

TEST(EffectRegistry, ParameterTableOfCogging) {
  const auto info = EffectParameterInfo("cogging");
  ASSERT_EQ(info.size(), 2u);
  EXPECT_EQ(info[0].name, "period");
  EXPECT_EQ(info[0].unit, "rad");
  EXPECT_TRUE(info[0].required);
  ASSERT_TRUE(info[0].search.has_value());
  EXPECT_EQ(info[0].search->min, 0.02);
  EXPECT_EQ(info[0].search->max, 3.0);
  EXPECT_EQ(info[1].name, "harmonics");
  EXPECT_TRUE(info[1].integer);
  EXPECT_EQ(info[1].default_value, 1.0);
}

TEST(EffectRegistry, MessagesNameTheParameterItsRangeAndUnit) {
  EXPECT_EQ(ErrorOf([] { MakeEffect("cogging", {{"period", -1.0}}); }),
            "effect 'cogging': parameter 'period' expected in [1e-06, 1e+06] rad, got -1");
  EXPECT_EQ(ErrorOf([] { MakeEffect("cogging"); }),
            "effect 'cogging': parameter 'period' is required (e.g. cogging@1:period=0.5)");
  EXPECT_EQ(ErrorOf([] { MakeEffect("cogging", {{"period", 0.3}, {"harmonics", 2.5}}); }),
            "effect 'cogging': parameter 'harmonics' expected an integer in [1, 20], got 2.5");
  EXPECT_EQ(ErrorOf([] { MakeEffect("coulomb", {{"widht", 0.1}}); }),
            "effect 'coulomb' has no parameter 'widht' (accepted: width)");
  EXPECT_EQ(ErrorOf([] { MakeEffect("viscous", {{"gain", 1.0}}); }),
            "effect 'viscous' has no parameter 'gain' (accepted: none)");
  EXPECT_EQ(ErrorOf([] { MakeEffect("stribeck", {{"velocity", 0.0}}); }),
            "effect 'stribeck': parameter 'velocity' expected in [1e-09, 1e+09] rad/s, got 0");
  EXPECT_EQ(ErrorOf([] { MakeEffect("drift", {{"span", NAN}}); }),
            "effect 'drift': parameter 'span' expected in [1e-09, 1e+12] s, got nan");
  EXPECT_NE(ErrorOf([] { MakeEffect("frob"); }).find("unknown effect 'frob' (known: viscous"),
            std::string::npos);
  // The parser gives the same words, with the item's position.
  EXPECT_EQ(ErrorOf([] { ParseEffectList("viscous,cogging@1:period=-1"); }),
            "effect list 'viscous,cogging@1:period=-1', character 9: effect 'cogging': "
            "parameter 'period' expected in [1e-06, 1e+06] rad, got -1");
}

TEST(EffectParameter, ExpectedTextCoversEveryKindOfRange) {
  EffectParameter p;
  p.name = "x";
  EXPECT_EQ(p.ExpectedText(), "a finite number");
  p.unit = "s";
  EXPECT_EQ(p.ExpectedText(), "a finite number of s");
  p.valid.min = 0.5;
  EXPECT_EQ(p.ExpectedText(), ">= 0.5 s");
  p.valid = ParameterRange{-HUGE_VAL, 2.0};
  EXPECT_EQ(p.ExpectedText(), "<= 2 s");
  p.integer = true;
  p.unit.clear();
  EXPECT_EQ(p.ExpectedText(), "an integer <= 2");
  EXPECT_NO_THROW(p.Check("e", 2.0));
  EXPECT_THROW(p.Check("e", 1.5), std::invalid_argument);
  EXPECT_THROW(p.Check("e", HUGE_VAL), std::invalid_argument);
}

// What users write parses into typed values, prints back canonically, and the canonical text
// parses into the same effects (bit for bit).
TEST(EffectText, RoundTripsThroughTheParser) {
  const std::string text =
      "coulomb@2, viscous,cogging@3:period=0.3;harmonics=2,stribeck@1/2:velocity=0.05,"
      "drift@1:t0=-2.5;span=40,offset,spring@2";
  const auto effects = ParseEffectList(text);
  ASSERT_EQ(effects.size(), 7u);
  const std::string canonical = ToString(effects);
  EXPECT_EQ(canonical,
            "coulomb@2,viscous,cogging@3:harmonics=2;period=0.29999999999999999,"
            "stribeck@1/2:velocity=0.050000000000000003,drift@1:span=40;t0=-2.5,offset,spring@2");
  const auto again = ParseEffectList(canonical);
  ASSERT_EQ(again.size(), effects.size());
  for (size_t i = 0; i < effects.size(); ++i) {
    EXPECT_EQ(again[i].name, effects[i].name);
    EXPECT_EQ(again[i].joints, effects[i].joints);
    EXPECT_EQ(again[i].params, effects[i].params);
    EXPECT_EQ(MakeEffect(again[i].name, again[i].params)->parameters(),
              MakeEffect(effects[i].name, effects[i].params)->parameters());
  }
}

TEST(ModelLabelText, RoundTripsAndReadsTheShortForms) {
  const ModelSpec spec = ParseModelLabel("pol+fri + coulomb@2,cogging@3:period=0.3");
  EXPECT_EQ(spec.base, BaseModel::kPol);
  EXPECT_TRUE(spec.friction);
  ASSERT_EQ(spec.effects.size(), 2u);
  EXPECT_EQ(ToString(spec.effects), ToString(ParseEffectList("coulomb@2,cogging@3:period=0.3")));
  // ModelLabel writes what ParseModelLabel reads.
  const ModelSpec again = ParseModelLabel(ModelLabel(spec));
  EXPECT_EQ(ModelLabel(again), ModelLabel(spec));
  EXPECT_EQ(ModelLabel(ParseModelLabel("lag")), "lag");
  EXPECT_EQ(ModelLabel(ParseModelLabel("rbf+fri")), "rbf+fri");
  // Without spaces, with or without +fri; a number with an exponent stays in its effect.
  const ModelSpec short_form = ParseModelLabel("motor+coulomb@1:width=1e+1");
  EXPECT_EQ(short_form.base, BaseModel::kMotor);
  EXPECT_FALSE(short_form.friction);
  ASSERT_EQ(short_form.effects.size(), 1u);
  EXPECT_EQ(short_form.effects[0].params.at("width"), 10.0);
  EXPECT_EQ(ParseModelLabel("pol+fri+viscous").effects.size(), 1u);
  // A URDF's torques beside a kernel base: "rbd+" is part of the model, not an effect.
  for (const char* label : {"rbd+pol", "rbd+rbf+fri", "rbd+rbfs + offset",
                            "rbd+motor+fri + coulomb@2", "rbd+fri + coulomb@1"}) {
    const ModelSpec urdf = ParseModelLabel(label);
    EXPECT_EQ(ModelLabel(ParseModelLabel(ModelLabel(urdf))), ModelLabel(urdf)) << label;
    EXPECT_EQ(ModelLabel(urdf), label) << label;
  }
  const ModelSpec beside = ParseModelLabel("rbd+pol+fri + coulomb@2");
  EXPECT_TRUE(beside.rigid_body_features);
  EXPECT_EQ(beside.base, BaseModel::kPol);
  EXPECT_TRUE(beside.friction);
  ASSERT_EQ(beside.effects.size(), 1u);
  EXPECT_EQ(beside.effects[0].joints, std::vector<int>{2});
  // Errors name the part, as the two parsers do.
  auto message = [](const std::string& text) {
    try {
      ParseModelLabel(text);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_EQ(message("pol+"), "model 'pol+': '+' must be followed by 'fri' or effects, e.g. coulomb@2");
  EXPECT_EQ(message("pol+fri+"), "model 'pol+fri+': '+' must be followed by effects, e.g. coulomb@2");
  EXPECT_NE(message("pole+fri").find("unknown base 'pole'"), std::string::npos);
  EXPECT_NE(message("pol+fric").find("unknown effect 'fric'"), std::string::npos);
}

TEST(BaseModelList, EveryBaseParsesByItsNameAndHasADescription) {
  std::vector<BaseModel> seen;
  for (BaseModel base : BaseModels()) {
    EXPECT_EQ(ParseModelSpec(ToString(base)).base, base);
    EXPECT_GT(std::string(Describe(base)).size(), 10u) << ToString(base);
    EXPECT_EQ(std::find(seen.begin(), seen.end(), base), seen.end()) << ToString(base);
    seen.push_back(base);
  }
  EXPECT_EQ(seen.size(), 7u);
}

TEST(EffectDescribe, OnePhrasePerBuiltInEffect) {
  const std::vector<std::pair<std::string, std::string>> expected = {
      {"viscous", "viscous friction"},   {"coulomb", "Coulomb friction"},
      {"stribeck", "Stribeck friction"}, {"offset", "a torque offset"},
      {"spring", "a spring"},            {"drift", "drifting friction"}};
  for (const auto& [name, phrase] : expected) EXPECT_EQ(MakeEffect(name)->Describe(), phrase);
  EXPECT_EQ(MakeEffect("cogging", {{"period", 0.3}})->Describe(), "cogging (period 0.3 rad)");
  EXPECT_EQ(MakeEffect("cogging", {{"period", 0.30360692392959288}})->Describe(),
            "cogging (period 0.304 rad)");
  Suggestion s;
  s.effect = "cogging";
  s.params = {{"period", 0.25}, {"harmonics", 1.0}};
  EXPECT_EQ(DescribeEffect(s), "cogging (period 0.25 rad)");
}

// viscous, Coulomb and offset are what "+fri" adds: the block of FrictionFeatureMap.
TEST(EffectSpannedBy, FrictionEffectsNameTheFrictionBlock) {
  const std::string friction = FrictionFeatureMap(2, 0.01).blocks().front().name;
  for (const std::string& name : kBuiltIn) {
    const auto spanned = MakeEffectPrototype(name)->spanned_by();
    const bool by_friction = name == "viscous" || name == "coulomb" || name == "offset";
    EXPECT_EQ(spanned, by_friction ? std::vector<std::string>{friction}
                                   : std::vector<std::string>{})
        << name;
  }
}

// ---- proposals against values known by construction ------------------------------------------

struct SyntheticJoint {
  Vector q, qd, qdd, t, residual;
};

SyntheticJoint MakeJoint(int m, std::uint64_t seed) {
  std::printf("[ seed     ] %llu\n", static_cast<unsigned long long>(seed));
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, 0.01);
  SyntheticJoint d;
  d.q.resize(m);
  d.qd.resize(m);
  d.qdd.resize(m);
  d.t.resize(m);
  d.residual.resize(m);
  for (int i = 0; i < m; ++i) {
    const double s = 5.0 + 40.0 * i / (m - 1);  // t from 5 s to 45 s
    d.t[i] = s;
    d.q[i] = 1.1 * std::sin(0.4 * s) + 0.3 * std::sin(1.3 * s);
    d.qd[i] = 0.44 * std::cos(0.4 * s) + 0.39 * std::cos(1.3 * s);
    d.qdd[i] = -0.176 * std::sin(0.4 * s) - 0.507 * std::sin(1.3 * s);
    d.residual[i] = noise(rng);
  }
  return d;
}

TEST(EffectProposal, CoggingFindsThePeriodOfTheRipple) {
  SyntheticJoint d = MakeJoint(3000, 11);
  for (int i = 0; i < d.q.size(); ++i) d.residual[i] += 0.05 * std::sin(kTwoPi * d.q[i] / 0.37);
  ResidualContext c(1, d.q, d.qd, d.qdd, d.t, d.residual);
  c.search_ranges["period"] = ParameterRange{0.02, 3.0};
  const auto proposals = MakeEffectPrototype("cogging")->ProposeParameters(c);
  ASSERT_EQ(proposals.size(), 13u);
  const double center = proposals[6].at("period");
  EXPECT_NEAR(center, 0.37, 0.37 * 0.005);
  EXPECT_DOUBLE_EQ(proposals.front().at("period"), center * 0.85);
  EXPECT_DOUBLE_EQ(proposals.back().at("period"), center * 1.15);
  // A search range that excludes the truth cannot find it, and every proposal stays inside
  // the range (the estimate lands at its edge: the grid is one-sided there).
  c.search_ranges["period"] = ParameterRange{1.0, 3.0};
  const auto inside = MakeEffectPrototype("cogging")->ProposeParameters(c);
  ASSERT_FALSE(inside.empty());
  for (const auto& p : inside) {
    EXPECT_GE(p.at("period"), 1.0);
    EXPECT_LE(p.at("period"), 3.0);
  }
}

// A period is tried only where q sweeps two of them; and where a residual has a larger
// periodogram peak of its own (a model far from the log), the evidence chooses among peaks.
TEST(EffectProposal, CoggingPeriodsThatTheMotionResolvesChosenByEvidence) {
  SyntheticJoint d = MakeJoint(3000, 13);
  const double sweep = d.q.maxCoeff() - d.q.minCoeff();
  for (int i = 0; i < d.q.size(); ++i) {
    d.residual[i] += 0.3 * std::sin(kTwoPi * d.q[i] / 0.9) + 0.05 * std::sin(kTwoPi * d.q[i] / 0.23);
  }
  ResidualContext c(1, d.q, d.qd, d.qdd, d.t, d.residual);
  c.search_ranges["period"] = ParameterRange{0.02, 3.0};
  // No score: the largest peak (0.9 rad), and no period beyond half the sweep.
  const auto largest = MakeEffectPrototype("cogging")->ProposeParameters(c);
  ASSERT_EQ(largest.size(), 13u);
  EXPECT_NEAR(largest[6].at("period"), 0.9, 0.9 * 0.01);
  for (const auto& p : largest) EXPECT_LE(p.at("period"), 0.5 * sweep + 1e-12);
  // A score that prefers the ripple at 0.23 rad: the proposals centre on it.
  int calls = 0;
  c.score = [&calls](const EffectParameters& p) {
    ++calls;
    return -std::abs(std::log(p.at("period") / 0.23));
  };
  const auto scored = MakeEffectPrototype("cogging")->ProposeParameters(c);
  ASSERT_EQ(scored.size(), 13u);
  // (its peak is shifted by the larger sinusoid's leakage; the grid around it holds 0.23)
  EXPECT_NEAR(scored[6].at("period"), 0.23, 0.23 * 0.05);
  double nearest = HUGE_VAL;
  for (const auto& p : scored) nearest = std::min(nearest, std::abs(p.at("period") - 0.23));
  EXPECT_LT(nearest, 0.23 * 0.0125);
  EXPECT_GE(calls, 2);
  EXPECT_LE(calls, 5);
  // A joint that sweeps less than two of the shortest periods gets no cogging candidate.
  Vector still = Vector::Constant(d.q.size(), 0.4) + 0.005 * d.q / sweep;
  ResidualContext narrow(1, still, d.qd, d.qdd, d.t, d.residual);
  narrow.search_ranges["period"] = ParameterRange{0.02, 3.0};
  EXPECT_TRUE(MakeEffectPrototype("cogging")->ProposeParameters(narrow).empty());
}

TEST(EffectProposal, StribeckVelocitiesAreFractionsOfTheLargestSpeed) {
  const SyntheticJoint d = MakeJoint(500, 12);
  const double top = d.qd.cwiseAbs().maxCoeff();
  ResidualContext c(1, d.q, d.qd, d.qdd, d.t, d.residual);
  const auto proposals = MakeEffectPrototype("stribeck")->ProposeParameters(c);
  ASSERT_EQ(proposals.size(), 4u);
  const double rel[] = {0.02, 0.05, 0.1, 0.2};
  for (int i = 0; i < 4; ++i) {
    EXPECT_EQ(proposals[i].size(), 1u);
    EXPECT_EQ(proposals[i].at("velocity"), rel[i] * top);
  }
}

TEST(EffectProposal, DriftSpansTheLogAndNeedsTime) {
  const SyntheticJoint d = MakeJoint(500, 13);
  ResidualContext c(2, d.q, d.qd, d.qdd, d.t, d.residual);
  const auto proposals = MakeEffectPrototype("drift")->ProposeParameters(c);
  ASSERT_EQ(proposals.size(), 1u);
  EXPECT_EQ(proposals[0].at("t0"), 5.0);
  EXPECT_EQ(proposals[0].at("span"), 40.0);
  const Vector no_time;
  ResidualContext without(2, d.q, d.qd, d.qdd, no_time, d.residual);
  EXPECT_TRUE(MakeEffectPrototype("drift")->ProposeParameters(without).empty());
}

TEST(EffectProposal, EffectsWithoutEstimatedParametersProposeTheirDefaults) {
  const SyntheticJoint d = MakeJoint(100, 14);
  ResidualContext c(1, d.q, d.qd, d.qdd, d.t, d.residual);
  for (const char* name : {"viscous", "coulomb", "offset", "spring"}) {
    const auto proposals = MakeEffectPrototype(name)->ProposeParameters(c);
    ASSERT_EQ(proposals.size(), 1u) << name;
    EXPECT_TRUE(proposals[0].empty()) << name;
  }
}

// ---- the battery on every built-in effect, kernels written out independently ------------------

double Sq(double x) { return x * x; }

struct EffectCase {
  std::string name;
  EffectParameters params;
  // k(a, b) = phi(a)^T phi(b) for joints {1, 2} of N = 2; a, b hold (q, qd, qdd[, t]).
  std::function<double(const Vector&, const Vector&)> kernel;
};

std::vector<EffectCase> EffectCases() {
  auto per_joint = [](std::function<double(const Vector&, const Vector&, int)> f) {
    return [f](const Vector& a, const Vector& b) { return f(a, b, 0) + f(a, b, 1); };
  };
  const double w = 0.3, v = 0.5, p = 0.7, t0 = 0.25, span = 3.0;
  auto stribeck = [=](double qd) { return std::exp(-Sq(qd / v)) * std::tanh(qd / w); };
  return {
      {"viscous", {}, per_joint([](const Vector& a, const Vector& b, int j) {
         return a[2 + j] * b[2 + j];
       })},
      {"coulomb", {{"width", w}}, per_joint([=](const Vector& a, const Vector& b, int j) {
         return std::tanh(a[2 + j] / w) * std::tanh(b[2 + j] / w);
       })},
      {"stribeck", {{"velocity", v}, {"width", w}},
       per_joint([=](const Vector& a, const Vector& b, int j) {
         return stribeck(a[2 + j]) * stribeck(b[2 + j]);
       })},
      {"offset", {}, [](const Vector&, const Vector&) { return 1.0; }},
      // sin x sin y + cos x cos y = cos(x - y), per harmonic.
      {"cogging", {{"period", p}, {"harmonics", 3}},
       per_joint([=](const Vector& a, const Vector& b, int j) {
         double k = 0.0;
         for (int h = 1; h <= 3; ++h) k += std::cos(kTwoPi * h * (a[j] - b[j]) / p);
         return k;
       })},
      {"spring", {}, per_joint([](const Vector& a, const Vector& b, int j) {
         return a[j] * b[j];
       })},
      {"drift", {{"t0", t0}, {"span", span}, {"width", w}},
       per_joint([=](const Vector& a, const Vector& b, int j) {
         const double sa = (a[6] - t0) / span, sb = (b[6] - t0) / span;
         return sa * sb *
                (std::tanh(a[2 + j] / w) * std::tanh(b[2 + j] / w) + a[2 + j] * b[2 + j] + 1.0);
       })},
  };
}

TEST(EffectFeatureMapBattery, EveryBuiltInEffect) {
  for (const EffectCase& c : EffectCases()) {
    SCOPED_TRACE(c.name);
    const EffectFeatureMap map(2, MakeEffect(c.name, c.params));
    testing::BatteryOptions options = testing::CountingBatteryOptions();
    options.reference_kernel = [&c](const Vector& a, const Vector& b, const Vector&) {
      return c.kernel(a, b);
    };
    testing::RunFeatureMapBattery(map, options);
  }
}

// ---- the diagnosis's suggestions parse back into the same effect -------------------------------

// The suggestion's --effects text and its FINDINGS.json entry give back the effect it names,
// on its joint, with its parameters bit for bit.
void ExpectRoundTrip(const Diagnosis& d) {
  const nlohmann::json findings = nlohmann::json::parse(ToJson(d));
  ASSERT_EQ(findings["suggestions"].size(), d.suggestions.size());
  for (size_t i = 0; i < d.suggestions.size(); ++i) {
    const Suggestion& s = d.suggestions[i];
    SCOPED_TRACE(s.spec);
    const auto& js = findings["suggestions"][i];
    EXPECT_EQ(js["spec"].get<std::string>(), s.spec);
    for (const std::string& text : {s.spec, js["spec"].get<std::string>()}) {
      const std::vector<EffectSpec> parsed = ParseEffectList(text);
      ASSERT_EQ(parsed.size(), 1u);
      EXPECT_EQ(parsed[0].name, s.effect);
      EXPECT_EQ(parsed[0].joints, std::vector<int>{s.joint});
      const std::shared_ptr<const Effect> effect = MakeEffect(parsed[0].name, parsed[0].params);
      EXPECT_EQ(effect->parameters(), s.params);
      EXPECT_EQ(effect->Describe(), DescribeEffect(s));
      EXPECT_TRUE((Features(effect, s.joint).array() ==
                   Features(MakeEffect(s.effect, s.params), s.joint).array())
                      .all());
    }
    // The params object of FINDINGS.json holds the same numbers, and is itself accepted.
    EffectParameters from_json;
    for (const auto& [key, value] : js["params"].items()) from_json[key] = value.get<double>();
    EXPECT_EQ(from_json, s.params);
    EXPECT_EQ(MakeEffect(s.effect, from_json)->parameters(), s.params);
  }
}

Diagnosis DiagnoseHidden(sim::HiddenEffect hidden, int joint, const std::string& candidate) {
  sim::HiddenEffectOptions o;
  o.effect = hidden;
  o.joint = joint;
  o.train_duration = 20.0;
  o.seed = 5;
  const auto scenario = sim::MakeHiddenEffectScenario(sim::TwoLinkArm(), o);
  const sim::Dataset& data = scenario.train;
  FittedModel fit = FitModel(ParseModelSpec("pol"), data.X, data.Y, data.t);
  EXPECT_TRUE(fit.summary.IsUsable()) << fit.summary.message;
  DiagnosisOptions options;
  options.candidates = {candidate};
  const Diagnosis d = Diagnose(fit.model, data.X, data.Y, data.t, options);
  std::printf("%s\n%s", scenario.description.c_str(), ToJson(d).c_str());
  return d;
}

TEST(SuggestionText, RoundTripsForEveryEffectWithEstimatedParameters) {
  const std::vector<std::pair<sim::HiddenEffect, std::string>> cases = {
      {sim::HiddenEffect::kCogging, "cogging"},
      {sim::HiddenEffect::kStribeck, "stribeck"},
      {sim::HiddenEffect::kDrift, "drift"}};
  for (const auto& [hidden, name] : cases) {
    SCOPED_TRACE(name);
    const Diagnosis d = DiagnoseHidden(hidden, 2, name);
    ASSERT_FALSE(d.suggestions.empty());
    EXPECT_EQ(d.suggestions.front().effect, name);
    EXPECT_EQ(d.suggestions.front().joint, 2);
    ExpectRoundTrip(d);
  }
}

// ---- a user effect: registered here, its parameter proposed by evidence ------------------------

// A localised disturbance of one joint's torque, e.g. a cable that catches at a position:
// exp(-((q - center) / 0.25)^2). Its one parameter, the center, is found by scoring a grid of
// centers by evidence (ResidualContext::score) and refining around the best.
class BumpEffect : public Effect {
 public:
  static constexpr double kWidth = 0.25;  // rad

  static std::vector<EffectParameter> Parameters() {
    EffectParameter center;
    center.name = "center";
    center.unit = "rad";
    center.default_value = 0.0;
    center.valid = ParameterRange{-10.0, 10.0};
    center.required = true;
    center.description = "joint position of the bump";
    return {center};
  }
  explicit BumpEffect(const EffectParameters& p) : center_(p.at("center")) {}

  std::string name() const override { return "bump"; }
  int num_bases() const override { return 1; }
  void Evaluate(double q, double, double, double, double* out) const override {
    out[0] = std::exp(-Sq((q - center_) / kWidth));
  }
  std::vector<EffectParameter> parameter_info() const override { return Parameters(); }
  EffectParameters parameters() const override { return {{"center", center_}}; }
  std::string Describe() const override {
    return "a bump at " + std::to_string(center_) + " rad";
  }
  std::vector<EffectParameters> ProposeParameters(const ResidualContext& c) const override {
    if (!c.score || c.q.size() == 0) return {};
    const double lo = c.q.minCoeff(), hi = c.q.maxCoeff();
    double best = lo, best_score = -HUGE_VAL;
    const int grid = 41;
    for (int g = 0; g < grid; ++g) {
      const double x = lo + (hi - lo) * g / (grid - 1);
      const double s = c.score({{"center", x}});
      if (s > best_score) best_score = s, best = x;
    }
    // Golden-section refinement on the bracketing grid cells.
    const double step = (hi - lo) / (grid - 1);
    double a = best - step, b = best + step;
    const double r = 0.5 * (std::sqrt(5.0) - 1.0);
    for (int it = 0; it < 30; ++it) {
      const double x1 = b - r * (b - a), x2 = a + r * (b - a);
      if (c.score({{"center", x1}}) > c.score({{"center", x2}})) b = x2; else a = x1;
    }
    ++proposals_;
    return {{{"center", 0.5 * (a + b)}}};
  }
  std::unique_ptr<Effect> Clone() const override { return std::make_unique<BumpEffect>(*this); }

  static int proposals_;

 private:
  double center_;
};
int BumpEffect::proposals_ = 0;

TEST(UserEffect, RegistrationChecksTheEffectAgainstItsDescription) {
  const auto factory = [](const EffectParameters& p) {
    return std::unique_ptr<Effect>(new BumpEffect(p));
  };
  // Registered under another name than the effect gives itself.
  EXPECT_NE(ErrorOf([&] { RegisterEffect("lump", BumpEffect::Parameters(), factory); })
                .find("calls itself 'bump'"),
            std::string::npos);
  // A parameter the effect does not report.
  auto extra = BumpEffect::Parameters();
  extra.push_back(extra[0]);
  extra[1].name = "depth";
  extra[1].required = false;
  EXPECT_NE(ErrorOf([&] { RegisterEffect("bump", extra, factory); }).find("parameter_info()"),
            std::string::npos);
  auto bad_default = BumpEffect::Parameters();
  bad_default[0].default_value = 20.0;
  EXPECT_EQ(ErrorOf([&] { RegisterEffect("bump", bad_default, factory); }),
            "effect 'bump': parameter 'center' expected in [-10, 10] rad, got 20");
  EXPECT_NE(ErrorOf([&] { RegisterEffect("bu mp", BumpEffect::Parameters(), factory); })
                .find("not a valid effect name"),
            std::string::npos);
  EXPECT_NE(ErrorOf([&] { RegisterEffect("coulomb", BumpEffect::Parameters(), factory); })
                .find("already exists"),
            std::string::npos);
}

// The user's effect, once registered, is parsed, built, checked with the registry's words and
// tried by Diagnose with its default options (every registered effect); the diagnosis finds
// the bump's center by the effect's own proposal and suggests it.
TEST(UserEffect, DiagnosisEstimatesItsParameterAndSuggestsIt) {
  RegisterEffect<BumpEffect>("bump");
  EXPECT_EQ(EffectNames().back(), "bump");
  EXPECT_EQ(ErrorOf([] { ParseEffectList("bump@1"); }),
            "effect list 'bump@1', character 1: effect 'bump': parameter 'center' is required "
            "(e.g. bump@1:center=0)");
  ASSERT_EQ(ParseEffectList("bump@1:center=0.4").front().params.at("center"), 0.4);

  sim::HiddenEffectOptions o;
  o.effect = sim::HiddenEffect::kNone;
  o.train_duration = 20.0;
  o.seed = 6;
  auto scenario = sim::MakeHiddenEffectScenario(sim::TwoLinkArm(), o);
  sim::Dataset& data = scenario.train;
  const int joint = 1;
  const double center = 0.4;
  const double size = 0.1 * data.Y.col(joint - 1).cwiseAbs().maxCoeff();
  const BumpEffect truth({{"center", center}});
  for (int i = 0; i < data.X.rows(); ++i) {
    double b = 0.0;
    truth.Evaluate(data.X(i, joint - 1), 0, 0, 0, &b);
    data.Y(i, joint - 1) += size * b;
  }
  FittedModel fit = FitModel(ParseModelSpec("pol"), data.X, data.Y, data.t);
  ASSERT_TRUE(fit.summary.IsUsable()) << fit.summary.message;
  BumpEffect::proposals_ = 0;
  const Diagnosis d = Diagnose(fit.model, data.X, data.Y, data.t);
  std::printf("%s", ToJson(d).c_str());
  EXPECT_EQ(BumpEffect::proposals_, 2);  // once per joint
  ASSERT_FALSE(d.suggestions.empty());
  const Suggestion& top = d.suggestions.front();
  EXPECT_EQ(top.effect, "bump");
  EXPECT_EQ(top.joint, joint);
  EXPECT_GT(top.score, 10.0);
  EXPECT_NEAR(top.params.at("center"), center, 0.02);
  // A refit of pol on this log absorbs much of the bump, but not out of sample: the held-out
  // error falls by more than half.
  EXPECT_LT(top.rms_after, 0.5 * top.rms_before);
  EXPECT_LT(top.residual_rms_after, top.residual_rms_before);
  EXPECT_EQ(DescribeEffect(top).rfind("a bump at 0.", 0), 0u) << DescribeEffect(top);
  ExpectRoundTrip(d);
}

}  // namespace
}  // namespace structgp
