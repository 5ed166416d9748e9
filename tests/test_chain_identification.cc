// A chain's kinematics identified from its torques (fit/chain_identification.h; the chain of
// given kinematics: rigid_body/dh_chain.h), against KDL: the URDF written for given kinematics spans the torques of the simulator's chain built
// from the same Denavit-Hartenberg parameters (and of chains that differ only where no torque
// shows it), and not of other kinematics; the search finds, from a slow noisy log of an arm
// in the other DH convention, a chain whose rbd+fri model predicts a fast log of another path
// as well as least squares on the true chain's regressor; an effect no chain makes (a cogging
// ripple) bends the chain unless it is given, and given it the log is explained to the noise;
// rounds of starts are drawn until two kept starts reach the best cost.

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <optional>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "structgp/core/row_subset.h"
#include "structgp/fit/chain_identification.h"
#include "structgp/fit/fit_model.h"
#include "structgp/model/model_spec.h"
#include "structgp/rigid_body/rigid_body_chain.h"
#include "structgp/sim/dataset.h"
#include "structgp/sim/friction.h"
#include "structgp/sim/robot.h"
#include "structgp/sim/trajectory.h"
#include "structgp/sim/urdf.h"
#include "ripple_log.h"

namespace structgp {
namespace {

// Random states (q, qd, qdd) of N joints.
Matrix RandomStates(int N, int rows, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  Matrix X(rows, 3 * N);
  for (Eigen::Index i = 0; i < X.rows(); ++i) {
    for (Eigen::Index k = 0; k < X.cols(); ++k) X(i, k) = u(rng);
  }
  return X;
}

Matrix Torques(const sim::Robot& robot, const Matrix& X) {
  const int N = robot.num_joints();
  Matrix Y(X.rows(), N);
  for (Eigen::Index i = 0; i < X.rows(); ++i) {
    const Vector x = X.row(i).transpose();
    Y.row(i) = robot.InverseDynamics(x.head(N), x.segment(N, N), x.segment(2 * N, N)).transpose();
  }
  return Y;
}

// RMS of the least-squares residual of Y on the chain's regressor, over the RMS of Y.
double RelativeResidual(const RigidBodyChain& chain, const Matrix& X, const Matrix& Y) {
  const int N = chain.num_joints();
  Matrix A(X.rows() * N, chain.num_parameters());
  Vector y(X.rows() * N);
  for (Eigen::Index i = 0; i < X.rows(); ++i) {
    const Vector x = X.row(i).transpose();
    A.middleRows(i * N, N) = chain.Regressor(x.head(N), x.segment(N, N), x.segment(2 * N, N));
    y.segment(i * N, N) = Y.row(i).transpose();
  }
  const Vector theta = A.colPivHouseholderQr().solve(y);
  return (y - A * theta).norm() / y.norm();
}

// The simulator's robot (modified DH) with the kinematics k of the layout of
// ChainKinematicNames, the redundant parameters set to `extra` (a_1, d_1, theta_N, d_N), and
// inertias of its own.
sim::Robot RobotOf(int N, const Vector& k, const Eigen::Vector4d& extra, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<sim::LinkParameters> links(static_cast<size_t>(N));
  for (auto& l : links) {
    l.mass = 0.5 + 2.0 * u(rng);
    l.com = Eigen::Vector3d(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5) * 0.2;
    l.inertia = Eigen::Vector3d(0.02 + 0.05 * u(rng), 0.02 + 0.05 * u(rng), 0.03 + 0.05 * u(rng))
                    .asDiagonal();
    l.armature = 0.01 * u(rng);
  }
  links[0].alpha = k[0];
  links[0].a = extra[0];
  links[0].d = extra[1];
  links[0].theta_offset = k[1];
  links[1].alpha = k[2];
  links[1].a = k[3];
  for (int i = 2; i <= N - 1; ++i) {
    const int o = 4 + 4 * (i - 2);
    links[static_cast<size_t>(i - 1)].theta_offset = k[o];
    links[static_cast<size_t>(i - 1)].d = k[o + 1];
    links[static_cast<size_t>(i)].alpha = k[o + 2];
    links[static_cast<size_t>(i)].a = k[o + 3];
  }
  links[static_cast<size_t>(N - 1)].theta_offset = extra[2];
  links[static_cast<size_t>(N - 1)].d = extra[3];
  return sim::Robot("dh", links, Eigen::Matrix3d::Identity(), sim::DhConvention::kModified);
}

TEST(ChainUrdf, SpansTheTorquesOfTheChainOfTheSameKinematicsAndNoOther) {
  for (int N : {2, 4, 6}) {
    SCOPED_TRACE("N = " + std::to_string(N));
    const int K = NumChainKinematicParameters(N);
    ASSERT_EQ(K, 4 * N - 4);
    ASSERT_EQ(static_cast<int>(ChainKinematicNames(N).size()), K);
    std::mt19937_64 rng(static_cast<std::uint64_t>(N));
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    Vector k(K);
    for (int i = 0; i < K; ++i) k[i] = u(rng);
    k[0] = 0.3;  // the first axis leans: gravity loads joint 1 too
    const Matrix X = RandomStates(N, 60, 7);
    const RigidBodyChain chain = RigidBodyChain::FromUrdfString(ChainUrdf(N, k), {}, "chain");
    ASSERT_EQ(chain.num_joints(), N);
    // The same kinematics, and with the parameters that change no torque set otherwise.
    for (const Eigen::Vector4d& extra :
         {Eigen::Vector4d(0.0, 0.0, 0.0, 0.0), Eigen::Vector4d(0.2, 0.3, 0.7, 0.1)}) {
      const Matrix Y = Torques(RobotOf(N, k, extra, 3), X);
      EXPECT_LT(RelativeResidual(chain, X, Y), 1e-9);
    }
    // Another twist or length anywhere: the torques are no longer spanned.
    for (int i : {0, 2, 3, K - 1}) {
      Vector other = k;
      other[i] += 0.3;
      const Matrix Y = Torques(RobotOf(N, other, Eigen::Vector4d::Zero(), 3), X);
      EXPECT_GT(RelativeResidual(chain, X, Y), 1e-4) << ChainKinematicNames(N)[static_cast<size_t>(i)];
    }
  }
}

TEST(ChainUrdf, RefusesAWrongSizeOrANonFiniteParameter) {
  EXPECT_THROW(ChainUrdf(3, Vector::Zero(7)), std::invalid_argument);
  Vector k = Vector::Zero(8);
  k[5] = std::nan("");
  EXPECT_THROW(ChainUrdf(3, k), std::invalid_argument);
  EXPECT_THROW(ChainUrdf(3, Vector::Zero(8), "a<b"), std::invalid_argument);
  EXPECT_EQ(NumChainKinematicParameters(1), 1);
  EXPECT_NO_THROW(RigidBodyChain::FromUrdfString(ChainUrdf(1, Vector::Constant(1, 0.4))));
}

// ChainKinematicsOfUrdf reads back exactly the numbers ChainUrdf wrote, and recognises no other
// document: one edited anywhere, or a URDF of the simulator's arms.
TEST(ChainUrdf, KinematicsReadBackFromItsOwnUrdfAndNoOther) {
  for (int N : {1, 2, 3, 7}) {
    SCOPED_TRACE("N = " + std::to_string(N));
    std::mt19937_64 rng(static_cast<std::uint64_t>(10 + N));
    std::uniform_real_distribution<double> u(-2.0, 2.0);
    Vector k(NumChainKinematicParameters(N));
    for (Eigen::Index i = 0; i < k.size(); ++i) k[i] = u(rng) / 3.0;  // not short decimals
    const std::string urdf = ChainUrdf(N, k, "arm-1.b");
    const std::optional<Vector> back = ChainKinematicsOfUrdf(urdf);
    ASSERT_TRUE(back.has_value());
    ASSERT_EQ(back->size(), k.size());
    for (Eigen::Index i = 0; i < k.size(); ++i) EXPECT_EQ((*back)[i], k[i]) << i;
    // Renamed, it is the same chain; edited (a mass, a joint origin, the comment's numbers, a
    // line added, cut short), another.
    EXPECT_TRUE(ChainKinematicsOfUrdf(ChainUrdf(N, k, "other")));
    auto edited = [&](const std::string& from, const std::string& to) {
      std::string e = urdf;
      const size_t at = e.find(from);
      EXPECT_NE(at, std::string::npos) << from;
      return at == std::string::npos ? e : e.replace(at, from.size(), to);
    };
    EXPECT_FALSE(ChainKinematicsOfUrdf(edited("<mass value=\"1\"/>", "<mass value=\"2\"/>")));
    EXPECT_FALSE(ChainKinematicsOfUrdf(edited("<origin xyz=\"", "<origin xyz=\"1")));
    EXPECT_FALSE(ChainKinematicsOfUrdf(edited("joint1 ", "joint1 1")));
    EXPECT_FALSE(ChainKinematicsOfUrdf(urdf + "\n"));
    EXPECT_FALSE(ChainKinematicsOfUrdf(urdf.substr(0, urdf.size() / 2)));
  }
  EXPECT_FALSE(ChainKinematicsOfUrdf(""));
  EXPECT_FALSE(ChainKinematicsOfUrdf(sim::ToUrdf(sim::ThreeLinkArm())));

  // A number written otherwise in its last digits (another libm) is the same document; one
  // changed in its sixth is not.
  const Vector k = Vector::LinSpaced(8, -0.7, 0.9) / 3.0;
  const std::string urdf = ChainUrdf(3, k);
  const size_t origin = urdf.find("<origin xyz=\"") + 13;
  const size_t end = urdf.find(' ', origin);
  const double x = std::stod(urdf.substr(origin, end - origin));
  auto with_x = [&](double value) {
    std::ostringstream text;
    text.precision(17);
    text << value;
    std::string e = urdf;
    return e.replace(origin, end - origin, text.str());
  };
  EXPECT_TRUE(ChainKinematicsOfUrdf(with_x(x + 1e-13 * std::max(1.0, std::abs(x)))));
  EXPECT_FALSE(ChainKinematicsOfUrdf(with_x(x + 1e-6)));

  // Read from a chain: whole and under the default gravity only.
  const RigidBodyChain whole = RigidBodyChain::FromUrdfString(urdf);
  ASSERT_TRUE(ChainKinematicsOf(whole));
  EXPECT_EQ(*ChainKinematicsOf(whole), *ChainKinematicsOfUrdf(urdf));
  UrdfOptions part;
  part.tip = "link2";
  EXPECT_FALSE(ChainKinematicsOf(RigidBodyChain::FromUrdfString(urdf, part)));
  UrdfOptions tilted;
  tilted.gravity = Eigen::Vector3d(0.0, -9.81, 0.0);
  EXPECT_FALSE(ChainKinematicsOf(RigidBodyChain::FromUrdfString(urdf, tilted)));
  EXPECT_FALSE(ChainKinematicsOf(sim::ToRigidBodyChain(sim::ThreeLinkArm())));
}

struct Log {
  Matrix X, Y;
};

// The three-link arm (standard DH, vertical waist) with viscous and Coulomb friction and 1%
// noise on each joint's RMS torque (noise_std returns it).
Log ThreeLinkLog(const sim::Trajectory& tr, std::uint64_t seed, Vector* noise_std) {
  const sim::Robot robot = sim::ThreeLinkArm();
  std::vector<sim::JointFriction> joints(3);
  for (int j = 0; j < 3; ++j) {
    joints[static_cast<size_t>(j)].coulomb = 0.3 + 0.1 * j;
    joints[static_cast<size_t>(j)].viscous = 0.2;
    joints[static_cast<size_t>(j)].smoothing_velocity = 0.01;
  }
  sim::SimulationOptions options;
  options.friction = sim::FrictionModel(joints);
  const sim::Dataset d = sim::Simulate(robot, tr, options);
  if (noise_std->size() == 0) {
    *noise_std = 0.01 * (d.Y.colwise().squaredNorm() / d.Y.rows()).cwiseSqrt().transpose();
  }
  Log log{d.X, d.Y};
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal;
  for (Eigen::Index i = 0; i < log.Y.rows(); ++i) {
    for (int j = 0; j < 3; ++j) log.Y(i, j) += (*noise_std)[j] * normal(rng);
  }
  return log;
}

// RMS per joint of (prediction - truth) over the noise.
Vector RmsOverNoise(const Matrix& prediction, const Matrix& Y, const Vector& noise) {
  return ((prediction - Y).colwise().squaredNorm() / Y.rows()).cwiseSqrt().transpose().cwiseQuotient(noise);
}

TEST(IdentifyChain, FindsAChainWhoseRbdModelPredictsFastMotionAsTheTrueChainDoes) {
  Vector noise;
  const Log slow = ThreeLinkLog(sim::ViaPoints(3, 30.0, 0.01, 30, 1.0, 1.0, 1), 11, &noise);
  const Log fast = ThreeLinkLog(sim::ViaPoints(3, 10.0, 0.01, 10, 2.5, 1.0, 2), 12, &noise);

  ChainIdentificationOptions options;
  options.starts = 12;  // screened: the 3 best searched to the end
  options.kept_starts = 3;
  options.search_rows = 300;
  const ChainIdentificationSummary id = IdentifyChain(slow.X, slow.Y, options);
  ASSERT_EQ(id.kinematics.size(), NumChainKinematicParameters(3));
  ASSERT_EQ(id.start_costs.size(), 3u);
  ASSERT_EQ(id.starts.size(), 3u);
  EXPECT_NE(std::find(id.starts.begin(), id.starts.end(), id.best_start), id.starts.end());
  EXPECT_GE(id.starts_at_best, 1);
  // The slow log explained to its noise.
  for (int j = 0; j < 3; ++j) {
    EXPECT_LT(id.residual_rms[j], 1.15 * noise[j]) << "joint " << j + 1;
    EXPECT_GT(id.torque_rms[j], 50.0 * noise[j]);
  }

  // rbd+fri on the identified URDF, as `structgp fit --model rbd+fri --urdf` fits it.
  FitOptions fit;
  fit.model.rigid_body = std::make_shared<const RigidBodyChain>(
      RigidBodyChain::FromUrdfString(id.urdf, {}, "identified.urdf"));
  const FittedModel model =
      FitModel(ParseModelSpec("rbd+fri"), slow.X, slow.Y, Vector(), fit);
  ASSERT_TRUE(model.summary.IsUsable()) << model.summary.message;
  Matrix mean(fast.X.rows(), 3);
  RobotModel::Workspace ws = model.model.MakeWorkspace();
  Vector m(3);
  for (Eigen::Index i = 0; i < fast.X.rows(); ++i) {
    ASSERT_EQ(model.model.Predict(fast.X.row(i).transpose(), m, ws), Status::kOk);
    mean.row(i) = m.transpose();
  }
  const Vector identified = RmsOverNoise(mean, fast.Y, noise);

  // The reference: least squares on the true chain's regressor and the true friction bases.
  const RigidBodyChain truth = sim::ToRigidBodyChain(sim::ThreeLinkArm());
  auto design = [&](const Matrix& X) {
    Matrix A = Matrix::Zero(X.rows() * 3, truth.num_parameters() + 6);
    for (Eigen::Index i = 0; i < X.rows(); ++i) {
      const Vector x = X.row(i).transpose();
      A.block(i * 3, 0, 3, truth.num_parameters()) =
          truth.Regressor(x.head(3), x.segment(3, 3), x.segment(6, 3));
      for (int j = 0; j < 3; ++j) {
        A(i * 3 + j, truth.num_parameters() + 2 * j) = x[3 + j];
        A(i * 3 + j, truth.num_parameters() + 2 * j + 1) = std::tanh(x[3 + j] / 0.01);
      }
    }
    return A;
  };
  const Matrix A = design(slow.X);
  Vector y(slow.X.rows() * 3);
  for (Eigen::Index i = 0; i < slow.X.rows(); ++i) y.segment(i * 3, 3) = slow.Y.row(i).transpose();
  const Vector theta = A.colPivHouseholderQr().solve(y);
  const Vector fast_y = design(fast.X) * theta;
  Matrix reference(fast.X.rows(), 3);
  for (Eigen::Index i = 0; i < fast.X.rows(); ++i) reference.row(i) = fast_y.segment(i * 3, 3).transpose();
  const Vector best = RmsOverNoise(reference, fast.Y, noise);
  for (int j = 0; j < 3; ++j) {
    EXPECT_LT(identified[j], 1.25 * best[j] + 0.1) << "joint " << j + 1 << ": identified chain "
                                                   << identified[j] << ", reference " << best[j];
  }
}

// The UR10's light wrist: at its own kinematics (given as the start) the least squares inside
// the search must explain the log to the noise on every joint, the 0.365 kg last link's
// included (a ridge relative to the mean column of the scaled design left 5 times the noise).
TEST(IdentifyChain, ExplainsALightWristToTheNoiseAtItsOwnKinematics) {
  const sim::Robot robot = sim::Ur10();
  const sim::Dataset d = sim::Simulate(robot, sim::ViaPoints(6, 20.0, 0.01, 20, 1.0, 1.0, 1));
  const Vector noise = 0.01 * (d.Y.colwise().squaredNorm() / d.Y.rows()).cwiseSqrt().transpose();
  Matrix Y = d.Y;
  std::mt19937_64 rng(5);
  std::normal_distribution<double> normal;
  for (Eigen::Index i = 0; i < Y.rows(); ++i) {
    for (int j = 0; j < 6; ++j) Y(i, j) += noise[j] * normal(rng);
  }
  // Universal Robots' standard-DH table (sim::Ur10) in the search's modified-DH layout.
  const double P = M_PI / 2;
  ChainIdentificationOptions options;
  options.initial_kinematics.resize(20);
  options.initial_kinematics << 0, 0, P, 0, 0, 0, 0, -0.612, 0, 0, 0, -0.5723, 0, 0.163941, P, 0,
      0, 0.1157, -P, 0;
  options.friction = false;
  options.starts = 1;
  options.kept_starts = 1;
  options.length_moves = false;
  options.refine_rows = 0;
  options.max_iterations = 5;
  const ChainIdentificationSummary id = IdentifyChain(d.X, Y, options);
  for (int j = 0; j < 6; ++j) EXPECT_LT(id.residual_rms[j], 1.1 * noise[j]) << "joint " << j + 1;
}

// The slow log of tests/ripple_log.h along 20 via points in 30 s (path and noise from seed).
testing::RippleLog TwoLinkRippleLog(std::uint64_t seed) {
  return testing::TwoLinkRippleLog(sim::ViaPoints(2, 30.0, 0.01, 20, 1.0, 1.0, seed), seed);
}

TEST(IdentifyChain, AnEffectNoChainMakesIsExplainedWhenGivenAndNotOtherwise) {
  const testing::RippleLog log = TwoLinkRippleLog(3);
  ChainIdentificationOptions options;
  options.starts = 8;
  options.kept_starts = 3;
  options.max_rounds = 1;
  const ChainIdentificationSummary without = IdentifyChain(log.XT(), log.Y, options);
  EXPECT_GT(without.residual_rms[1], 3.0 * log.noise[1]);  // the ripple is left over
  // ... and the summary says so: the residual's white noise is near the log's (the ripple's
  // own steps from row to row raise it a little), its RMS far above.
  EXPECT_NEAR(without.noise[1], log.noise[1], 0.25 * log.noise[1]);
  EXPECT_GT(without.residual_rms[1], 3.0 * without.noise[1]);
  options.effects = ParseEffectList("cogging@2:period=0.3");
  const ChainIdentificationSummary with = IdentifyChain(log.XT(), log.Y, options);
  for (int j = 0; j < 2; ++j) {
    EXPECT_LT(with.residual_rms[j], 1.1 * log.noise[j]) << "joint " << j + 1;
    EXPECT_NEAR(with.noise[j], log.noise[j], 0.1 * log.noise[j]) << "joint " << j + 1;
  }
  // The ripple's period wrong by a third: the effect does not fit, and the residual stays.
  options.effects = ParseEffectList("cogging@2:period=0.4");
  EXPECT_GT(IdentifyChain(log.XT(), log.Y, options).residual_rms[1], 3.0 * log.noise[1]);
  // The time column is read only by effects that use it: the same chain without it.
  options.effects = ParseEffectList("cogging@2:period=0.3");
  const ChainIdentificationSummary no_time =
      IdentifyChain(log.X, log.Y, options);
  EXPECT_EQ(no_time.urdf, with.urdf);
  // An effect that reads the time (a drift of the Coulomb level on joint 1) is accepted with it.
  options.effects = ParseEffectList("cogging@2:period=0.3,drift@1");
  const ChainIdentificationSummary drift = IdentifyChain(log.XT(), log.Y, options);
  EXPECT_LT(drift.residual_rms[1], 1.1 * log.noise[1]);
}

// Rounds: one start a round, so that a second round is drawn whenever the first start alone is
// at its own best; the rounds stop as soon as two kept starts reach the best cost.
TEST(IdentifyChain, DrawsRoundsOfStartsUntilTwoReachTheBestCost) {
  const testing::RippleLog log = TwoLinkRippleLog(4);
  ChainIdentificationOptions options;
  options.starts = 1;
  options.kept_starts = 1;
  options.max_rounds = 4;
  options.effects = ParseEffectList("cogging@2:period=0.3");
  options.length_moves = false;
  options.refine_rows = 0;
  const ChainIdentificationSummary id = IdentifyChain(log.XT(), log.Y, options);
  ASSERT_GE(id.rounds, 2);
  ASSERT_EQ(static_cast<int>(id.starts.size()), id.rounds);
  for (int r = 0; r < id.rounds; ++r) EXPECT_EQ(id.starts[static_cast<size_t>(r)], r);
  const double best = *std::min_element(id.start_costs.begin(), id.start_costs.end());
  int at_best = 0;
  for (double c : id.start_costs) at_best += c <= 1.01 * best ? 1 : 0;
  EXPECT_EQ(at_best, id.starts_at_best);
  // Stopped at the first round with two at the best, or at the last round.
  EXPECT_TRUE(id.starts_at_best >= 2 || id.rounds == options.max_rounds);
  if (id.rounds < options.max_rounds) {
    EXPECT_LE(id.start_costs.back(), 1.01 * best);  // the last round's start made the pair
  }
  // The same first round as a run of one round: rounds only add starts.
  options.max_rounds = 1;
  const ChainIdentificationSummary one = IdentifyChain(log.XT(), log.Y, options);
  EXPECT_EQ(one.rounds, 1);
  EXPECT_EQ(one.start_costs.front(), id.start_costs.front());
}

// A chain that leaves a smooth misfit (the ripple, not given as an effect) draws every round;
// the same search with the misfit rule off stops when two starts agree.
TEST(IdentifyChain, DrawsRoundsWhileTheChainLeavesMoreThanTheNoise) {
  const testing::RippleLog log = TwoLinkRippleLog(3);
  ChainIdentificationOptions options;
  options.starts = 4;
  options.kept_starts = 2;
  options.max_rounds = 2;
  options.length_moves = false;
  const ChainIdentificationSummary id = IdentifyChain(log.XT(), log.Y, options);
  EXPECT_GT(id.residual_rms[1], options.misfit_ratio * id.noise[1]);
  EXPECT_EQ(id.rounds, 2);
  EXPECT_EQ(id.starts.size(), 4u);
  options.misfit_ratio = std::numeric_limits<double>::infinity();
  const ChainIdentificationSummary agreed = IdentifyChain(log.XT(), log.Y, options);
  if (agreed.rounds == 1) {
    EXPECT_GE(agreed.starts_at_best, 2);
  }
  // The first round is the same search: its kept starts end at the same costs.
  EXPECT_EQ(agreed.start_costs[0], id.start_costs[0]);
  EXPECT_EQ(agreed.start_costs[1], id.start_costs[1]);
}

TEST(IdentifyChain, RefusesBadInputNamingIt) {
  const Matrix X = RandomStates(2, 40, 1);
  Matrix Y = Matrix::Ones(40, 2);
  auto message = [](const std::function<void()>& f) {
    try {
      f();
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no exception");
  };
  EXPECT_NE(message([&] { IdentifyChain(X.leftCols(5), Y); }).find("expected 3 N = 6"),
            std::string::npos);
  EXPECT_NE(message([&] { IdentifyChain(X.topRows(10), Y); }).find("10 input rows and 40"),
            std::string::npos);
  // The times apart: one per row.
  EXPECT_NE(message([&] { IdentifyChain(X, Vector::LinSpaced(39, 0.0, 1.0), Y); })
                .find("t has 39 entries, expected one per row of the states (40)"),
            std::string::npos);
  Matrix bad = X;
  bad(3, 1) = std::nan("");
  EXPECT_NE(message([&] { IdentifyChain(bad, Y); }).find("non-finite"), std::string::npos);
  Y.col(1).setZero();
  EXPECT_NE(message([&] { IdentifyChain(X, Y); }).find("joint 2 is zero"), std::string::npos);
  Y.col(1).setOnes();
  ChainIdentificationOptions o;
  o.starts = -1;
  EXPECT_NE(message([&] { IdentifyChain(X, Y, o); }).find("starts >= 0"), std::string::npos);
  o.starts = 0;  // a local search needs a start of its own
  EXPECT_NE(message([&] { IdentifyChain(X, Y, o); }).find("starts = 0 (a local search) needs "
                                                          "initial_kinematics"),
            std::string::npos);
  // 20 rows of 2 joints: 40 torques for 28 linear parameters (with friction).
  EXPECT_NE(message([&] { IdentifyChain(X.topRows(20), Y.topRows(20)); })
                .find("40 torques for 28 linear parameters: at least 28 rows"),
            std::string::npos);
  o = ChainIdentificationOptions();
  o.max_rounds = 0;
  EXPECT_NE(message([&] { IdentifyChain(X, Y, o); }).find("max_rounds >= 1"), std::string::npos);
  o = ChainIdentificationOptions();
  o.misfit_ratio = std::nan("");
  EXPECT_NE(message([&] { IdentifyChain(X, Y, o); }).find("misfit_ratio > 0"), std::string::npos);
  // Effects: a joint the robot lacks, the time an effect needs, the bases counted as unknowns.
  o = ChainIdentificationOptions();
  o.effects = ParseEffectList("cogging@3:period=0.3");
  EXPECT_NE(message([&] { IdentifyChain(X, Y, o); }).find("names joint 3, but the robot has 2"),
            std::string::npos);
  o.effects = ParseEffectList("drift@1");
  EXPECT_NE(message([&] { IdentifyChain(X, Y, o); }).find("uses the time: X needs the time t"),
            std::string::npos);
  o.effects = ParseEffectList("cogging:period=0.3");  // 2 bases on each joint: 32 unknowns
  EXPECT_NE(message([&] { IdentifyChain(X.topRows(30), Y.topRows(30), o); })
                .find("60 torques for 32 linear parameters"),
            std::string::npos);
  EXPECT_NE(message([&] { IdentifyChain(Matrix::Zero(40, 8), Y); }).find("or 3 N + 1 with the time"),
            std::string::npos);
  o = ChainIdentificationOptions();
  o.robot_name = "a\"b";
  EXPECT_NE(message([&] { IdentifyChain(X, Y, o); }).find("letters, digits"), std::string::npos);
}

}  // namespace
}  // namespace structgp
