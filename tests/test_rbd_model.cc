// The rbd model (the rigid-body regressor of a URDF chain) against KDL: data simulated with
// KDL's inverse dynamics of the same chain with other inertial parameters and friction, fitted
// by the library's workflow; the fast test motion must be predicted to the noise level, the
// friction found, the components must add up and match KDL's terms, and the model file must
// restore the model.

#include <cmath>
#include <random>
#include <stdexcept>
#include <string>

#include <gtest/gtest.h>

#include "structgp/diagnose/diagnosis.h"
#include "structgp/fit/fit_model.h"
#include "structgp/io/model_file.h"
#include "structgp/model/robot_model.h"
#include "structgp/rigid_body/rigid_body_chain.h"
#include "structgp/sim/trajectory.h"
#include "urdf_test_util.h"

namespace structgp {
namespace {

constexpr double kNoise = 0.05;       // N m
constexpr double kWidth = 0.01;       // Coulomb tanh width, rad/s (the model's default)

struct Log {
  Matrix X, Y, clean;
};

// KDL torques of `truth` along a trajectory, with viscous and Coulomb friction and noise.
Log Simulate(const RigidBodyChain& truth, const Vector& viscous, const Vector& coulomb,
             const sim::Trajectory& tr, std::uint64_t seed) {
  const int N = truth.num_joints();
  std::mt19937_64 rng(seed + 100);
  std::normal_distribution<double> normal(0.0, kNoise);
  Log log;
  const Eigen::Index m = tr.q.rows();
  log.X.resize(m, 3 * N);
  log.X << tr.q, tr.qd, tr.qdd;
  log.clean.resize(m, N);
  for (Eigen::Index i = 0; i < m; ++i) {
    Vector tau = truth.InverseDynamics(tr.q.row(i).transpose(), tr.qd.row(i).transpose(),
                                       tr.qdd.row(i).transpose());
    for (int j = 0; j < N; ++j) {
      tau[j] += viscous[j] * tr.qd(i, j) + coulomb[j] * std::tanh(tr.qd(i, j) / kWidth);
    }
    log.clean.row(i) = tau.transpose();
  }
  log.Y = log.clean.unaryExpr([&](double v) { return v + normal(rng); });
  return log;
}

class RbdModelTest : public ::testing::Test {
 protected:
  RbdModelTest() {
    testing::RandomUrdfOptions o;
    o.num_joints = 3;
    o.fixed_links = true;
    o.seed = 4;
    urdf_ = testing::RandomUrdf(o);
    nominal_ = std::make_shared<const RigidBodyChain>(RigidBodyChain::FromUrdfString(urdf_));
    // The real robot: every inertial parameter off by up to +-30%, some armature.
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> u(-0.3, 0.3);
    Vector pi = nominal_->parameters();
    for (Eigen::Index k = 0; k < pi.size(); ++k) pi[k] *= 1.0 + u(rng);
    const int N = nominal_->num_joints();
    for (int j = 0; j < N; ++j) pi[10 * N + j] = 0.02 * (j + 1);
    truth_ = std::make_shared<const RigidBodyChain>(nominal_->WithParameters(pi));
    viscous_ = Vector::LinSpaced(N, 0.5, 0.2);
    coulomb_ = Vector::LinSpaced(N, 0.8, 0.3);
    // An excitation trajectory for training (five harmonics of 0.05 Hz), another one of the
    // same kind for testing, and a fast via-point motion: velocities up to ~4 rad/s.
    train_ = Simulate(*truth_, viscous_, coulomb_, sim::SumOfSines(N, 40.0, 0.01, 5, 0.05, 1.5, 1), 1);
    test_ = Simulate(*truth_, viscous_, coulomb_, sim::SumOfSines(N, 20.0, 0.01, 5, 0.05, 1.5, 2), 2);
    fast_ = Simulate(*truth_, viscous_, coulomb_, sim::ViaPoints(N, 20.0, 0.01, 8, 2.5, 1.2, 3), 3);
  }

  FittedModel Fit(const std::string& model) const {
    FitOptions options;
    options.model.rigid_body = nominal_;
    return FitModel(ParseModelSpec(model), train_.X, train_.Y, Vector(), options);
  }

