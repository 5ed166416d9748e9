// Per-joint hyper-parameters (Hyperparameters::per_output, FitOptions::per_joint): each joint
// is its own Gaussian process with its own prior and noise. Checked against independent
// references: one single-output GaussianProcess per column fitted by hand (weight space,
// function space and a kernel without a finite map), the weight-space form against the kernel
// form, online additions against the batch fit, the per-joint workflow against each joint's
// search assembled by hand from the lower layers, the model file against the model it came from.
// Also: the real-time path allocates nothing, the joint's own noise is recovered where a shared
// ratio of prior to noise cannot serve two joints, and the models whose joints share their
// parameters refuse per-joint sets.

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "alloc_counter.h"
#include "demo_scenario.h"
#include "structgp/diagnose/diagnosis.h"
#include "structgp/diagnose/diagnosis_loop.h"
#include "structgp/feature/feature_hyperparameters.h"
#include "structgp/fit/fit_check.h"
#include "structgp/fit/fit_model.h"
#include "structgp/hyper/evidence.h"
#include "structgp/hyper/marginal_likelihood.h"
#include "structgp/io/model_file.h"
#include "structgp/kernel/kernel_hyperparameters.h"
#include "structgp/model/sufficient_statistics.h"
#include "structgp/online/replay.h"
#include "structgp/sim/hidden_effect.h"

