// The physical split of a pol model's prediction, checked against the rigid-body terms that
// KDL computes: fitted on i.i.d. states of a KDL robot with tiny noise and hyper-parameters
// by type-II maximum likelihood, the "inertial", "coriolis" and "gravity" components predict
// M(q) qdd, C(q, qd) qd and G(q) on held-out states, each with an error bar that covers its
// actual error; with "+fri" on data with Coulomb and viscous friction, the fitted friction
// coefficients are the simulated ones within a few posterior standard deviations.
//
// Why the split is identifiable here: the three blocks are functions of different degree in
// (qd, qdd) - linear in qdd, quadratic in qd, independent of both - and with (q, qd, qdd)
// drawn independently, no combination of two blocks can imitate the third. The gravity block
// has no constant feature, and G(q) has none either (it is the gradient of the potential
// energy, and every term of a derivative with respect to q_n carries a cos or sin of q_n),
// while a constant M(q) part (e.g. the armature) sits in the inertial block (V_0 = 1). The
// friction bases are odd in qd and the pol blocks are even in qd, so they do not mix either.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <optional>
#include <random>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "structgp/fit/fit_model.h"
#include "structgp/model/robot_model.h"
#include "structgp/sim/dataset.h"
#include "structgp/sim/friction.h"
#include "structgp/sim/robot.h"
#include "structgp/sim/trajectory.h"

