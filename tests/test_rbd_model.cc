// The rbd model (the rigid-body regressor of a URDF chain) against KDL: data simulated with
// KDL's inverse dynamics of the same chain with other inertial parameters and friction, fitted
// by the library's workflow; the fast test motion must be predicted to the noise level, the
// friction found, the components must add up and match KDL's terms, and the model file must
// restore the model.

#include <cmath>
#include <cstdio>
#include <random>
#include <stdexcept>
#include <string>

#include <gtest/gtest.h>

#include "battery_options.h"
#include "structgp/diagnose/diagnosis.h"
#include "structgp/feature/rigid_body_torque_feature_map.h"
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

// ---- rbd+pol: the URDF's torques as features beside a kernel -------------------------------

TEST_F(RbdModelTest, TorqueFeaturesAreKdlsTermsAndPassTheBattery) {
  const RigidBodyTorqueFeatureMap map(*nominal_);
  const int N = nominal_->num_joints();
  ASSERT_EQ(map.dim(), 3 * N);
  Vector phi(map.dim());
  for (Eigen::Index i : {Eigen::Index(5), Eigen::Index(1200)}) {
    const Vector x = fast_.X.row(i).transpose();
    map.Evaluate(x, phi);
    const Vector q = x.head(N), qd = x.segment(N, N), qdd = x.tail(N);
    // KDL's ChainDynParam terms, and their sum KDL's recursive Newton-Euler.
    const Vector inertial = nominal_->MassMatrix(q) * qdd;
    const Vector coriolis = nominal_->Coriolis(q, qd);
    const Vector gravity = nominal_->Gravity(q);
    const Vector tau = nominal_->InverseDynamics(q, qd, qdd);
    EXPECT_LT((phi.head(N) - inertial).norm(), 1e-10 * (1 + inertial.norm()));
    EXPECT_LT((phi.segment(N, N) - coriolis).norm(), 1e-10 * (1 + coriolis.norm()));
    EXPECT_LT((phi.tail(N) - gravity).norm(), 1e-10 * (1 + gravity.norm()));
    EXPECT_LT((phi.head(N) + phi.segment(N, N) + phi.tail(N) - tau).norm(), 1e-10 * (1 + tau.norm()));
  }
  testing::BatteryOptions options = testing::CountingBatteryOptions();
  options.num_states = 12;
  testing::RunFeatureMapBattery(map, options);
}

TEST_F(RbdModelTest, RbdPolSpecRoundTripsAndNeedsTheChain) {
  const ModelSpec spec = ParseModelSpec("rbd+pol+fri");
  EXPECT_EQ(spec.base, BaseModel::kPol);
  EXPECT_TRUE(spec.rigid_body_features);
  EXPECT_TRUE(spec.friction);
  EXPECT_EQ(ToString(spec), "rbd+pol+fri");
  EXPECT_EQ(ToString(ParseModelSpec("rbd+rbf")), "rbd+rbf");
  EXPECT_FALSE(ParseModelSpec("rbd+fri").rigid_body_features);
  for (const char* bad : {"rbd+lag", "rbd+rbd", "pol+rbd", "rbd+pol+fri+fri"}) {
    EXPECT_THROW(ParseModelSpec(bad), std::invalid_argument) << bad;
  }
  try {
    RobotModel(ParseModelSpec("rbd+pol"), 3);
    FAIL() << "expected an error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("model 'rbd+pol' needs the robot's kinematic chain"),
              std::string::npos)
        << e.what();
  }
}

