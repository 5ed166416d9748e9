// The Euler-Lagrange kernel GP as a product model ("lagk", "lagk+fri"): FitModel against the
// same steps by hand (FitEulerLagrangeGP's search, then EulerLagrangeGP::Condition), the model
// file round trip (exact and through inducing states, with and without its posterior file),
// the allocation-free one-state prediction of RobotModel, effects of the state and of the
// time, and the clear refusals of what it does not do (online updates, cross-validation); the
// diagnosis loop on lagk.

#include <zlib.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "alloc_counter.h"
#include "temp_files.h"
#include "structgp/core/row_subset.h"
#include "structgp/diagnose/diagnosis.h"
#include "structgp/fit/fit_model.h"
#include "structgp/hyper/euler_lagrange_fit.h"
#include "structgp/io/model_file.h"
#include "structgp/online/online_learner.h"
#include "structgp/sim/hidden_effect.h"

namespace structgp {
namespace {

using Json = nlohmann::json;

// A slow three-link log (30 via points in 20 s, 400 rows) with the hidden effect on joint 2,
// and a 2.5x faster test log.
sim::HiddenEffectScenario ThreeLinkScenario(sim::HiddenEffect effect) {
  sim::HiddenEffectOptions o;
  o.effect = effect;
  o.joint = 2;
  o.seed = 5;
  o.train_duration = 20.0;
  o.test_duration = 5.0;
  o.dt = 0.05;
  o.num_vias = 30;
  return sim::MakeHiddenEffectScenario(sim::ThreeLinkArm(), o);
}

// With Coulomb friction on joint 2.
const sim::HiddenEffectScenario& Scenario() {
  static const sim::HiddenEffectScenario scenario =
      ThreeLinkScenario(sim::HiddenEffect::kCoulomb);
  return scenario;
}

// Small and quick: three sigmas, 150 evidence rows, 60 iterations.
FitOptions QuickOptions() {
  FitOptions o;
  o.euler_lagrange.sigmas = {3.0, 10.0, 30.0};
  o.euler_lagrange.max_iterations = 60;
  o.max_euler_lagrange_evidence_values = 450;
  o.check.enabled = false;
  return o;
}

double Rms(const Matrix& A) { return std::sqrt(A.squaredNorm() / static_cast<double>(A.size())); }

TEST(LagkModel, FitModelEqualsTheStepsByHand) {
  const sim::Dataset& d = Scenario().train;
  const FitOptions options = QuickOptions();
  const FittedModel fit = FitModel(ParseModelSpec("lagk+fri"), d.X, d.Y, Vector(), options);
  ASSERT_TRUE(fit.summary.IsUsable()) << fit.summary.message;
  EXPECT_EQ(fit.model.gp().form(), Form::kEulerLagrange);
  EXPECT_EQ(fit.summary.hyperparameter_rows, 150);
  EXPECT_EQ(fit.summary.model_rows, d.X.rows());

  // By hand: the search on the same 150 rows with friction, then the posterior on every row
  // (400 rows of 3 joints: under the default 800 inducing states, so exact).
  ASSERT_LE(d.X.rows(), 800);
  EulerLagrangeGPOptions o = options.euler_lagrange;
  o.friction = true;
  o.coulomb_width = RobotModelOptions().friction_width;
  o.hyperparameter_rows = 150;
  std::optional<EulerLagrangeGP> twin;
  const EulerLagrangeGPSummary s = FitEulerLagrangeGP(d.X, d.Y, o, &twin);
  ASSERT_EQ(s.status, Status::kOk) << s.message;
  EXPECT_NEAR(fit.summary.final_negative_log_evidence, -s.log_evidence,
              1e-9 * std::abs(s.log_evidence));
  // The summary counts the search of every sigma and starts from the first one's start.
  int iterations = 0, evaluations = 0;
  for (size_t k = 0; k < s.sigmas.size(); ++k) {
    iterations += s.iterations_per_sigma[k];
    evaluations += s.evaluations_per_sigma[k];
  }
  EXPECT_GT(iterations, 0);
  EXPECT_GE(evaluations, iterations);
  EXPECT_EQ(fit.summary.iterations, iterations);
  EXPECT_EQ(fit.summary.num_evaluations, evaluations);
  ASSERT_TRUE(std::isfinite(s.initial_log_evidence));
  EXPECT_NEAR(fit.summary.initial_negative_log_evidence, -s.initial_log_evidence,
              1e-9 * std::abs(s.initial_log_evidence));
  EXPECT_GT(fit.summary.initial_negative_log_evidence, fit.summary.final_negative_log_evidence);
  EXPECT_EQ(fit.summary.BriefReport().find("nan"), std::string::npos) << fit.summary.BriefReport();

  const sim::Dataset& t = Scenario().test;
  Matrix mean, latent_std, twin_mean, twin_var;
  fit.model.PredictRows(t.X, &mean, &latent_std);
  ASSERT_EQ(twin->Predict(t.X, &twin_mean, &twin_var), Status::kOk);
  EXPECT_LT((mean - twin_mean).cwiseAbs().maxCoeff(), 1e-9 * (1.0 + twin_mean.cwiseAbs().maxCoeff()));
  EXPECT_LT((latent_std - twin_var.cwiseSqrt()).cwiseAbs().maxCoeff(),
            1e-7 * (1.0 + latent_std.cwiseAbs().maxCoeff()));
  EXPECT_NEAR(fit.model.gp().LogMarginalLikelihood(), twin->LogMarginalLikelihood(),
              1e-9 * std::abs(twin->LogMarginalLikelihood()));

  // It learned the arm: the fast log, unseen, within half the torques' RMS on every joint (a
  // model that learned nothing is at 100%; measured 6.5%, 41% and 15% with the evidence on 150 rows;
  // the accuracy itself is measured in docs/generalisation.md).
  for (int j = 0; j < 3; ++j) {
    EXPECT_LT(Rms(mean.col(j) - t.Y.col(j)), 0.5 * Rms(t.Y.col(j))) << "joint " << j + 1;
  }

  // The report and the JSON name the form, the kernel's parameters and every joint's noise.
  const std::string report = FitReport(fit.model, fit.summary);
  EXPECT_NE(report.find("Euler-Lagrange kernel"), std::string::npos) << report;
  EXPECT_NE(report.find("log_weight_potential_3"), std::string::npos) << report;
  EXPECT_NE(report.find("log_friction_std_2"), std::string::npos) << report;
  const std::string json = ToJson(fit.model, fit.summary);
  EXPECT_NE(json.find("\"euler_lagrange\""), std::string::npos) << json;
}

// What the library's search says of a part the log does not excite reaches the user: a log
// whose accelerations are zero to rounding leaves link 1's kinetic energy (I_1 qdd_1) unseen,
// and FitModel's summary (what `structgp fit` prints) warns, naming it.
TEST(LagkModel, TheFitWarnsOfAPartTheLogDoesNotExcite) {
  const sim::Dataset& d = Scenario().train;
  const int n = 3, m = 120;
  Matrix X = d.X.topRows(m);
  for (Eigen::Index r = 0; r < m; ++r) {
    for (int j = 0; j < n; ++j) X(r, 2 * n + j) = 1e-15 * ((r + j) % 3 - 1.0);
  }
  const FittedModel fit = FitModel(ParseModelSpec("lagk"), X, d.Y.topRows(m), Vector(),
                                   QuickOptions());
  ASSERT_TRUE(fit.summary.IsUsable()) << fit.summary.message;
  int naming = 0;
  for (const std::string& warning : fit.summary.warnings) {
    naming += warning.find("kinetic energy of link 1 ") != std::string::npos ? 1 : 0;
  }
  EXPECT_EQ(naming, 1) << FitReport(fit.model, fit.summary);
  // The same log with its accelerations: no such warning.
  const FittedModel excited = FitModel(ParseModelSpec("lagk"), d.X.topRows(m), d.Y.topRows(m),
                                       Vector(), QuickOptions());
  ASSERT_TRUE(excited.summary.IsUsable()) << excited.summary.message;
  for (const std::string& warning : excited.summary.warnings) {
    EXPECT_EQ(warning.find("do not excite"), std::string::npos) << warning;
  }
}

TEST(LagkModel, ModelFileRoundTripsExactAndThroughInducingStates) {
  const sim::Dataset& d = Scenario().train;
  const sim::Dataset& t = Scenario().test;
  for (int inducing : {0, 60}) {
    FitOptions options = QuickOptions();
    options.method = HyperparameterMethod::kFixed;
    options.model.batch.inducing_states = inducing;
    const FittedModel fit = FitModel(ParseModelSpec("lagk"), d.X, d.Y, Vector(), options);
    ASSERT_TRUE(fit.summary.IsUsable()) << fit.summary.message;
    const EulerLagrangeGP& gp = *fit.model.gp().euler_lagrange();
    EXPECT_EQ(gp.dtc(), inducing > 0);
    if (inducing > 0) {
      EXPECT_EQ(gp.states().rows(), inducing);
      // The states are the ones that cover the data (FarthestStateRows), not a time stride.
      EXPECT_EQ(gp.states(), SelectRows(d.X, FarthestStateRows(d.X, inducing)));
    }
    const RobotModel loaded = ParseModelFile(ModelFileText(fit.model), "lagk.json");
    EXPECT_EQ(loaded.gp().form(), Form::kEulerLagrange);
    Matrix m1, s1, m2, s2;
    fit.model.PredictRows(t.X, &m1, &s1);
    loaded.PredictRows(t.X, &m2, &s2);
    EXPECT_EQ(m1, m2) << "inducing " << inducing;
    EXPECT_EQ(s1, s2) << "inducing " << inducing;
    EXPECT_EQ(fit.model.gp().LogMarginalLikelihood(), loaded.gp().LogMarginalLikelihood());
    // Loaded on three workers (400 rows: four blocks of the DTC's accumulation): they reach
    // the posterior, and it is the same bit for bit.
    LoadOptions three;
    three.num_threads = 3;
    const RobotModel threaded = ParseModelFile(ModelFileText(fit.model), "lagk.json", three);
    EXPECT_EQ(threaded.options().batch.num_threads, 3);
    Matrix m3, s3;
    threaded.PredictRows(t.X, &m3, &s3);
    EXPECT_EQ(m3, m1) << "inducing " << inducing;
    EXPECT_EQ(s3, s1) << "inducing " << inducing;
    LoadOptions none;
    none.num_threads = 0;
    EXPECT_THROW(ParseModelFile(ModelFileText(fit.model), "lagk.json", none),
                 std::invalid_argument);
  }
}

// The posterior file (io/model_file.h): a lagk model through inducing states saved with it
// loads the factors of its pass over the rows from it, to the fitted model's predictions bit
// for bit; a posterior file that is damaged, of another model file or missing is not used
// (the note says why) and the posterior is computed from the rows, to the same predictions.
TEST(LagkModel, PosteriorFileGivesTheSamePosteriorWithoutThePassOverTheRows) {
  const sim::Dataset& d = Scenario().train;
  const sim::Dataset& t = Scenario().test;
  FitOptions options = QuickOptions();
  options.method = HyperparameterMethod::kFixed;
  options.model.batch.inducing_states = 60;
  const FittedModel fit = FitModel(ParseModelSpec("lagk+fri"), d.X, d.Y, Vector(), options);
  ASSERT_TRUE(fit.summary.IsUsable()) << fit.summary.message;
  Matrix m0, s0;
  fit.model.PredictRows(t.X, &m0, &s0);
  const int N = fit.model.num_joints();
  const Eigen::Index pn = 60 * N;

  testing::TempDir dir("posterior_file");
  const std::string path = dir.File("lagk.json");
  const std::string posterior = PosteriorFilePath(path);
  EXPECT_EQ(posterior, path + ".posterior");
  SaveModel(path, fit.model);
  const std::string bytes = testing::ReadFile(posterior);
  const std::string checksum = Json::parse(testing::ReadFile(path)).at("checksum");
  // Header, log p(Y), alpha, the factor's lower triangle, CRC-32.
  const size_t header = 24 + 4 + 4 + checksum.size() + 8;
  EXPECT_EQ(bytes.size(),
            header + 8 * (1 + static_cast<size_t>(pn) + static_cast<size_t>(pn * (pn + 1) / 2)) +
                4);
  EXPECT_EQ(bytes, PosteriorFileBytes(fit.model));

  struct Loaded {
    Matrix mean, std;
    LoadSummary summary;
    double log_evidence = 0.0;
  };
  auto load = [&](bool posterior_file = true) {
    Loaded l;
    LoadOptions o;
    o.posterior_file = posterior_file;
    const RobotModel model = LoadModel(path, o, &l.summary);
    model.PredictRows(t.X, &l.mean, &l.std);
    l.log_evidence = model.gp().LogMarginalLikelihood();
    return l;
  };
  const Loaded read = load();
  EXPECT_TRUE(read.summary.posterior_file_read);
  EXPECT_EQ(read.summary.posterior_file_note, "");
  EXPECT_EQ(read.mean, m0);
  EXPECT_EQ(read.std, s0);
  EXPECT_EQ(read.log_evidence, fit.model.gp().LogMarginalLikelihood());
  const Loaded computed = load(false);
  EXPECT_FALSE(computed.summary.posterior_file_read);
  EXPECT_EQ(computed.mean, m0);

  // The factors are read, not computed again: a file whose alpha is changed (with its CRC
  // made to match) changes the predictions.
  auto with_crc = [](std::string b) {
    const uLong crc = crc32(crc32(0L, Z_NULL, 0), reinterpret_cast<const Bytef*>(b.data()),
                            static_cast<uInt>(b.size() - 4));
    const uint32_t c = static_cast<uint32_t>(crc);
    std::memcpy(&b[b.size() - 4], &c, 4);
    return b;
  };
  auto set_double = [](std::string* b, size_t offset, double value) {
    std::memcpy(&(*b)[offset], &value, 8);
  };
  std::string changed = bytes;
  set_double(&changed, header + 8, 1.0);  // alpha[0]
  ASSERT_TRUE(testing::WriteFile(posterior, with_crc(changed)));
  const Loaded altered = load();
  EXPECT_TRUE(altered.summary.posterior_file_read);
  EXPECT_NE(altered.mean, m0);
  EXPECT_EQ(altered.std, s0);  // the variance does not use alpha

  // Files that are not used, each with its note; the posterior is then computed from the rows.
  auto expect_not_used = [&](const std::string& file_bytes, const std::string& note) {
    SCOPED_TRACE(note);
    ASSERT_TRUE(testing::WriteFile(posterior, file_bytes));
    const Loaded l = load();
    EXPECT_FALSE(l.summary.posterior_file_read);
    EXPECT_NE(l.summary.posterior_file_note.find(note), std::string::npos)
        << l.summary.posterior_file_note;
    EXPECT_EQ(l.mean, m0);
    EXPECT_EQ(l.std, s0);
  };
  std::string flipped = bytes;
  flipped[header + 8 * 100] ^= 0x10;
  expect_not_used(flipped, "CRC-32");
  expect_not_used(bytes.substr(0, bytes.size() / 2), "truncated");
  expect_not_used(bytes + "x", "after its end");
  expect_not_used("a text file\n", "not a structgp posterior file");
  std::string other_version = bytes;
  other_version[24] = 7;
  expect_not_used(other_version, "version 7");
  // B >= I: a diagonal entry of its factor below 1 is not a posterior's (the CRC matching).
  std::string small_diagonal = bytes;
  set_double(&small_diagonal, header + 8 * (1 + static_cast<size_t>(pn)), 0.5);  // B's L(0, 0)
  expect_not_used(with_crc(small_diagonal), "not those of a posterior");
  // The posterior file of another fit (other rows): its checksum is another model file's.
  const FittedModel other = FitModel(ParseModelSpec("lagk+fri"), d.X.topRows(300),
                                     d.Y.topRows(300), Vector(), options);
  ASSERT_TRUE(other.summary.IsUsable()) << other.summary.message;
  expect_not_used(PosteriorFileBytes(other.model), "written for another model file");

  // Saved without it, or as a model that has none (exact): no posterior file is left.
  SaveOptions without;
  without.posterior_file = false;
  ASSERT_TRUE(testing::WriteFile(posterior, bytes));
  SaveModel(path, fit.model, without);
  EXPECT_FALSE(std::filesystem::exists(posterior));
  SaveModel(path, fit.model);
  EXPECT_TRUE(std::filesystem::exists(posterior));
  options.model.batch.inducing_states = 0;
  const FittedModel exact = FitModel(ParseModelSpec("lagk+fri"), d.X.topRows(100),
                                     d.Y.topRows(100), Vector(), options);
  ASSERT_TRUE(exact.summary.IsUsable()) << exact.summary.message;
  EXPECT_EQ(PosteriorFileBytes(exact.model), "");
  SaveModel(path, exact.model);
  EXPECT_FALSE(std::filesystem::exists(posterior));
  LoadSummary summary;
  LoadModel(path, LoadOptions(), &summary);
  EXPECT_FALSE(summary.posterior_file_read);
  EXPECT_EQ(summary.posterior_file_note, "");
}

// Effects of the state ("lagk+fri + coulomb@2,offset@3"): fitted, saved and loaded with the
// same predictions; the effect features change the model (the predictions differ from
// lagk+fri's at the same kernel hyper-parameters).
TEST(LagkModel, TakesEffectsOfTheStateThroughFitAndModelFile) {
  const sim::Dataset& d = Scenario().train;
  const sim::Dataset& t = Scenario().test;
  FitOptions options = QuickOptions();
  options.method = HyperparameterMethod::kFixed;
  const ModelSpec spec = ParseModelLabel("lagk+fri+coulomb@2,offset@3");
  const FittedModel fit = FitModel(spec, d.X, d.Y, Vector(), options);
  ASSERT_TRUE(fit.summary.IsUsable()) << fit.summary.message;
  ASSERT_NE(fit.model.effect_map(), nullptr);
  EXPECT_EQ(fit.model.effect_prior_variance().size(), fit.model.effect_map()->dim());
  const RobotModel loaded = ParseModelFile(ModelFileText(fit.model), "lagk_effects.json");
  Matrix m1, s1, m2, s2;
  fit.model.PredictRows(t.X, &m1, &s1);
  loaded.PredictRows(t.X, &m2, &s2);
  EXPECT_EQ(m1, m2);
  EXPECT_EQ(s1, s2);
  const FittedModel plain = FitModel(ParseModelSpec("lagk+fri"), d.X, d.Y, Vector(), options);
  ASSERT_TRUE(plain.summary.IsUsable()) << plain.summary.message;
  Matrix m3;
  plain.model.PredictRows(t.X, &m3);
  EXPECT_GT((m1 - m3).cwiseAbs().maxCoeff(), 1e-6);
  EXPECT_NE(FitReport(fit.model, fit.summary).find("log_effect_scale_3"), std::string::npos);
}

// The diagnosis loop on lagk: the hidden Coulomb friction of joint 2 is named on joint 2 and
// nothing else is suggested; adding it lowers joint 2's error on the fast log, unseen. On the
// same arm without a hidden effect nothing is suggested.
TEST(LagkModel, DiagnosisNamesTheHiddenFrictionAndNothingElse) {
  const sim::Dataset& d = Scenario().train;
  const sim::Dataset& t = Scenario().test;
  // One sigma: four fits and two diagnoses stay quick (also under the sanitizers).
  FitOptions options = QuickOptions();
  options.euler_lagrange.sigmas = {10.0};
  const FittedModel before = FitModel(ParseModelSpec("lagk"), d.X, d.Y, Vector(), options);
  ASSERT_TRUE(before.summary.IsUsable()) << before.summary.message;
  const Diagnosis dx = Diagnose(before.model, d.X, d.Y, d.t);
  ASSERT_EQ(dx.status, DiagnosisStatus::kOk) << dx.message;
  EXPECT_NE(dx.features.find("Euler-Lagrange"), std::string::npos) << dx.features;
  ASSERT_FALSE(dx.suggestions.empty());
  EXPECT_EQ(dx.suggestions[0].effect, "coulomb");
  EXPECT_EQ(dx.suggestions[0].joint, 2);
  for (const Suggestion& s : dx.suggestions) EXPECT_EQ(s.joint, 2) << s.spec;

  ModelSpec spec = ParseModelSpec("lagk");
  spec.effects = ParseEffectList(dx.suggestions[0].spec);
  const FittedModel after = FitModel(spec, d.X, d.Y, Vector(), options);
  ASSERT_TRUE(after.summary.IsUsable()) << after.summary.message;
  Matrix mb, ma;
  before.model.PredictRows(t.X, &mb);
  after.model.PredictRows(t.X, &ma);
  EXPECT_LT(Rms(ma.col(1) - t.Y.col(1)), 0.8 * Rms(mb.col(1) - t.Y.col(1)));

  const sim::HiddenEffectScenario clean = ThreeLinkScenario(sim::HiddenEffect::kNone);
  const FittedModel plain =
      FitModel(ParseModelSpec("lagk"), clean.train.X, clean.train.Y, Vector(), options);
  ASSERT_TRUE(plain.summary.IsUsable()) << plain.summary.message;
  const Diagnosis none = Diagnose(plain.model, clean.train.X, clean.train.Y, clean.train.t);
  ASSERT_EQ(none.status, DiagnosisStatus::kOk) << none.message;
  EXPECT_TRUE(none.suggestions.empty()) << none.suggestions[0].spec;
}

// A friction that drifts with time on joint 2 (the three-link arm): the diagnosis of lagk on
// the training log names a drift on joint 2; lagk + that drift fits with the times (FitModel),
// saves and loads with the same predictions, and predicts joint 2 of the fast log, unseen,
// better than lagk alone; its diagnosis then names no drift again.
TEST(LagkModel, TakesTimeEffectsThroughFitModelFileAndDiagnosis) {
  const sim::HiddenEffectScenario drift = ThreeLinkScenario(sim::HiddenEffect::kDrift);
  const sim::Dataset& d = drift.train;
  const sim::Dataset& t = drift.test;
  FitOptions options = QuickOptions();
  options.euler_lagrange.sigmas = {10.0};
  const FittedModel before = FitModel(ParseModelSpec("lagk"), d.X, d.Y, d.t, options);
  ASSERT_TRUE(before.summary.IsUsable()) << before.summary.message;
  const Diagnosis dx = Diagnose(before.model, d.X, d.Y, d.t);
  ASSERT_EQ(dx.status, DiagnosisStatus::kOk) << dx.message;
  const Suggestion* named = nullptr;
  for (const Suggestion& s : dx.suggestions) {
    if (s.effect == "drift" && s.joint == 2) named = &s;
  }
  ASSERT_NE(named, nullptr) << (dx.suggestions.empty() ? "no suggestion" : dx.suggestions[0].spec);

  ModelSpec spec = ParseModelSpec("lagk");
  spec.effects = ParseEffectList(named->spec);
  const FittedModel after = FitModel(spec, d.X, d.Y, d.t, options);
  ASSERT_TRUE(after.summary.IsUsable()) << after.summary.message;
  EXPECT_TRUE(after.model.uses_time());
  EXPECT_EQ(after.model.input_dim(), 3 * 3 + 1);
  const Matrix Xt = ModelInputs(after.model, t.X, t.t);
  Matrix mb, ma, sa;
  before.model.PredictRows(t.X, &mb);
  after.model.PredictRows(Xt, &ma, &sa);
  // (0.22 -> 0.18 here; lagk with the true drift gets the same 0.18: the rest is its
  // extrapolation to the faster motion.)
  EXPECT_LT(Rms(ma.col(1) - t.Y.col(1)), 0.9 * Rms(mb.col(1) - t.Y.col(1)));
  // Without the times the inputs are refused by name.
  EXPECT_THROW(ModelInputs(after.model, t.X, Vector()), std::invalid_argument);

  const RobotModel loaded = ParseModelFile(ModelFileText(after.model), "lagk_drift.json");
  EXPECT_TRUE(loaded.uses_time());
  Matrix ml, sl;
  loaded.PredictRows(Xt, &ml, &sl);
  EXPECT_EQ(ma, ml);
  EXPECT_EQ(sa, sl);

  const Diagnosis again = Diagnose(after.model, ModelInputs(after.model, d.X, d.t), d.Y, d.t);
  ASSERT_EQ(again.status, DiagnosisStatus::kOk) << again.message;
  for (const Suggestion& s : again.suggestions) EXPECT_NE(s.effect, "drift") << s.spec;
}

TEST(LagkModel, OneStatePredictionAllocatesNothingAndMatchesTheRows) {
  const sim::Dataset& d = Scenario().train;
  FitOptions options = QuickOptions();
  options.method = HyperparameterMethod::kFixed;
  options.model.batch.inducing_states = 50;
  const FittedModel fit = FitModel(ParseModelSpec("lagk+fri"), d.X, d.Y, Vector(), options);
  ASSERT_TRUE(fit.summary.IsUsable()) << fit.summary.message;
  const RobotModel& model = fit.model;
  Matrix rows_mean, rows_std;
  model.PredictRows(d.X.topRows(5), &rows_mean, &rows_std);
  RobotModel::Workspace w = model.MakeWorkspace();
  Vector x(9), mean(3), lv(3), nv(3);
  const Vector noise = model.gp().euler_lagrange()->hyperparameters().noise_std;
  for (int s = 0; s < 5; ++s) {
    x = d.X.row(s).transpose();
    std::size_t allocations = 0;
    {
      testing::AllocationCounter counter;
      ASSERT_EQ(model.PredictWithVariance(x, mean, lv, nv, w), Status::kOk);
      allocations = counter.count();
    }
    if (testing::CountsEveryAllocation()) {
      EXPECT_EQ(allocations, 0u);
    }
    EXPECT_LT((mean - rows_mean.row(s).transpose()).cwiseAbs().maxCoeff(), 1e-12);
    EXPECT_LT((lv.cwiseSqrt() - rows_std.row(s).transpose()).cwiseAbs().maxCoeff(), 1e-12);
    EXPECT_LT((nv - lv - noise.cwiseAbs2()).cwiseAbs().maxCoeff(), 1e-12);
  }
  x[0] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(model.Predict(x, mean, w), Status::kInvalidInput);
}

TEST(LagkModel, RefusesWhatItDoesNotDoWithAClearError) {
  const sim::Dataset& d = Scenario().train;
  auto message = [](auto&& call) {
    try {
      call();
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no exception");
  };
  FitOptions options = QuickOptions();
  options.method = HyperparameterMethod::kFixed;
  FittedModel fit = FitModel(ParseModelSpec("lagk"), d.X, d.Y, Vector(), options);
  ASSERT_TRUE(fit.summary.IsUsable()) << fit.summary.message;
  EXPECT_NE(message([&] { OnlineLearnerOptionsFor(fit.model); }).find("feature map"),
            std::string::npos);
  EXPECT_EQ(fit.model.mutable_gp().Add(d.X.row(0).transpose(), d.Y.row(0).transpose()),
            Status::kInvalidInput);
  options.method = HyperparameterMethod::kCrossValidation;
  EXPECT_NE(message([&] { FitModel(ParseModelSpec("lagk"), d.X, d.Y, Vector(), options); })
                .find("cross-validation is not available"),
            std::string::npos);
  // A model file whose stored states do not fit the model is refused by name.
  std::string text = ModelFileText(fit.model);
  RobotModelState state = fit.model.State();
  state.inducing = Matrix::Zero(4, 5);
  EXPECT_NE(message([&] { RobotModel::FromState(state); }).find("inducing"), std::string::npos);
  state.inducing.resize(0, 0);
  state.form = Form::kFunctionSpace;
  EXPECT_NE(message([&] { RobotModel::FromState(state); }).find("do not go together"),
            std::string::npos);
}

}  // namespace
}  // namespace structgp