  std::string urdf_;
  std::shared_ptr<const RigidBodyChain> nominal_, truth_;
  Vector viscous_, coulomb_;
  Log train_, test_, fast_;
};

TEST_F(RbdModelTest, PredictsUnseenMotionToTheNoiseAndFindsTheFriction) {
  const FittedModel fitted = Fit("rbd+fri");
  ASSERT_TRUE(fitted.summary.IsUsable()) << fitted.summary.message;
  const RobotModel& model = fitted.model;
  EXPECT_EQ(model.gp().form(), Form::kRegressor);
  Matrix mean, latent_std;
  model.PredictRows(test_.X, &mean, &latent_std);
  const int N = model.num_joints();
  Matrix fast_mean, fast_std;
  model.PredictRows(fast_.X, &fast_mean, &fast_std);
  for (int j = 0; j < N; ++j) {
    const double rms = std::sqrt((mean.col(j) - test_.Y.col(j)).squaredNorm() / mean.rows());
    EXPECT_LT(rms / kNoise, 1.1) << "joint " << j + 1;
    // Fast motion extrapolates (Coriolis terms ~6 times the training ones): the error grows,
    // and the predictive band says so.
    const Vector err = fast_mean.col(j) - fast_.Y.col(j);
    EXPECT_LT(std::sqrt(err.squaredNorm() / err.size()) / kNoise, 1.6) << "joint " << j + 1;
    const Vector band = 2.0 * (fast_std.col(j).array().square() + kNoise * kNoise).sqrt().matrix();
    const double covered =
        static_cast<double>((err.array().abs() <= band.array()).count()) / err.size();
    EXPECT_GT(covered, 0.9) << "joint " << j + 1;
    // The noise level of each joint, by evidence.
    const Hyperparameters& h = model.hyperparameters();
    EXPECT_NEAR(std::exp(h.log_noise_std + h.log_output_scale[j]) / kNoise, 1.0, 0.1);
    const auto [fc, fc_std] = model.Coefficient("coulomb@" + std::to_string(j + 1), j + 1);
    EXPECT_NEAR(fc, coulomb_[j], 4 * fc_std + 1e-3) << "joint " << j + 1;
    const auto [fv, fv_std] = model.Coefficient("viscous@" + std::to_string(j + 1), j + 1);
    EXPECT_NEAR(fv, viscous_[j], 4 * fv_std + 1e-3) << "joint " << j + 1;
  }
  // Without friction in the model the same data are far from the noise.
  const FittedModel plain = Fit("rbd");
  Matrix plain_mean;
  plain.model.PredictRows(test_.X, &plain_mean);
  EXPECT_GT(std::sqrt((plain_mean - test_.Y).squaredNorm() / plain_mean.size()), 3 * kNoise);
}

TEST_F(RbdModelTest, DiagnosisLoopFindsTheMissingFrictionAndReachesTheNoise) {
  // The loop a user runs: diagnose, add what it names, refit, until it names nothing.
  ModelSpec spec = ParseModelSpec("rbd");
  FitOptions options;
  options.model.rigid_body = nominal_;
  const int N = nominal_->num_joints();
  std::vector<bool> coulomb(static_cast<size_t>(N), false), viscous(static_cast<size_t>(N), false);
  FittedModel model = FitModel(spec, train_.X, train_.Y, Vector(), options);
  for (int round = 0; round < 4; ++round) {
    const Diagnosis d = Diagnose(model.model, train_.X, train_.Y, Vector());
    ASSERT_EQ(d.status, DiagnosisStatus::kOk) << d.message;
    if (d.suggestions.empty()) break;
    for (const Suggestion& s : d.suggestions) {
      EXPECT_TRUE(s.effect == "coulomb" || s.effect == "viscous" || s.effect == "stribeck")
          << "round " << round << ": " << s.spec;
      if (s.effect == "coulomb") coulomb[static_cast<size_t>(s.joint - 1)] = true;
      if (s.effect == "viscous") viscous[static_cast<size_t>(s.joint - 1)] = true;
      const std::vector<EffectSpec> added = ParseEffectList(s.spec);
      spec.effects.insert(spec.effects.end(), added.begin(), added.end());
    }
    model = FitModel(spec, train_.X, train_.Y, Vector(), options);
  }
  for (int j = 0; j < N; ++j) {
    EXPECT_TRUE(coulomb[static_cast<size_t>(j)]) << "Coulomb friction of joint " << j + 1;
    EXPECT_TRUE(viscous[static_cast<size_t>(j)]) << "viscous friction of joint " << j + 1;
  }
  Matrix mean;
  model.model.PredictRows(test_.X, &mean);
  for (int j = 0; j < N; ++j) {
    const double rms = std::sqrt((mean.col(j) - test_.Y.col(j)).squaredNorm() / mean.rows());
    EXPECT_LT(rms / kNoise, 1.1) << "joint " << j + 1 << " with " << ToString(spec.effects);
  }
}

TEST_F(RbdModelTest, ComponentsAddUpAndMatchKdlsTerms) {
  const FittedModel fitted = Fit("rbd+fri");
  const RobotModel& model = fitted.model;
  const int N = model.num_joints();
  ASSERT_EQ(model.ComponentNames(),
            (std::vector<std::string>{"inertial", "coriolis", "gravity", "friction"}));
  for (Eigen::Index i : {Eigen::Index(10), Eigen::Index(700), Eigen::Index(1500)}) {
    const Vector x = test_.X.row(i).transpose();
    std::vector<Component> parts;
    ASSERT_EQ(model.PredictComponents(x, &parts), Status::kOk);
    Vector sum = Vector::Zero(N), mean(N);
    for (const Component& c : parts) sum += c.mean;
    ASSERT_EQ(model.Predict(x, mean), Status::kOk);
    EXPECT_LT((sum - mean).norm(), 1e-9 * (1 + mean.norm()));
    const Vector q = x.head(N), qd = x.segment(N, N), qdd = x.tail(N);
    const Vector gravity = truth_->Gravity(q);
    const Vector coriolis = truth_->Coriolis(q, qd);
    const Vector inertial = truth_->MassMatrix(q) * qdd;
    for (int j = 0; j < N; ++j) {
      EXPECT_NEAR(parts[0].mean[j], inertial[j], 5 * std::sqrt(parts[0].latent_variance[j]) + 0.02);
      EXPECT_NEAR(parts[1].mean[j], coriolis[j], 5 * std::sqrt(parts[1].latent_variance[j]) + 0.02);
      EXPECT_NEAR(parts[2].mean[j], gravity[j], 5 * std::sqrt(parts[2].latent_variance[j]) + 0.02);
    }
  }
}

TEST_F(RbdModelTest, WithoutDataTheModelIsTheUrdf) {
  RobotModel model(ParseModelSpec("rbd"), nominal_->num_joints(), [&] {
    RobotModelOptions o;
    o.rigid_body = nominal_;
    return o;
  }());
  // One sample drowned in noise: the posterior mean is the prior's, the URDF's dynamics.
  Hyperparameters h = model.DefaultHyperparameters(train_.Y);
  h.log_noise_std = std::log(1e6);
  ASSERT_EQ(model.Fit(train_.X.topRows(1), train_.Y.topRows(1), h), Status::kOk);
  const int N = model.num_joints();
  for (Eigen::Index i : {Eigen::Index(3), Eigen::Index(900)}) {
    const Vector x = test_.X.row(i).transpose();
    Vector mean(N);
    ASSERT_EQ(model.Predict(x, mean), Status::kOk);
    const Vector urdf = nominal_->InverseDynamics(x.head(N), x.segment(N, N), x.tail(N));
    EXPECT_LT((mean - urdf).norm(), 1e-6 * (1 + urdf.norm()));
  }
}

TEST_F(RbdModelTest, ModelFileRestoresTheSamePredictions) {
  const FittedModel fitted = Fit("rbd+fri");
  const std::string text = ModelFileText(fitted.model);
  const RobotModel loaded = ParseModelFile(text, "model.json");
  Matrix a, b, sa, sb;
  fitted.model.PredictRows(test_.X.topRows(50), &a, &sa);
  loaded.PredictRows(test_.X.topRows(50), &b, &sb);
  EXPECT_EQ(a, b);
  EXPECT_EQ(sa, sb);
  EXPECT_EQ(ModelFileText(loaded), text);
}

TEST_F(RbdModelTest, RefusesAModelWithoutItsChainOrWithAnotherJointCount) {
  try {
    RobotModel(ParseModelSpec("rbd+fri"), 3);
    FAIL() << "expected an error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("--urdf"), std::string::npos) << e.what();
  }
  RobotModelOptions options;
  options.rigid_body = nominal_;
  try {
    RobotModel(ParseModelSpec("rbd"), 2, options);
    FAIL() << "expected an error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("has 3 moving joints, the data have 2"),
              std::string::npos)
        << e.what();
  }
  FitOptions cv;
  cv.method = HyperparameterMethod::kCrossValidation;
  cv.model = options;
  EXPECT_THROW(FitModel(ParseModelSpec("rbd"), train_.X, train_.Y, Vector(), cv),
               std::invalid_argument);
}

}  // namespace
}  // namespace structgp