namespace structgp {
namespace {

using testing::Spec;

const sim::HiddenEffectScenario& Scenario() { return testing::DemoScenario(); }

Matrix EveryKth(const Matrix& A, int k) {
  Matrix out((A.rows() + k - 1) / k, A.cols());
  for (Eigen::Index i = 0; i < out.rows(); ++i) out.row(i) = A.row(i * k);
  return out;
}

// Two sets for the two joints of `shared` (one output scale each), far apart.
std::vector<Hyperparameters> TwoSets(const Hyperparameters& shared) {
  std::vector<Hyperparameters> sets(2, shared);
  for (int j = 0; j < 2; ++j) {
    Hyperparameters& h = sets[static_cast<size_t>(j)];
    h.log_output_scale = Vector::Constant(1, j == 0 ? std::log(2.0) : std::log(0.5));
    h.log_noise_std = j == 0 ? std::log(0.03) : std::log(0.2);
    if (h.shape.size() > 0) h.shape.array() += j == 0 ? 0.3 : -0.4;
    if (h.log_block_scale.size() > 0) h.log_block_scale[0] += j == 0 ? 0.5 : -0.5;
  }
  return sets;
}

struct Prediction {
  Matrix mean, latent, noisy;
};

Prediction PredictAll(const GaussianProcess& gp, const Matrix& X) {
  const int P = gp.num_outputs();
  Prediction p{Matrix(X.rows(), P), Matrix(X.rows(), P), Matrix(X.rows(), P)};
  Vector m(P), lv(P), nv(P);
  for (Eigen::Index i = 0; i < X.rows(); ++i) {
    EXPECT_EQ(gp.PredictWithVariance(X.row(i).transpose(), m, lv, nv), Status::kOk);
    p.mean.row(i) = m.transpose();
    p.latent.row(i) = lv.transpose();
    p.noisy.row(i) = nv.transpose();
  }
  return p;
}

void ExpectClose(const Matrix& a, const Matrix& b, double relative, const std::string& what) {
  ASSERT_EQ(a.rows(), b.rows());
  ASSERT_EQ(a.cols(), b.cols());
  const double scale = std::max(1e-300, b.cwiseAbs().maxCoeff());
  EXPECT_LE((a - b).cwiseAbs().maxCoeff(), relative * scale) << what;
}

// Each column of the per-output model equals a single-output model of that column alone.
void ExpectEqualsOneModelPerOutput(const GaussianProcess& per_output,
                                   const std::vector<GaussianProcess>& references,
                                   const Matrix& Xtest, double relative) {
  const Prediction p = PredictAll(per_output, Xtest);
  double evidence = 0.0;
  for (size_t j = 0; j < references.size(); ++j) {
    const Prediction r = PredictAll(references[j], Xtest);
    const auto k = static_cast<Eigen::Index>(j);
    ExpectClose(p.mean.col(k), r.mean, relative, "mean of output " + std::to_string(j));
    ExpectClose(p.latent.col(k), r.latent, relative, "latent variance " + std::to_string(j));
    ExpectClose(p.noisy.col(k), r.noisy, relative, "noisy variance " + std::to_string(j));
    evidence += references[j].LogMarginalLikelihood();
  }
  EXPECT_NEAR(per_output.LogMarginalLikelihood(), evidence, 1e-9 * std::abs(evidence));
}

TEST(PerJointGaussianProcess, EachOutputEqualsItsOwnModelInEveryForm) {
  const sim::Dataset& d = Scenario().train;
  const Matrix X = EveryKth(d.X, 10);  // 400 rows > D = 137: the weight space is possible
  const Matrix Y = EveryKth(d.Y, 10);
  const Matrix Xtest = EveryKth(Scenario().test.X, 40);
  const RobotModel layout(Spec("pol+fri"), 2);
  const auto& map = layout.feature_map();
  Hyperparameters hyper = DefaultHyperparameters(*map, 2);
  hyper.per_output = TwoSets(hyper);

  for (Form form : {Form::kWeightSpace, Form::kFunctionSpace}) {
    SCOPED_TRACE(ToString(form));
    GaussianProcess per_output(map, hyper, 2, form);
    ASSERT_TRUE(per_output.per_output());
    ASSERT_EQ(per_output.Fit(X, Y), Status::kOk);
    EXPECT_EQ(per_output.form(), form);
    EXPECT_EQ(per_output.weight_space(), nullptr);
    std::vector<GaussianProcess> references;
    for (int j = 0; j < 2; ++j) {
      references.emplace_back(map, hyper.per_output[static_cast<size_t>(j)], 1, form);
      ASSERT_EQ(references.back().Fit(X, Y.col(j)), Status::kOk);
    }
    ExpectEqualsOneModelPerOutput(per_output, references, Xtest, 1e-9);
  }

  // The two forms of the same per-output model: the same posterior.
  GaussianProcess weights(map, hyper, 2, Form::kWeightSpace);
  GaussianProcess kernel(map, hyper, 2, Form::kFunctionSpace);
  ASSERT_EQ(weights.Fit(X, Y), Status::kOk);
  ASSERT_EQ(kernel.Fit(X, Y), Status::kOk);
  const Prediction a = PredictAll(weights, Xtest), b = PredictAll(kernel, Xtest);
  ExpectClose(a.mean, b.mean, 1e-6, "mean, weight space vs function space");
  ExpectClose(a.latent, b.latent, 1e-5, "latent variance, weight space vs function space");
  EXPECT_NEAR(weights.LogMarginalLikelihood(), kernel.LogMarginalLikelihood(),
              1e-6 * std::abs(kernel.LogMarginalLikelihood()));

  // A set per output really is used: the shared set gives other predictions.
  Hyperparameters shared = hyper;
  shared.per_output.clear();
  GaussianProcess one(map, shared, 2, Form::kWeightSpace);
  ASSERT_EQ(one.Fit(X, Y), Status::kOk);
  EXPECT_GT((PredictAll(one, Xtest).noisy - a.noisy).cwiseAbs().maxCoeff(), 1e-3);
}

TEST(PerJointGaussianProcess, KernelWithoutAFiniteMapEqualsItsOwnModels) {
  const sim::Dataset& d = Scenario().train;
  const Matrix X = EveryKth(d.X, 20);
  const Matrix Y = EveryKth(d.Y, 20);
  const RobotModel layout(Spec("rbf"), 2);
  const Kernel& k = *layout.kernel();
  Hyperparameters hyper = DefaultHyperparameters(k, 2);
  hyper.per_output = TwoSets(hyper);
  GaussianProcess per_output(k, hyper, 2);
  ASSERT_EQ(per_output.Fit(X, Y), Status::kOk);
  std::vector<GaussianProcess> references;
  for (int j = 0; j < 2; ++j) {
    references.emplace_back(k, hyper.per_output[static_cast<size_t>(j)], 1);
    ASSERT_EQ(references.back().Fit(X, Y.col(j)), Status::kOk);
  }
  ExpectEqualsOneModelPerOutput(per_output, references, EveryKth(Scenario().test.X, 40), 1e-9);
}

TEST(PerJointGaussianProcess, OnlineAdditionsEqualTheBatchFitAndAllocateNothing) {
  const sim::Dataset& d = Scenario().train;
  const Matrix X = EveryKth(d.X, 10);
  const Matrix Y = EveryKth(d.Y, 10);
  const Eigen::Index half = X.rows() / 2;
  const RobotModel layout(Spec("pol+fri"), 2);
  const auto& map = layout.feature_map();
  Hyperparameters hyper = DefaultHyperparameters(*map, 2);
  hyper.per_output = TwoSets(hyper);
  GaussianProcess online(map, hyper, 2, Form::kWeightSpace);
  ASSERT_EQ(online.Fit(X.topRows(half), Y.topRows(half)), Status::kOk);
  GaussianProcess::Workspace workspace = online.MakeWorkspace();
  Vector x(X.cols()), y(2), mean(2), latent(2), noisy(2);
  {
    testing::AllocationCounter guard;
    for (Eigen::Index i = half; i < X.rows(); ++i) {
      x = X.row(i).transpose();
      y = Y.row(i).transpose();
      ASSERT_EQ(online.PredictWithVariance(x, mean, latent, noisy, workspace), Status::kOk);
      ASSERT_EQ(online.Predict(x, mean, workspace), Status::kOk);
      ASSERT_EQ(online.Add(x, y), Status::kOk);
    }
    EXPECT_EQ(guard.count(), 0u) << "predict and update of a per-output model allocated";
  }
  GaussianProcess batch(map, hyper, 2, Form::kWeightSpace);
  ASSERT_EQ(batch.Fit(X, Y), Status::kOk);
  const Matrix Xtest = EveryKth(Scenario().test.X, 40);
  const Prediction a = PredictAll(online, Xtest), b = PredictAll(batch, Xtest);
  ExpectClose(a.mean, b.mean, 1e-8, "mean, online vs batch");
  ExpectClose(a.latent, b.latent, 1e-7, "latent variance, online vs batch");

  // A bad sample changes no output; a wrong workspace is refused.
  y[1] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(online.Add(x, y), Status::kInvalidInput);
  const Prediction c = PredictAll(online, Xtest);
  EXPECT_EQ(c.mean, a.mean);
  GaussianProcess::Workspace empty;
  EXPECT_EQ(online.Predict(x, mean, empty), Status::kInvalidInput);
}

TEST(PerJointGaussianProcess, RefusesBadSetsAndSharedForms) {
  const RobotModel layout(Spec("pol+fri"), 2);
  const auto& map = layout.feature_map();
  Hyperparameters hyper = DefaultHyperparameters(*map, 2);
  hyper.per_output = TwoSets(hyper);
  hyper.per_output.pop_back();
  EXPECT_THROW(GaussianProcess(map, hyper, 2), std::invalid_argument);
  hyper.per_output = TwoSets(hyper);
  hyper.per_output[1].log_output_scale = Vector::Zero(2);
  EXPECT_THROW(GaussianProcess(map, hyper, 2), std::invalid_argument);
  hyper.per_output = TwoSets(hyper);
  hyper.per_output[1].per_output = TwoSets(hyper);
  EXPECT_THROW(GaussianProcess(map, hyper, 2), std::invalid_argument);

  // Output(j): a joint's own set, or the shared set with the joint's scale.
  hyper.per_output = TwoSets(hyper);
  EXPECT_EQ(hyper.Output(1).log_noise_std, hyper.per_output[1].log_noise_std);
  Hyperparameters shared = hyper;
  shared.per_output.clear();
  EXPECT_EQ(shared.Output(1).log_output_scale[0], shared.log_output_scale[1]);
  EXPECT_EQ(shared.Output(1).shape, shared.shape);
  EXPECT_THROW(shared.Output(2), std::out_of_range);

  // lag shares its parameters across joints.
  const sim::Dataset& d = Scenario().train;
  RobotModel lag(Spec("lag"), 2);
  Hyperparameters h = lag.DefaultHyperparameters(d.Y);
  h.per_output = std::vector<Hyperparameters>(2, h);
  for (Hyperparameters& own : h.per_output) own.log_output_scale = Vector::Zero(1);
  try {
    lag.Fit(d.X, d.Y, h);
    ADD_FAILURE() << "lag took per-joint sets";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("shares its parameters across joints"),
              std::string::npos)
        << e.what();
  }
  FitOptions options;
  options.per_joint = true;
  EXPECT_THROW(FitModel(Spec("lag"), d.X, d.Y, Vector(), options), std::invalid_argument);
  EXPECT_THROW(FitModel(Spec("lagk"), d.X, d.Y, Vector(), options), std::invalid_argument);
}

// The same set, bit for bit.
void ExpectSameSet(const Hyperparameters& a, const Hyperparameters& b) {
  EXPECT_EQ(a.shape, b.shape);
  EXPECT_EQ(a.log_block_scale, b.log_block_scale);
  EXPECT_EQ(a.log_noise_std, b.log_noise_std);
  EXPECT_EQ(a.log_output_scale, b.log_output_scale);
}

// The per-joint workflow equals each joint's search assembled by hand from the lower layers:
// its torque's statistics, the profile of noise and scale, LBFGS from 3 starts with the prior.
TEST(PerJointFit, EqualsEachJointsSearchByHand) {
  const sim::Dataset& d = Scenario().train;
  const ModelSpec spec = Spec("pol+fri");
  FitOptions options;
  options.per_joint = true;
  const FittedModel fit = FitModel(spec, d.X, d.Y, d.t, options);
  ASSERT_TRUE(fit.summary.IsUsable()) << fit.summary.message;
  ASSERT_TRUE(fit.model.per_joint());
  ASSERT_EQ(fit.summary.joints.size(), 2u);
  EXPECT_TRUE(fit.summary.check.ran);
  EXPECT_EQ(fit.summary.check.coverage.size(), 2);

  RobotModel reference(spec, 2);
  const Hyperparameters start = reference.DefaultHyperparameters(d.Y);
  Hyperparameters hyper = start;
  double evidence = 0.0;
  int iterations = 0;
  for (int j = 0; j < 2; ++j) {
    const FitSummary& js = fit.summary.joints[static_cast<size_t>(j)];
    ASSERT_TRUE(js.IsUsable()) << js.message;
    // The check took the best start of each joint's search (else the hand version differs).
    ASSERT_EQ(js.chosen_start, js.best_start) << "joint " << j + 1;
    EXPECT_TRUE(js.check.ran);
    EXPECT_TRUE(std::isnan(js.check.coverage[1 - j])) << "the check of joint " << j + 1
                                                      << " read the other joint";
    Hyperparameters own = start.Output(j);
    EXPECT_TRUE(own.per_output.empty());
    EXPECT_EQ(own.log_output_scale.size(), 1);
    const SufficientStatistics stats =
        AccumulateStatistics(*reference.feature_map(), d.X, d.Y.col(j));
    const WeightSpaceEvidence ev(reference.feature_map(), stats);
    own = ProfileNoiseAndScales(ev, own, -9.0, 1.0);
    const MaximumLikelihoodSummary s = FitHyperparameters(ev, MaximumLikelihoodOptions(), &own);
    ASSERT_TRUE(s.usable());
    EXPECT_EQ(js.final_negative_log_evidence, s.final_negative_log_likelihood);
    evidence += s.final_negative_log_likelihood;
    iterations += js.iterations;
    ExpectSameSet(fit.model.hyperparameters().per_output[static_cast<size_t>(j)], own);
    hyper.per_output.push_back(own);
  }
  EXPECT_DOUBLE_EQ(fit.summary.final_negative_log_evidence, evidence);
  EXPECT_EQ(fit.summary.iterations, iterations);
  ASSERT_EQ(reference.Fit(d.X, d.Y, hyper), Status::kOk);
  Matrix a, b;
  fit.model.PredictRows(d.X, &a);
  reference.PredictRows(d.X, &b);
  EXPECT_EQ(a, b);

  // The report and the JSON show every joint's set.
  const std::string report = FitReport(fit.model, fit.summary);
  EXPECT_NE(report.find("one set of hyper-parameters per joint"), std::string::npos) << report;
  EXPECT_NE(report.find("tau2"), std::string::npos);
  const std::string json = ToJson(fit.model, fit.summary);
  EXPECT_NE(json.find("\"per_joint\": true"), std::string::npos);
  EXPECT_NE(json.find("\"joints\""), std::string::npos);
}

// With two threads both joints are searched at once: the same sets as one at a time, the
// progress still on the calling thread, and an abort from it stops the fit.
TEST(PerJointFit, JointsOnThreadsGiveTheOneThreadResult) {
  const sim::Dataset& d = Scenario().train;
  const ModelSpec spec = Spec("pol+fri");
  FitOptions one;
  one.per_joint = true;
  const FittedModel a = FitModel(spec, d.X, d.Y, d.t, one);
  ASSERT_TRUE(a.summary.IsUsable()) << a.summary.message;

  FitOptions two = one;
  two.num_threads = 2;
  const std::thread::id caller = std::this_thread::get_id();
  bool other_thread = false;
  std::vector<std::string> messages;
  two.callback = [&](const FitProgress& p) {
    other_thread = other_thread || std::this_thread::get_id() != caller;
    if (!p.message.empty()) messages.push_back(p.message);
    return FitCallbackReturn::kContinue;
  };
  const FittedModel b = FitModel(spec, d.X, d.Y, d.t, two);
  ASSERT_TRUE(b.summary.IsUsable()) << b.summary.message;
  EXPECT_FALSE(other_thread) << "the callback was called on a worker thread";
  for (int j = 0; j < 2; ++j) {
    ExpectSameSet(a.model.hyperparameters().per_output[static_cast<size_t>(j)],
                  b.model.hyperparameters().per_output[static_cast<size_t>(j)]);
  }
  Matrix pa, pb;
  a.model.PredictRows(d.X, &pa);
  b.model.PredictRows(d.X, &pb);
  EXPECT_EQ(pa, pb);
  for (const char* joint : {"joint 1: ", "joint 2: "}) {
    EXPECT_TRUE(std::any_of(messages.begin(), messages.end(), [&](const std::string& m) {
      return m.rfind(joint, 0) == 0;
    })) << joint;
  }

  FitOptions abort = two;
  abort.callback = [](const FitProgress& p) {
    return p.message.find("joint 2: ") == 0 ? FitCallbackReturn::kAbort
                                            : FitCallbackReturn::kContinue;
  };
  const FittedModel c = FitModel(spec, d.X, d.Y, d.t, abort);
  EXPECT_EQ(c.summary.termination, FitTermination::kUserAbort);
  EXPECT_FALSE(c.model.fitted());
}

// Noise-free two-link torques with noise of 0.3% of joint 1's torque RMS and 8% of joint 2's:
// with their own sets, each joint's noise is recovered; shared, one ratio of prior to noise
// serves both and the fitted noise is off on at least one joint.
TEST(PerJointFit, RecoversEachJointsOwnNoise) {
  sim::HiddenEffectOptions o;
  o.effect = sim::HiddenEffect::kNone;
  o.noise_std = 0.0;
  o.seed = 5;
  const sim::HiddenEffectScenario scenario = sim::MakeHiddenEffectScenario(sim::TwoLinkArm(), o);
  const sim::Dataset& d = scenario.train;
  Matrix Y = d.Y;
  const double relative[2] = {0.003, 0.08};
  Vector truth(2);
  std::mt19937_64 rng(11);
  std::normal_distribution<double> normal;
  for (int j = 0; j < 2; ++j) {
    truth[j] = relative[j] * std::sqrt(d.Y.col(j).squaredNorm() / d.Y.rows());
    for (Eigen::Index i = 0; i < Y.rows(); ++i) Y(i, j) += truth[j] * normal(rng);
  }
  FitOptions options;
  options.per_joint = true;
  const FittedModel own = FitModel(Spec("pol"), d.X, Y, d.t, options);
  ASSERT_TRUE(own.summary.IsUsable()) << own.summary.message;
  const Vector fitted = own.model.hyperparameters().noise_stds();
  for (int j = 0; j < 2; ++j) {
    EXPECT_NEAR(fitted[j] / truth[j], 1.0, 0.15) << "joint " << j + 1;
  }
  // Cross-check: each joint's noise std is its own set's s_j sigma_n.
  for (int j = 0; j < 2; ++j) {
    const Hyperparameters& h = own.model.hyperparameters().per_output[static_cast<size_t>(j)];
    EXPECT_DOUBLE_EQ(fitted[j], std::exp(h.log_noise_std + h.log_output_scale[0]));
  }
}

TEST(PerJointModel, ComponentsAndCoefficientsAreEachJointsOwn) {
  const sim::Dataset& d = Scenario().train;
  const ModelSpec spec = Spec("pol+fri");
  RobotModel model(spec, 2);
  Hyperparameters hyper = model.DefaultHyperparameters(d.Y);
  hyper.per_output = TwoSets(hyper);
  ASSERT_EQ(model.Fit(d.X, d.Y, hyper), Status::kOk);
  ASSERT_TRUE(model.has_components());
  const Matrix Xtest = EveryKth(Scenario().test.X, 100);
  Matrix mean, latent_std;
  model.PredictRows(Xtest, &mean, &latent_std);
  const std::vector<ComponentRows> parts = model.PredictComponentRows(Xtest);
  Matrix sum = Matrix::Zero(mean.rows(), 2);
  for (const ComponentRows& p : parts) sum += p.mean;
  ExpectClose(sum, mean, 1e-10, "the components add up to the prediction");

  // Joint j's coefficients and components are those of a shared model whose one set is joint
  // j's (a shared set fits each column as a model of that column alone with that set).
  for (int j = 0; j < 2; ++j) {
    SCOPED_TRACE("joint " + std::to_string(j + 1));
    const Hyperparameters& own = hyper.per_output[static_cast<size_t>(j)];
    Hyperparameters as_shared = own;
    as_shared.log_output_scale = Vector::Constant(2, own.log_output_scale[0]);
    RobotModel reference(spec, 2);
    ASSERT_EQ(reference.Fit(d.X, d.Y, as_shared), Status::kOk);
    int compared = 0;
    for (const FeatureCoefficient& c : model.Coefficients()) {
      if (c.joint != j + 1) continue;
      const auto [value, std] = reference.Coefficient(c.name, j + 1);
      EXPECT_NEAR(c.value, value, 1e-8 * std::max(1.0, std::abs(value))) << c.name;
      EXPECT_NEAR(c.std, std, 1e-8 * std) << c.name;
      ++compared;
    }
    EXPECT_GE(compared, 2);  // Coulomb and viscous of the joint
    std::vector<Component> mine, theirs;
    ASSERT_EQ(model.PredictComponents(Xtest.row(3).transpose(), &mine), Status::kOk);
    ASSERT_EQ(reference.PredictComponents(Xtest.row(3).transpose(), &theirs), Status::kOk);
    ASSERT_EQ(mine.size(), theirs.size());
    for (size_t c = 0; c < mine.size(); ++c) {
      EXPECT_NEAR(mine[c].mean[j], theirs[c].mean[j], 1e-8 * std::max(1.0, std::abs(theirs[c].mean[j])))
          << mine[c].name;
      EXPECT_NEAR(mine[c].latent_variance[j], theirs[c].latent_variance[j],
                  1e-8 * theirs[c].latent_variance[j])
          << mine[c].name;
    }
  }
}

TEST(PerJointModel, ModelFileRoundTripsInBothForms) {
  const sim::Dataset& d = Scenario().train;
  const Matrix Xtest = EveryKth(Scenario().test.X, 40);
  for (const char* name : {"pol+fri", "rbf+fri"}) {
    SCOPED_TRACE(name);
    RobotModel model(Spec(name), 2);
    const Matrix X = EveryKth(d.X, 8), Y = EveryKth(d.Y, 8);
    Hyperparameters hyper = model.DefaultHyperparameters(Y);
    hyper.per_output = TwoSets(hyper);
    ASSERT_EQ(model.Fit(X, Y, hyper), Status::kOk);
    const std::string text = ModelFileText(model);
    EXPECT_NE(text.find("\"version\": 3"), std::string::npos);
    EXPECT_NE(text.find("\"per_joint\""), std::string::npos);
    const RobotModel loaded = ParseModelFile(text, "per_joint.json");
    ASSERT_TRUE(loaded.per_joint());
    Matrix a, sa, b, sb;
    model.PredictRows(Xtest, &a, &sa);
    loaded.PredictRows(Xtest, &b, &sb);
    if (model.gp().form() == Form::kWeightSpace) {
      EXPECT_EQ(a, b);  // the posterior is restored as it is
      EXPECT_EQ(sa, sb);
    } else {
      ExpectClose(b, a, 1e-9, "function space refitted from its stored points");
      ExpectClose(sb, sa, 1e-7, "function space refitted from its stored points");
    }
    EXPECT_EQ(ModelFileText(loaded), text);
    EXPECT_EQ(loaded.hyperparameters().noise_stds(), model.hyperparameters().noise_stds());
  }
  // A model whose joints share their set writes version 2, as before.
  RobotModel shared(Spec("pol+fri"), 2);
  ASSERT_EQ(shared.Fit(d.X, d.Y), Status::kOk);
  EXPECT_NE(ModelFileText(shared).find("\"version\": 2"), std::string::npos);
}

TEST(PerJointModel, TheOnlineLearnerAsksForTheSharedSet) {
  const sim::Dataset& d = Scenario().train;
  FitOptions options;
  options.per_joint = true;
  options.method = HyperparameterMethod::kFixed;
  const FittedModel fit = FitModel(Spec("pol+fri"), d.X, d.Y, d.t, options);
  ASSERT_TRUE(fit.summary.IsUsable()) << fit.summary.message;
  try {
    Replay(fit.model, Scenario().test.X, Scenario().test.Y, Scenario().test.t, ReplayOptions());
    ADD_FAILURE() << "replay took a per-joint model";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("per-joint hyper-parameters"), std::string::npos)
        << e.what();
  }
}