// A URDF whose inertial parameters are off by up to 30%: pol with the URDF model as its prior
// mean predicts the fast motion better than pol alone and than the URDF alone, its components
// add up, and its model file restores it.
TEST_F(RbdModelTest, RbdPolLearnsWhatTheUrdfGetsWrong) {
  // Every 16th training row (250) keeps pol's three-joint fit short.
  const Eigen::Index rows = train_.X.rows() / 16;
  Matrix X(rows, train_.X.cols()), Y(rows, train_.Y.cols());
  for (Eigen::Index i = 0; i < rows; ++i) {
    X.row(i) = train_.X.row(16 * i);
    Y.row(i) = train_.Y.row(16 * i);
  }
  FitOptions options;
  options.model.rigid_body = nominal_;
  options.evidence.num_starts = 1;  // one search each: the comparison, not the search, is tested
  options.check.enabled = false;
  const FittedModel pol = FitModel(ParseModelSpec("pol+fri"), X, Y, Vector(), options);
  const FittedModel both = FitModel(ParseModelSpec("rbd+pol+fri"), X, Y, Vector(), options);
  std::printf("fit seconds: pol+fri %.2f, rbd+pol+fri %.2f\n", pol.summary.total_seconds,
              both.summary.total_seconds);
  ASSERT_TRUE(pol.summary.IsUsable()) << pol.summary.message;
  ASSERT_TRUE(both.summary.IsUsable()) << both.summary.message;
  const int N = nominal_->num_joints();
  Matrix a, b, b_std;
  pol.model.PredictRows(fast_.X, &a);
  both.model.PredictRows(fast_.X, &b, &b_std);
  // The URDF alone, for scale.
  Matrix urdf(fast_.X.rows(), N);
  for (Eigen::Index i = 0; i < fast_.X.rows(); ++i) {
    urdf.row(i) = nominal_->InverseDynamics(fast_.X.row(i).head(N).transpose(),
                                            fast_.X.row(i).segment(N, N).transpose(),
                                            fast_.X.row(i).tail(N).transpose())
                      .transpose();
  }
  const double pol_rms = std::sqrt((a - fast_.Y).squaredNorm() / a.size());
  const double both_rms = std::sqrt((b - fast_.Y).squaredNorm() / b.size());
  const double urdf_rms = std::sqrt((urdf - fast_.Y).squaredNorm() / urdf.size());
  std::printf("fast motion RMS: pol+fri %.4g, URDF alone %.4g, rbd+pol+fri %.4g N m (noise %.3g)\n",
              pol_rms, urdf_rms, both_rms, kNoise);
  EXPECT_LT(both_rms, 0.5 * pol_rms);
  EXPECT_LT(both_rms, 0.5 * urdf_rms);
  // Components: pol's three blocks, friction, the URDF's three terms; they add up (pol runs
  // in function space on these 250 rows: refit in weight space for the split).
  ASSERT_EQ(both.model.ComponentNames(),
            (std::vector<std::string>{"inertial", "coriolis", "gravity", "friction",
                                      "urdf inertial", "urdf coriolis", "urdf gravity"}));
  RobotModelOptions weight_space = options.model;
  weight_space.form = Form::kWeightSpace;
  RobotModel split(ParseModelSpec("rbd+pol+fri"), N, weight_space);
  ASSERT_EQ(split.Fit(X, Y, both.model.hyperparameters()), Status::kOk);
  Matrix d;
  split.PredictRows(fast_.X.topRows(400), &d);
  EXPECT_LT((d - b.topRows(400)).norm(), 1e-6 * (1 + b.topRows(400).norm()));  // the two forms agree
  const Vector x = fast_.X.row(300).transpose();
  std::vector<Component> parts;
  ASSERT_EQ(split.PredictComponents(x, &parts), Status::kOk);
  Vector sum = Vector::Zero(N), mean(N);
  for (const Component& c : parts) sum += c.mean;
  ASSERT_EQ(split.Predict(x, mean), Status::kOk);
  const Vector q = x.head(N), qd = x.segment(N, N), qdd = x.tail(N);
  EXPECT_LT((parts[6].mean - nominal_->Gravity(q)).norm(), 1e-9 * (1 + parts[6].mean.norm()));
  EXPECT_LT((parts[4].mean - nominal_->MassMatrix(q) * qdd).norm(), 1e-9 * (1 + parts[4].mean.norm()));
  EXPECT_EQ(parts[5].latent_variance, Vector::Zero(N));
  (void)qd;
  EXPECT_LT((sum - mean).norm(), 1e-9 * (1 + mean.norm()));
  // The model file carries the URDF and restores the same predictions.
  const std::string text = ModelFileText(both.model);
  const RobotModel loaded = ParseModelFile(text, "model.json");
  Matrix c, c_std;
  loaded.PredictRows(fast_.X.topRows(40), &c, &c_std);
  EXPECT_EQ(c, b.topRows(40));
  EXPECT_EQ(c_std, b_std.topRows(40));
}

}  // namespace
}  // namespace structgp