namespace structgp {
namespace {

constexpr double kPi = 3.141592653589793;

// State ranges of the i.i.d. training and test states.
constexpr double kQRange = kPi;   // rad
constexpr double kQdRange = 2.0;  // rad/s
constexpr double kQddRange = 4.0;  // rad/s^2
// Noise of the training torques, relative to max |tau| (global normalisation).
constexpr double kNoiseStd = 1e-3;

struct Problem {
  sim::Dataset train;
  Matrix X_test;
  // Noise-free terms at the test states, in the units of train.Y.
  sim::TorqueComponents truth;
};

Problem MakeProblem(const sim::Robot& robot, const std::optional<sim::FrictionModel>& friction,
                    int num_train, int num_test, std::uint64_t seed) {
  std::printf("robot %s, seed %llu, %d training states\n", robot.name().c_str(),
              static_cast<unsigned long long>(seed), num_train);
  const int n = robot.num_joints();
  Problem p;
  sim::SimulationOptions options;
  options.friction = friction;
  options.noise_std = kNoiseStd;
  options.normalization = sim::TorqueNormalization::kGlobal;
  options.seed = seed + 1;  // the noise stream apart from the states' stream (seed)
  p.train = sim::Simulate(
      robot, sim::UniformBox(n, num_train, kQRange, kQdRange, kQddRange, seed), options);
  const sim::Trajectory test =
      sim::UniformBox(n, num_test, kQRange, kQdRange, kQddRange, seed + 1000);
  sim::SimulationOptions raw;
  raw.friction = friction;
  p.truth = sim::SimulateComponents(robot, test, raw);  // N m
  const Eigen::DiagonalMatrix<double, Eigen::Dynamic> inverse_scale(
      p.train.torque_scale.cwiseInverse());
  p.truth.inertial = p.truth.inertial * inverse_scale;
  p.truth.coriolis = p.truth.coriolis * inverse_scale;
  p.truth.gravity = p.truth.gravity * inverse_scale;
  p.truth.friction = p.truth.friction * inverse_scale;
  p.truth.torque_scale = p.train.torque_scale;
  p.X_test.resize(num_test, 3 * n);
  p.X_test << test.q, test.qd, test.qdd;
  return p;
}

// A weight-space model of `spec` with hyper-parameters by type-II maximum likelihood: log
// sigma, block scales and noise. The output scales stay at 1: the torques share one
// normalisation and one noise level, and per-joint scales from the torque spread (the
// default) would impose noise levels in the ratio of the joints' torques (here up to 5:1),
// making the small joints' error bars too narrow.
RobotModel FitByEvidence(const std::string& spec, const sim::Dataset& train) {
  FitOptions options;
  options.model.form = Form::kWeightSpace;
  options.output_scaling = OutputScaling::kUnit;
  options.evidence.gradient_tolerance = 1e-7;
  FittedModel fit = FitModel(ParseModelSpec(spec), train.X, train.Y, train.t, options);
  std::printf("  %s: D = %d, %s\n%s", spec.c_str(), fit.model.feature_map()->dim(),
              fit.summary.BriefReport().c_str(), FitReport(fit.model, fit.summary).c_str());
  EXPECT_TRUE(fit.summary.IsUsable()) << fit.summary.message;
  return std::move(fit.model);
}

struct ComponentScore {
  std::string name;
  double relative_rms = 0.0;  // RMS(prediction - truth) / RMS(truth), over joints and states
  double covered = 0.0;       // fraction of |error| < 3 posterior std
  double rms_truth = 0.0;
  double rms_z = 0.0;         // RMS of error / posterior std (1 when calibrated)
};

std::vector<ComponentScore> ScoreComponents(const RobotModel& model, const Problem& p) {
  const std::vector<std::pair<std::string, const Matrix*>> truth = {
      {"inertial", &p.truth.inertial},
      {"coriolis", &p.truth.coriolis},
      {"gravity", &p.truth.gravity},
      {"friction", &p.truth.friction}};
  const std::vector<std::string> names = model.ComponentNames();
  std::vector<ComponentScore> scores;
  std::vector<double> error2, truth2, covered, z2;
  for (const auto& [name, matrix] : truth) {
    if (std::find(names.begin(), names.end(), name) == names.end()) continue;
    scores.push_back(ComponentScore{name});
  }
  error2.assign(scores.size(), 0.0);
  truth2.assign(scores.size(), 0.0);
  covered.assign(scores.size(), 0.0);
  z2.assign(scores.size(), 0.0);
  std::vector<Component> components;
  const Eigen::Index m = p.X_test.rows();
  const int n = model.num_joints();
  for (Eigen::Index i = 0; i < m; ++i) {
    const Vector x = p.X_test.row(i).transpose();
    EXPECT_EQ(model.PredictComponents(x, &components), Status::kOk);
    for (size_t s = 0; s < scores.size(); ++s) {
      const Component* c = nullptr;
      for (const auto& candidate : components) {
        if (candidate.name == scores[s].name) c = &candidate;
      }
      if (c == nullptr) {
        ADD_FAILURE() << "no component " << scores[s].name;
        continue;
      }
      const Matrix* target = nullptr;
      for (const auto& [name, matrix] : truth) {
        if (name == scores[s].name) target = matrix;
      }
      for (int j = 0; j < n; ++j) {
        const double error = c->mean[j] - (*target)(i, j);
        error2[s] += error * error;
        truth2[s] += (*target)(i, j) * (*target)(i, j);
        const double std = std::sqrt(c->latent_variance[j]);
        covered[s] += std::abs(error) < 3.0 * std ? 1.0 : 0.0;
        z2[s] += error * error / (std * std);
      }
    }
  }
  for (size_t s = 0; s < scores.size(); ++s) {
    scores[s].relative_rms = std::sqrt(error2[s] / truth2[s]);
    scores[s].covered = covered[s] / static_cast<double>(m * n);
    scores[s].rms_truth = std::sqrt(truth2[s] / static_cast<double>(m * n));
    scores[s].rms_z = std::sqrt(z2[s] / static_cast<double>(m * n));
    std::printf("  %-9s RMS(truth) %.4f  relative RMS error %.2e  |error| < 3 std: %.1f%%  "
                "RMS(error / std) %.2f\n",
                scores[s].name.c_str(), scores[s].rms_truth, scores[s].relative_rms,
                100.0 * scores[s].covered, scores[s].rms_z);
  }
  return scores;
}

// Tolerances. The model class contains each rigid-body term exactly (a least-squares fit of
// KDL's M(q) qdd, C(q, qd) qd and G(q) on their own blocks leaves residuals of 1e-15), so the
// error of a part is estimation error only. For least squares with D features, m i.i.d.
// samples and noise sigma_n, the RMS prediction error at new states is about
// sigma_n sqrt(D / m) in all (the parts share it); the broad ML-II prior changes that little.
// Each part's absolute RMS error must stay below twice that. Relative to the part's own size
// this is largest for the smallest part, the Coriolis term (qd within +-2 rad/s): 1% on the
// two-link arm, 3% on the random 3-joint robot (D = 1151); the limit is 5%. Any mix-up of the
// parts would move O(1) of one part into another.
constexpr double kMaxRelativeRms = 0.05;
constexpr double kAbsoluteErrorFactor = 2.0;
// |error| < 3 posterior std holds for 99.7% of a calibrated Gaussian; 90% is the limit.
constexpr double kMinCoverage = 0.9;

void CheckScores(const std::vector<ComponentScore>& scores, const std::string& robot, int dim,
                 int num_train) {
  const double expected = kNoiseStd * std::sqrt(static_cast<double>(dim) / num_train);
  for (const ComponentScore& s : scores) {
    SCOPED_TRACE(robot + " " + s.name);
    EXPECT_LT(s.relative_rms, kMaxRelativeRms);
    EXPECT_LT(s.relative_rms * s.rms_truth, kAbsoluteErrorFactor * expected);
    EXPECT_GT(s.covered, kMinCoverage);
  }
}

void CheckRigidBodySplit(const sim::Robot& robot, std::uint64_t seed) {
  const int m = 3000;
  const Problem p = MakeProblem(robot, std::nullopt, m, 500, seed);
  const RobotModel model = FitByEvidence("pol", p.train);
  CheckScores(ScoreComponents(model, p), robot.name(), model.feature_map()->dim(), m);
}

TEST(Decomposition, TwoLinkArmPartsMatchKdl) { CheckRigidBodySplit(sim::TwoLinkArm(), 11); }

TEST(Decomposition, RandomThreeJointRobotPartsMatchKdl) {
  CheckRigidBodySplit(sim::RandomRobot(3, 7), 12);
}

// Convergence: with 4 times the data, every part's error falls by about half (1 / sqrt(4)).
// 0.7 allows for the spread of the error estimate itself (500 test states, two fits).
TEST(Decomposition, TwoLinkArmPartsConvergeWithData) {
  const sim::Robot robot = sim::TwoLinkArm();
  std::vector<double> previous;
  for (int m : {1500, 6000, 24000}) {
    const Problem p = MakeProblem(robot, std::nullopt, m, 500, 13);
    const RobotModel model = FitByEvidence("pol", p.train);
    const std::vector<ComponentScore> scores = ScoreComponents(model, p);
    for (size_t s = 0; s < scores.size() && !previous.empty(); ++s) {
      EXPECT_LT(scores[s].relative_rms, 0.7 * previous[s]) << scores[s].name << ", m = " << m;
    }
    previous.clear();
    for (const ComponentScore& s : scores) previous.push_back(s.relative_rms);
  }
}

// Coulomb and viscous friction of a few percent of the torque range on every joint; the
// Coulomb term is smoothed with the model's own width (tanh(qd / 0.01)), so that the model
// class contains the data exactly and the coefficients are well defined.
void CheckFrictionRecovery(const sim::Robot& robot, std::uint64_t seed) {
  const int n = robot.num_joints();
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> coulomb(0.2, 0.6), viscous(0.1, 0.4);
  std::vector<sim::JointFriction> joints(static_cast<size_t>(n));
  for (auto& j : joints) {
    j.coulomb = coulomb(rng);  // N m
    j.viscous = viscous(rng);  // N m s / rad
    j.smoothing_velocity = RobotModelOptions().friction_width;
  }
  const sim::FrictionModel friction(joints);
  const int m = 3000;
  const Problem p = MakeProblem(robot, friction, m, 500, seed);
  const RobotModel model = FitByEvidence("pol+fri", p.train);
  CheckScores(ScoreComponents(model, p), robot.name(), model.feature_map()->dim(), m);
  // Coefficients in N m (s/rad): the model's are in the units of Y.
  const double scale = p.train.torque_scale[0];
  for (int j = 1; j <= n; ++j) {
    const auto& truth = joints[static_cast<size_t>(j - 1)];
    const auto [fc, fc_std] = model.Coefficient("coulomb@" + std::to_string(j), j);
    const auto [fv, fv_std] = model.Coefficient("viscous@" + std::to_string(j), j);
    const auto [fo, fo_std] = model.Coefficient("offset", j);
    std::printf("  joint %d: coulomb %.5f (true %.5f, std %.1e), viscous %.5f (true %.5f, "
                "std %.1e), offset %.1e (true 0, std %.1e)\n",
                j, fc * scale, truth.coulomb, fc_std * scale, fv * scale, truth.viscous,
                fv_std * scale, fo * scale, fo_std * scale);
    EXPECT_NEAR(fc * scale, truth.coulomb, 4.0 * fc_std * scale) << "joint " << j;
    EXPECT_NEAR(fv * scale, truth.viscous, 4.0 * fv_std * scale) << "joint " << j;
    EXPECT_NEAR(fo * scale, 0.0, 4.0 * fo_std * scale) << "joint " << j;
    // And the error bars are tight: a few percent of the coefficient at most.
    EXPECT_LT(fc_std * scale, 0.03 * truth.coulomb) << "joint " << j;
    EXPECT_LT(fv_std * scale, 0.03 * truth.viscous) << "joint " << j;
  }
}

// The batch calls give what the one-row calls give: PredictComponentRows row by row equals
// PredictComponents (bit for bit), its means add up to PredictRows' mean, and Coefficients
// lists Coefficient(name, joint) of every friction feature on its joint.
TEST(Decomposition, ComponentRowsAndCoefficientsAgreeWithTheOneRowCalls) {
  const sim::Robot robot = sim::TwoLinkArm();
  const Problem p = MakeProblem(robot, std::nullopt, 400, 50, 5);
  RobotModel model(ParseModelSpec("pol+fri"), 2);
  ASSERT_EQ(model.Fit(p.train.X, p.train.Y), Status::kOk);
  ASSERT_TRUE(model.has_components());
  const std::vector<ComponentRows> rows = model.PredictComponentRows(p.X_test);
  ASSERT_EQ(rows.size(), model.ComponentNames().size());
  Matrix mean, std_dev;
  model.PredictRows(p.X_test, &mean, &std_dev);
  Matrix sum = Matrix::Zero(mean.rows(), mean.cols());
  std::vector<Component> parts;
  for (Eigen::Index i = 0; i < p.X_test.rows(); ++i) {
    ASSERT_EQ(model.PredictComponents(p.X_test.row(i).transpose(), &parts), Status::kOk);
    for (size_t c = 0; c < rows.size(); ++c) {
      EXPECT_EQ(rows[c].name, parts[c].name);
      for (int j = 0; j < 2; ++j) {
        EXPECT_EQ(rows[c].mean(i, j), parts[c].mean[j]);
        EXPECT_EQ(rows[c].latent_std(i, j), std::sqrt(parts[c].latent_variance[j]));
      }
    }
  }
  for (const auto& c : rows) sum += c.mean;
  EXPECT_LE((sum - mean).cwiseAbs().maxCoeff(), 1e-12 * mean.cwiseAbs().maxCoeff());

  const std::vector<FeatureCoefficient> coefficients = model.Coefficients();
  // viscous@j and coulomb@j on joint j's torque, the shared offset once per joint torque.
  ASSERT_EQ(coefficients.size(), 6u);
  for (const FeatureCoefficient& c : coefficients) {
    const auto [value, std_c] = model.Coefficient(c.name, c.joint);
    EXPECT_EQ(c.value, value) << c.name;
    EXPECT_EQ(c.std, std_c) << c.name;
    if (c.name != "offset") {
      EXPECT_EQ(c.name.back() - '0', c.joint) << c.name;
    }
  }
  // Without components: a function-space model says so.
  RobotModel kernel(ParseModelSpec("rbf"), 2);
  ASSERT_EQ(kernel.Fit(p.train.X.topRows(100), p.train.Y.topRows(100)), Status::kOk);
  EXPECT_FALSE(kernel.has_components());
  EXPECT_THROW(kernel.PredictComponentRows(p.X_test), std::invalid_argument);
  EXPECT_TRUE(kernel.Coefficients().empty());
}

TEST(Decomposition, TwoLinkArmFrictionCoefficients) {
  CheckFrictionRecovery(sim::TwoLinkArm(), 21);
}

TEST(Decomposition, RandomThreeJointRobotFrictionCoefficients) {
  CheckFrictionRecovery(sim::RandomRobot(3, 7), 22);
}

}  // namespace
}  // namespace structgp