// The diagnosis of a per-joint model (each joint against its own prior) names the Coulomb
// friction the model lacks, on its joint.
// pol (without the friction the log has) fitted per joint on the slow log: noise and output
// scales by evidence, the default shape and block scales, as test_diagnosis fits its models.
FitOptions PerJointNoiseAndScales() {
  FitOptions options;
  options.per_joint = true;
  options.evidence.optimize_shape = false;
  options.evidence.optimize_block_scales = false;
  options.evidence.optimize_noise = false;
  return options;
}

TEST(PerJointModel, DiagnosisNamesTheMissingCoulombOnItsJoint) {
  const sim::HiddenEffectScenario& s = Scenario();
  const FittedModel fit =
      FitModel(Spec("pol"), s.train.X, s.train.Y, s.train.t, PerJointNoiseAndScales());
  ASSERT_TRUE(fit.summary.IsUsable()) << fit.summary.message;
  DiagnosisOptions d;
  d.training_inputs = s.train.X;
  d.training_targets = s.train.Y;
  d.training_times = s.train.t;
  const Diagnosis out = Diagnose(fit.model, s.test.X, s.test.Y, s.test.t, d);
  ASSERT_EQ(out.status, DiagnosisStatus::kOk) << out.message;
  ASSERT_FALSE(out.suggestions.empty());
  EXPECT_EQ(out.suggestions.front().effect, "coulomb");
  EXPECT_EQ(out.suggestions.front().joint, 2);
  for (const Suggestion& suggestion : out.suggestions) EXPECT_EQ(suggestion.joint, 2);
  EXPECT_NE(out.features.find("own hyper-parameters"), std::string::npos) << out.features;
}

// The diagnosis loop refits with the suggestions, per joint as the diagnosed model was.
TEST(PerJointModel, TheDiagnosisLoopRefitsPerJoint) {
  const sim::HiddenEffectScenario& s = Scenario();
  const FitOptions options = PerJointNoiseAndScales();
  const FittedModel fit = FitModel(Spec("pol"), s.train.X, s.train.Y, s.train.t, options);
  ASSERT_TRUE(fit.summary.IsUsable()) << fit.summary.message;
  DiagnosisLoopOptions loop;
  loop.max_rounds = 1;
  loop.fit = options;
  loop.fit.per_joint = false;  // replaced by the diagnosed model's choice
  std::optional<RobotModel> improved;
  const DiagnosisLoopSummary summary =
      RunDiagnosisLoop(loop, fit.model, s.train.X, s.train.Y, s.train.t, s.test.X, s.test.Y,
                       s.test.t, &improved);
  ASSERT_TRUE(improved.has_value()) << summary.message;
  EXPECT_TRUE(improved->per_joint());
  EXPECT_FALSE(improved->spec().effects.empty());
}

}  // namespace
}  // namespace structgp
