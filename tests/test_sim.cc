// Tests of the simulated robots, friction, trajectories and data sets.
//
// References independent of KDL's dynamics: the analytic pendulum, the mass matrix from the
// kinetic energy of each link and the gravity torques from the potential energy, both
// computed with a separate Denavit-Hartenberg forward-kinematics routine below.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <iostream>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "structgp/sim/dataset.h"
#include "structgp/sim/friction.h"
#include "structgp/sim/robot.h"
#include "structgp/sim/trajectory.h"

namespace structgp {
namespace sim {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kEps = 2.220446049250313e-16;  // double machine epsilon

// Fixed seeds of every randomised test; printed so that a failure can be replayed.
const std::vector<std::uint64_t> kSeeds = {1, 2, 3, 42, 2024};

void PrintSeeds(const char* test) {
  std::cout << "[ seeds    ] " << test << ":";
  for (std::uint64_t seed : kSeeds) std::cout << ' ' << seed;
  std::cout << '\n';
}

std::string Trace(const Robot& robot, std::uint64_t seed) {
  return "robot " + robot.name() + ", state seed " + std::to_string(seed);
}

// Every robot the tests run on: the fixed ones and random ones with N = 1..7.
std::vector<Robot> AllRobots() {
  std::vector<Robot> robots = {TwoLinkArm(), ThreeLinkArm(), Puma560(), Panda(), Ur10()};
  for (std::uint64_t seed : kSeeds) {
    for (int n = 1; n <= 7; ++n) robots.push_back(RandomRobot(n, seed));
  }
  return robots;
}

struct State {
  Eigen::VectorXd q, qd, qdd;
};

State RandomState(int n, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> angle(-kPi, kPi);
  std::uniform_real_distribution<double> rate(-3.0, 3.0);
  State s{Eigen::VectorXd(n), Eigen::VectorXd(n), Eigen::VectorXd(n)};
  for (int j = 0; j < n; ++j) {
    s.q(j) = angle(rng);
    s.qd(j) = rate(rng);
    s.qdd(j) = 3.0 * rate(rng);
  }
  return s;
}

// ---- an independent kinematic model ----------------------------------------------------

struct LinkPose {
  Eigen::Vector3d origin;    // o_i in base frame 0
  Eigen::Matrix3d rotation;  // R_i: link frame i in base frame 0
};

struct Kinematics {
  std::vector<LinkPose> poses;       // entry 0 the base frame, entry i link frame i
  std::vector<Eigen::Vector3d> axes;    // joint i+1's axis, base frame 0
  std::vector<Eigen::Vector3d> points;  // a point on it
};

// DH forward kinematics. Standard: T_i = T_{i-1} Rz(q_i + theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i),
// joint i turns about z_{i-1}. Modified: T_i = T_{i-1} Rx(alpha_i) Tx(a_i) Rz(q_i + theta_i)
// Tz(d_i), joint i turns about z_i.
Kinematics ForwardKinematics(const Robot& robot, const Eigen::VectorXd& q) {
  const std::vector<LinkParameters>& links = robot.links();
  const bool modified = robot.convention() == DhConvention::kModified;
  Kinematics k;
  k.poses.resize(links.size() + 1);
  k.poses[0] = {Eigen::Vector3d::Zero(), Eigen::Matrix3d::Identity()};
  for (std::size_t i = 0; i < links.size(); ++i) {
    const LinkParameters& l = links[i];
    const Eigen::Matrix3d rz =
        Eigen::AngleAxisd(q(i) + l.theta_offset, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    const Eigen::Matrix3d rx =
        Eigen::AngleAxisd(l.alpha, Eigen::Vector3d::UnitX()).toRotationMatrix();
    const LinkPose& previous = k.poses[i];
    LinkPose& pose = k.poses[i + 1];
    if (modified) {
      const Eigen::Matrix3d r = previous.rotation * rx;
      pose.origin = previous.origin + previous.rotation * Eigen::Vector3d(l.a, 0.0, 0.0) +
                    r * Eigen::Vector3d(0.0, 0.0, l.d);
      pose.rotation = r * rz;
      k.axes.push_back(pose.rotation.col(2));
      k.points.push_back(pose.origin);
    } else {
      k.axes.push_back(previous.rotation.col(2));
      k.points.push_back(previous.origin);
      const Eigen::Matrix3d r = previous.rotation * rz;
      pose.origin = previous.origin + r * Eigen::Vector3d(l.a, 0.0, l.d);
      pose.rotation = r * rx;
    }
  }
  return k;
}

// Geometric Jacobians (3 x N each) of the centre of mass of link i: linear velocity of the
// centre of mass and angular velocity of the link, both in base frame 0.
void ComJacobians(const std::vector<LinkParameters>& links, const Kinematics& k, int i,
                  Eigen::MatrixXd* jv, Eigen::MatrixXd* jw) {
  const int n = static_cast<int>(links.size());
  const Eigen::Vector3d com = k.poses[i + 1].origin + k.poses[i + 1].rotation * links[i].com;
  jv->setZero(3, n);
  jw->setZero(3, n);
  for (int j = 0; j <= i; ++j) {
    jv->col(j) = k.axes[j].cross(com - k.points[j]);
    jw->col(j) = k.axes[j];
  }
}

// M(q) = sum_i m_i Jv_i^T Jv_i + Jw_i^T (R_i I_i R_i^T) Jw_i + diag(armature): the
// quadratic form of twice the kinetic energy.
Eigen::MatrixXd ReferenceMassMatrix(const Robot& robot, const Eigen::VectorXd& q) {
  const auto& links = robot.links();
  const Kinematics k = ForwardKinematics(robot, q);
  const int n = robot.num_joints();
  Eigen::MatrixXd mass = Eigen::MatrixXd::Zero(n, n);
  Eigen::MatrixXd jv, jw;
  for (int i = 0; i < n; ++i) {
    ComJacobians(links, k, i, &jv, &jw);
    const Eigen::Matrix3d& r = k.poses[i + 1].rotation;
    mass += links[i].mass * jv.transpose() * jv +
            jw.transpose() * (r * links[i].inertia * r.transpose()) * jw;
    mass(i, i) += links[i].armature;
  }
  return mass;
}

// G(q) = dV/dq with V = -sum_i m_i g . c_i: G = -sum_i m_i Jv_i^T g.
Eigen::VectorXd ReferenceGravity(const Robot& robot, const Eigen::VectorXd& q) {
  const auto& links = robot.links();
  const Kinematics k = ForwardKinematics(robot, q);
  const int n = robot.num_joints();
  Eigen::VectorXd gravity = Eigen::VectorXd::Zero(n);
  Eigen::MatrixXd jv, jw;
  for (int i = 0; i < n; ++i) {
    ComJacobians(links, k, i, &jv, &jw);
    gravity -= links[i].mass * jv.transpose() * robot.gravity_in_base();
  }
  return gravity;
}

// ---- robots ------------------------------------------------------------------------------

TEST(Robot, ComponentsSumToRecursiveNewtonEuler) {
  PrintSeeds("ComponentsSumToRecursiveNewtonEuler");
  for (const Robot& robot : AllRobots()) {
    for (std::uint64_t seed : kSeeds) {
      SCOPED_TRACE(Trace(robot, seed));
      std::mt19937_64 rng(seed);
      const State s = RandomState(robot.num_joints(), rng);
      const Eigen::VectorXd tau = robot.InverseDynamics(s.q, s.qd, s.qdd);
      const DynamicsComponents c = robot.Components(s.q, s.qd, s.qdd);
      const double scale = std::max(1.0, tau.cwiseAbs().maxCoeff());
      EXPECT_LE((c.inertial + c.coriolis + c.gravity - tau).cwiseAbs().maxCoeff(), 1e-9 * scale);
      // Each term alone is the inverse dynamics with the other inputs switched off.
      const Eigen::VectorXd zero = Eigen::VectorXd::Zero(robot.num_joints());
      const Eigen::VectorXd tau_at_rest = robot.InverseDynamics(s.q, zero, zero);
      EXPECT_LE((c.gravity - tau_at_rest).cwiseAbs().maxCoeff(), 1e-9 * scale);
    }
  }
}

TEST(Robot, ForwardDynamicsInvertsInverseDynamics) {
  PrintSeeds("ForwardDynamicsInvertsInverseDynamics");
  for (const Robot& robot : AllRobots()) {
    for (std::uint64_t seed : kSeeds) {
      SCOPED_TRACE(Trace(robot, seed));
      std::mt19937_64 rng(seed + 100);
      const State s = RandomState(robot.num_joints(), rng);
      const Eigen::VectorXd tau = robot.InverseDynamics(s.q, s.qd, s.qdd);
      const Eigen::VectorXd qdd = robot.ForwardDynamics(s.q, s.qd, tau);
      // Error of a Cholesky solve: about cond(M) * eps * |qdd|, with a safety factor.
      const Eigen::MatrixXd mass = robot.MassMatrix(s.q);
      const Eigen::VectorXd eig =
          Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(mass).eigenvalues();
      const double cond = eig.maxCoeff() / eig.minCoeff();
      const double tol =
          1e3 * robot.num_joints() * cond * kEps * std::max(1.0, s.qdd.cwiseAbs().maxCoeff());
      EXPECT_LE((qdd - s.qdd).cwiseAbs().maxCoeff(), tol) << "cond(M) = " << cond;
    }
  }
}

TEST(Robot, MassMatrixIsSymmetricPositiveDefinite) {
  PrintSeeds("MassMatrixIsSymmetricPositiveDefinite");
  for (const Robot& robot : AllRobots()) {
    for (std::uint64_t seed : kSeeds) {
      SCOPED_TRACE(Trace(robot, seed));
      std::mt19937_64 rng(seed + 200);
      const State s = RandomState(robot.num_joints(), rng);
      const Eigen::MatrixXd mass = robot.MassMatrix(s.q);
      const double norm = mass.cwiseAbs().maxCoeff();
      EXPECT_LE((mass - mass.transpose()).cwiseAbs().maxCoeff(), 1e-12 * norm);
      EXPECT_EQ(Eigen::LLT<Eigen::MatrixXd>(mass).info(), Eigen::Success);
      const Eigen::VectorXd eig =
          Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(mass).eigenvalues();
      EXPECT_GT(eig.minCoeff(), 1e-10 * eig.maxCoeff());
    }
  }
}

TEST(Robot, MassMatrixMatchesKineticEnergy) {
  PrintSeeds("MassMatrixMatchesKineticEnergy");
  for (const Robot& robot : AllRobots()) {
    for (std::uint64_t seed : kSeeds) {
      SCOPED_TRACE(Trace(robot, seed));
      std::mt19937_64 rng(seed + 300);
      const State s = RandomState(robot.num_joints(), rng);
      const Eigen::MatrixXd mass = robot.MassMatrix(s.q);
      const Eigen::MatrixXd reference = ReferenceMassMatrix(robot, s.q);
      EXPECT_LE((mass - reference).cwiseAbs().maxCoeff(),
                1e-12 * std::max(1.0, reference.cwiseAbs().maxCoeff()));
    }
  }
}

TEST(Robot, GravityMatchesPotentialEnergy) {
  PrintSeeds("GravityMatchesPotentialEnergy");
  for (const Robot& robot : AllRobots()) {
    for (std::uint64_t seed : kSeeds) {
      SCOPED_TRACE(Trace(robot, seed));
      std::mt19937_64 rng(seed + 400);
      const State s = RandomState(robot.num_joints(), rng);
      const Eigen::VectorXd zero = Eigen::VectorXd::Zero(robot.num_joints());
      const Eigen::VectorXd gravity = robot.Components(s.q, zero, zero).gravity;
      const Eigen::VectorXd reference = ReferenceGravity(robot, s.q);
      EXPECT_LE((gravity - reference).cwiseAbs().maxCoeff(),
                1e-12 * std::max(1.0, reference.cwiseAbs().maxCoeff()));
    }
  }
}

TEST(Robot, RandomInertiasArePhysicallyValid) {
  PrintSeeds("RandomInertiasArePhysicallyValid");
  for (std::uint64_t seed : kSeeds) {
    for (int n = 1; n <= 7; ++n) {
      const Robot robot = RandomRobot(n, seed);
      SCOPED_TRACE(robot.name());
      ASSERT_EQ(robot.num_joints(), n);
      for (const LinkParameters& link : robot.links()) {
        EXPECT_GE(link.mass, 0.5);
        EXPECT_LE(link.mass, 5.0);
        EXPECT_LE(link.com.cwiseAbs().maxCoeff(), 0.15);
        const Eigen::Matrix3d& in = link.inertia;
        EXPECT_EQ(in, in.transpose());
        const Eigen::Vector3d p =
            Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(in).eigenvalues();  // ascending
        const double tol = 1e-12 * p(2);
        EXPECT_GT(p(0), 0.0);
        // Triangle inequalities; with ascending moments, p0 + p1 >= p2 implies the others.
        EXPECT_GE(p(0) + p(1), p(2) - tol);
        // Moments of a box with edges in [0.04, 0.4] m.
        EXPECT_GE(p(0), link.mass * 2 * 0.04 * 0.04 / 12 - tol);
        EXPECT_LE(p(2), link.mass * 2 * 0.4 * 0.4 / 12 + tol);
      }
    }
  }
}

TEST(Robot, RandomRobotIsReproducibleAndSeedDependent) {
  const Robot a = RandomRobot(4, 7);
  const Robot b = RandomRobot(4, 7);
  const Robot c = RandomRobot(4, 8);
  EXPECT_EQ(a.name(), "random4_seed7");
  for (int i = 0; i < 4; ++i) {
    EXPECT_EQ(a.links()[i].a, b.links()[i].a);
    EXPECT_EQ(a.links()[i].inertia, b.links()[i].inertia);
    EXPECT_NE(a.links()[i].mass, c.links()[i].mass);
  }
}

// A single link of length l turning about a horizontal axis, angle q measured from the
// horizontal upwards: tau = I_O qdd + m g r cos(q), I_O the inertia about the axis and r
// the distance of the centre of mass from it.
Robot Pendulum(double mass, double length, bool rod) {
  LinkParameters link;
  link.a = length;
  link.mass = mass;
  if (rod) {  // uniform thin rod from the axis to the tip, along x_1
    link.com = Eigen::Vector3d(-0.5 * length, 0.0, 0.0);
    link.inertia = Eigen::Vector3d(0.0, 1.0, 1.0).asDiagonal();
    link.inertia *= mass * length * length / 12.0;
  }  // else a point mass at the tip: com = 0, inertia = 0
  const Eigen::Matrix3d horizontal_axis =
      Eigen::AngleAxisd(0.5 * kPi, Eigen::Vector3d::UnitX()).toRotationMatrix();
  return Robot(rod ? "rod_pendulum" : "point_pendulum", {link}, horizontal_axis);
}

TEST(Robot, PendulumMatchesAnalyticTorque) {
  PrintSeeds("PendulumMatchesAnalyticTorque");
  const double m = 1.7, l = 0.55, g = kStandardGravity;
  const Robot point = Pendulum(m, l, /*rod=*/false);
  const Robot rod = Pendulum(m, l, /*rod=*/true);
  for (std::uint64_t seed : kSeeds) {
    SCOPED_TRACE("state seed " + std::to_string(seed));
    std::mt19937_64 rng(seed + 500);
    const State s = RandomState(1, rng);
    const double q = s.q(0), qdd = s.qdd(0);
    const double point_tau = m * l * l * qdd + m * g * l * std::cos(q);
    const double rod_tau = m * l * l / 3.0 * qdd + m * g * 0.5 * l * std::cos(q);
    EXPECT_NEAR(point.InverseDynamics(s.q, s.qd, s.qdd)(0), point_tau, 1e-12 * 20.0);
    EXPECT_NEAR(rod.InverseDynamics(s.q, s.qd, s.qdd)(0), rod_tau, 1e-12 * 20.0);
    // A single revolute joint has no Coriolis or centrifugal torque.
    EXPECT_NEAR(rod.Components(s.q, s.qd, s.qdd).coriolis(0), 0.0, 1e-12);
  }
}

TEST(Robot, TwoLinkArmGravityAtHorizontalStretch) {
  // Statics at q = 0 (both links horizontal): joint 1 carries both links, joint 2 link 2.
  const Robot arm = TwoLinkArm();
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(2);
  const Eigen::VectorXd tau = arm.InverseDynamics(zero, zero, zero);
  const double g = kStandardGravity;
  EXPECT_NEAR(tau(0), g * (2.0 * 0.2 + 1.0 * (0.4 + 0.15)), 1e-12);
  EXPECT_NEAR(tau(1), g * 1.0 * 0.15, 1e-12);
  // Hanging straight down (q1 = -pi/2, q2 = 0) needs no torque.
  const Eigen::VectorXd down = Eigen::Vector2d(-0.5 * kPi, 0.0);
  EXPECT_LE(arm.InverseDynamics(down, zero, zero).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(Robot, Puma560Parameters) {
  const Robot puma = Puma560();
  EXPECT_EQ(puma.name(), "puma560");
  ASSERT_EQ(puma.num_joints(), 6);
  double total_mass = 0.0;
  for (const LinkParameters& link : puma.links()) total_mass += link.mass;
  EXPECT_NEAR(total_mass, 17.4 + 4.8 + 0.82 + 0.34 + 0.09, 1e-12);
  // Armature of joint 1: 200e-6 kg m^2 rotor, gear ratio 62.6111.
  EXPECT_NEAR(puma.links()[0].armature, 200e-6 * 62.6111 * 62.6111, 1e-12);
  // At q = 0 joint 1's inertia is I_yy of link 1 + armature + what links 2..6 add.
  const Eigen::MatrixXd mass = puma.MassMatrix(Eigen::VectorXd::Zero(6));
  EXPECT_GT(mass(0, 0), 0.35 + puma.links()[0].armature);
  // Joint 1 turns about the vertical: no gravity torque in any pose.
  std::mt19937_64 rng(kSeeds[0]);
  const State s = RandomState(6, rng);
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(6);
  EXPECT_NEAR(puma.InverseDynamics(s.q, zero, zero)(0), 0.0, 1e-12);
}

TEST(Robot, RejectsBadInput) {
  const Robot arm = TwoLinkArm();
  const Eigen::VectorXd two = Eigen::VectorXd::Zero(2), three = Eigen::VectorXd::Zero(3);
  EXPECT_THROW(arm.InverseDynamics(three, two, two), std::invalid_argument);
  EXPECT_THROW(arm.Components(two, three, two), std::invalid_argument);
  EXPECT_THROW(arm.MassMatrix(three), std::invalid_argument);
  EXPECT_THROW(arm.ForwardDynamics(two, two, three), std::invalid_argument);
  EXPECT_THROW(RandomRobot(0, 1), std::invalid_argument);
  EXPECT_THROW(RandomRobot(8, 1), std::invalid_argument);
  EXPECT_THROW(Robot("empty", {}), std::invalid_argument);
  LinkParameters bad;
  bad.mass = -1.0;
  EXPECT_THROW(Robot("bad", {bad}), std::invalid_argument);
  bad.mass = 1.0;
  bad.armature = -0.1;
  EXPECT_THROW(Robot("bad", {bad}), std::invalid_argument);
  bad.armature = 0.0;
  bad.inertia = Eigen::Vector3d(1.0, 1.0, -0.5).asDiagonal();
  EXPECT_THROW(Robot("bad", {bad}), std::invalid_argument);
  bad.inertia.setZero();
  EXPECT_THROW(Robot("bad", {bad}, 2.0 * Eigen::Matrix3d::Identity()), std::invalid_argument);
  // A joint that moves no mass has a singular mass matrix: reported, not a silent NaN.
  LinkParameters massless;
  const Robot singular("massless", {massless});
  const Eigen::VectorXd one = Eigen::VectorXd::Zero(1);
  EXPECT_THROW(singular.ForwardDynamics(one, one, one), std::runtime_error);
}

// ---- friction ----------------------------------------------------------------------------

TEST(Friction, CoulombViscousStribeck) {
  JointFriction f;
  f.coulomb = 2.0;
  f.viscous = 0.5;
  const FrictionModel plain = FrictionModel::Uniform(2, f);
  EXPECT_EQ(plain.num_joints(), 2);
  EXPECT_DOUBLE_EQ(plain.JointTorque(0, 3.0), 2.0 + 1.5);
  EXPECT_DOUBLE_EQ(plain.JointTorque(1, -3.0), -2.0 - 1.5);
  EXPECT_EQ(plain.JointTorque(0, 0.0), 0.0);
  const Eigen::VectorXd tau = plain.Torque(Eigen::Vector2d(1.0, -2.0));
  EXPECT_DOUBLE_EQ(tau(0), 2.5);
  EXPECT_DOUBLE_EQ(tau(1), -3.0);

  f.stribeck = 1.0;
  f.stribeck_velocity = 0.2;
  const FrictionModel stribeck = FrictionModel::Uniform(1, f);
  // Just above zero velocity the breakaway torque is F_c + F_s; far above, F_c + F_v qd.
  EXPECT_NEAR(stribeck.JointTorque(0, 1e-9), 3.0, 1e-8);
  EXPECT_NEAR(stribeck.JointTorque(0, 4.0), 2.0 + 0.5 * 4.0, 1e-12);
  EXPECT_NEAR(stribeck.JointTorque(0, 0.2), 2.0 + 0.1 + std::exp(-1.0), 1e-12);
  // Dissipative and odd.
  for (double v : {-2.0, -0.3, -0.01, 0.01, 0.3, 2.0}) {
    EXPECT_GT(stribeck.JointTorque(0, v) * v, 0.0);
    EXPECT_DOUBLE_EQ(stribeck.JointTorque(0, -v), -stribeck.JointTorque(0, v));
  }

  f.smoothing_velocity = 0.05;
  const FrictionModel smooth = FrictionModel::Uniform(1, f);
  EXPECT_EQ(smooth.JointTorque(0, 0.0), 0.0);
  EXPECT_NEAR(smooth.JointTorque(0, 0.05), (2.0 + std::exp(-0.0625)) * std::tanh(1.0) + 0.025,
              1e-12);
}

TEST(Friction, Puma560Values) {
  const FrictionModel friction = Puma560Friction();
  ASSERT_EQ(friction.num_joints(), 6);
  // Joint 1: B G^2 = 1.48e-3 * 62.6111^2, |G| (0.395 + 0.435) / 2.
  EXPECT_NEAR(friction.joints()[0].viscous, 1.48e-3 * 62.6111 * 62.6111, 1e-12);
  EXPECT_NEAR(friction.joints()[0].coulomb, 62.6111 * 0.415, 1e-12);
  EXPECT_NEAR(friction.joints()[5].coulomb, 76.686 * 0.5 * (3.96e-3 + 10.5e-3), 1e-12);
  EXPECT_EQ(Puma560Friction(0.01).joints()[3].smoothing_velocity, 0.01);
}

TEST(Friction, RejectsBadParameters) {
  EXPECT_THROW(FrictionModel({}), std::invalid_argument);
  JointFriction f;
  f.coulomb = -1.0;
  EXPECT_THROW(FrictionModel::Uniform(1, f), std::invalid_argument);
  f.coulomb = 1.0;
  f.stribeck_velocity = 0.0;
  EXPECT_THROW(FrictionModel::Uniform(1, f), std::invalid_argument);
  f.stribeck_velocity = 0.1;
  EXPECT_THROW(FrictionModel::Uniform(2, f).Torque(Eigen::VectorXd::Zero(3)),
               std::invalid_argument);
}

// ---- trajectories ------------------------------------------------------------------------

// max |f'''| estimated by third differences over the samples where smooth[i] and
// smooth[i + 1] (an empty mask means all).
double MaxThirdDerivative(const Eigen::MatrixXd& f, double h, const std::vector<bool>& smooth) {
  double third = 0.0;
  for (Eigen::Index i = 1; i + 2 < f.rows(); ++i) {
    if (!smooth.empty() && (!smooth[i] || !smooth[i + 1])) continue;
    const Eigen::VectorXd d3 =
        (f.row(i + 2) - 3.0 * f.row(i + 1) + 3.0 * f.row(i) - f.row(i - 1)) / (h * h * h);
    third = std::max(third, d3.cwiseAbs().maxCoeff());
  }
  return third;
}

// Checks that d/dt of `f` (column-wise samples at spacing h) matches `df` by central
// differences, at every sample i with smooth[i] (an empty mask means all). Error bound:
// h^2/6 max|f'''| (truncation) plus rounding ~eps |f| / h, with a factor 2 of safety;
// f''' is estimated by third differences of f itself over the smooth samples, so the bound
// does not depend on the derivative under test. `smooth` excludes the samples whose stencils
// straddle a via point, where the jerk jumps and neither estimate is valid.
void ExpectDerivative(const Eigen::MatrixXd& f, const Eigen::MatrixXd& df, double h,
                      const std::vector<bool>& smooth, const char* what) {
  const Eigen::Index m = f.rows();
  ASSERT_GE(m, 4);
  auto is_smooth = [&](Eigen::Index i) { return smooth.empty() || smooth[i]; };
  const double third = MaxThirdDerivative(f, h, smooth);
  const double tol = 2.0 * (h * h / 6.0 * third + 4.0 * kEps * f.cwiseAbs().maxCoeff() / h) + 1e-12;
  double error = 0.0;
  Eigen::Index checked = 0;
  for (Eigen::Index i = 1; i + 1 < m; ++i) {
    if (!is_smooth(i)) continue;
    const Eigen::VectorXd central = (f.row(i + 1) - f.row(i - 1)) / (2.0 * h);
    error = std::max(error, (central - df.row(i).transpose()).cwiseAbs().maxCoeff());
    ++checked;
  }
  EXPECT_GT(checked, m / 2) << what;
  EXPECT_LE(error, tol) << what << ": max error " << error << ", bound " << tol;
}

// Mask of the samples t_i = i h whose 5-point neighbourhood [t_i - 2h, t_i + 2h] contains no
// via time k * segment_duration.
std::vector<bool> AwayFromVias(Eigen::Index m, double h, double segment_duration) {
  std::vector<bool> smooth(m, true);
  for (Eigen::Index i = 0; i < m; ++i) {
    const double t = static_cast<double>(i) * h;
    const double nearest = std::round(t / segment_duration) * segment_duration;
    smooth[i] = std::abs(t - nearest) > 2.0 * h * (1.0 + 1e-9);
  }
  return smooth;
}

TEST(Trajectory, ViaPointsDerivativesMatchFiniteDifferences) {
  PrintSeeds("ViaPointsDerivativesMatchFiniteDifferences");
  const double h = 1e-4;
  for (std::uint64_t seed : kSeeds) {
    for (ViaVelocity mode : {ViaVelocity::kStop, ViaVelocity::kContinuous}) {
      for (double speed : {0.5, 3.0}) {
        SCOPED_TRACE("seed " + std::to_string(seed) + ", speed " + std::to_string(speed) +
                     (mode == ViaVelocity::kStop ? ", stop" : ", continuous"));
        const Trajectory tr = ViaPoints(3, 2.0, h, 4, speed, 1.5, seed, mode);
        ASSERT_EQ(tr.num_samples(), 20000);
        const std::vector<bool> smooth = AwayFromVias(20000, h, 2.0 / (4 * speed));
        ASSERT_EQ(tr.num_joints(), 3);
        if (mode == ViaVelocity::kStop) {  // monotone segments: stays within the vias' box
          EXPECT_LE(tr.q.cwiseAbs().maxCoeff(), 1.5 + 1e-12);
        }
        ExpectDerivative(tr.q, tr.qd, h, smooth, "qd");
        ExpectDerivative(tr.qd, tr.qdd, h, smooth, "qdd");
        // Continuity across the via points too: by the mean value theorem every step of qd
        // is at most h max|qdd|, every step of qdd at most h max|jerk| (1% slack for the
        // maxima between samples). A jump at a via point would break these.
        const Eigen::Index m = tr.num_samples();
        const double qd_step =
            (tr.qd.bottomRows(m - 1) - tr.qd.topRows(m - 1)).cwiseAbs().maxCoeff();
        const double qdd_step =
            (tr.qdd.bottomRows(m - 1) - tr.qdd.topRows(m - 1)).cwiseAbs().maxCoeff();
        EXPECT_LE(qd_step, 1.01 * h * tr.qdd.cwiseAbs().maxCoeff());
        EXPECT_LE(qdd_step, 1.01 * h * MaxThirdDerivative(tr.q, h, smooth));
      }
    }
  }
}

TEST(Trajectory, ViaPointsStopsAtViasAndLoops) {
  // 4 vias, duration 2 s, speed 1: segments of 0.5 s; the loop closes at t = 2 s.
  const double dt = 0.01;
  const double duration = 2.0 + 0.5 * dt;  // so that t = 2 s is sampled
  const Trajectory tr = ViaPoints(2, duration, dt, 4, duration / 2.0, 1.0, 5, ViaVelocity::kStop);
  for (Eigen::Index i : {0, 50, 100, 150, 200}) {
    EXPECT_NEAR(tr.t(i), 0.01 * i, 1e-12);
    EXPECT_LE(tr.qd.row(i).cwiseAbs().maxCoeff(), 1e-9);
    EXPECT_LE(tr.qdd.row(i).cwiseAbs().maxCoeff(), 1e-9);
  }
  EXPECT_LE((tr.q.row(200) - tr.q.row(0)).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_GT(tr.qd.cwiseAbs().maxCoeff(), 0.1);  // it does move in between
}

TEST(Trajectory, SpeedScaleRetimesTheSamePath) {
  // Same duration, speed s: q_fast(t) = q_slow(s t), qd_fast = s qd_slow,
  // qdd_fast = s^2 qdd_slow. Sampling the fast one s times as densely lines the samples up;
  // its first loop (the first m_slow samples) is the whole slow trajectory.
  const double s = 4.0, dt = 0.04;
  for (ViaVelocity mode : {ViaVelocity::kStop, ViaVelocity::kContinuous}) {
    const Trajectory slow = ViaPoints(3, 2.0, dt, 5, 1.0, 2.0, 11, mode);
    const Trajectory fast = ViaPoints(3, 2.0, dt / s, 5, s, 2.0, 11, mode);
    const Eigen::Index m = slow.num_samples();
    ASSERT_EQ(m, 50);
    ASSERT_EQ(fast.num_samples(), 4 * m);
    EXPECT_LE((fast.q.topRows(m) - slow.q).cwiseAbs().maxCoeff(), 1e-9);
    EXPECT_LE((fast.qd.topRows(m) - s * slow.qd).cwiseAbs().maxCoeff(), 1e-9 * s);
    EXPECT_LE((fast.qdd.topRows(m) - s * s * slow.qdd).cwiseAbs().maxCoeff(), 1e-9 * s * s);
    // Later loops repeat the first.
    EXPECT_LE((fast.q.middleRows(m, m) - slow.q).cwiseAbs().maxCoeff(), 1e-9);
  }
}

TEST(Trajectory, SumOfSinesDerivativesAndBounds) {
  PrintSeeds("SumOfSinesDerivativesAndBounds");
  const double h = 1e-4;
  for (std::uint64_t seed : kSeeds) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    const Trajectory tr = SumOfSines(4, 1.0, h, 5, 0.5, 1.2, seed);
    ASSERT_EQ(tr.num_samples(), 10000);
    EXPECT_LE(tr.q.cwiseAbs().maxCoeff(), 1.2 + 1e-12);
    ExpectDerivative(tr.q, tr.qd, h, {}, "qd");
    ExpectDerivative(tr.qd, tr.qdd, h, {}, "qdd");
  }
  // Periodic with period 1 / f0.
  const Trajectory period = SumOfSines(2, 2.0 + 0.005, 0.01, 3, 0.5, 1.0, 9);
  EXPECT_LE((period.q.row(200) - period.q.row(0)).cwiseAbs().maxCoeff(), 1e-9);
}

TEST(Trajectory, UniformBoxRangesAndSeeds) {
  const Trajectory a = UniformBox(3, 5000, 2.0, 1.0, 4.0, 17, 0.02);
  const Trajectory b = UniformBox(3, 5000, 2.0, 1.0, 4.0, 17, 0.02);
  const Trajectory c = UniformBox(3, 5000, 2.0, 1.0, 4.0, 18, 0.02);
  ASSERT_EQ(a.num_samples(), 5000);
  EXPECT_EQ(a.q, b.q);
  EXPECT_EQ(a.qdd, b.qdd);
  EXPECT_NE(a.q, c.q);
  EXPECT_LE(a.q.cwiseAbs().maxCoeff(), 2.0);
  EXPECT_GT(a.q.cwiseAbs().maxCoeff(), 1.99);
  EXPECT_LE(a.qd.cwiseAbs().maxCoeff(), 1.0);
  EXPECT_LE(a.qdd.cwiseAbs().maxCoeff(), 4.0);
  EXPECT_NEAR(a.q.mean(), 0.0, 0.05);
  EXPECT_DOUBLE_EQ(a.t(10), 0.2);
  // A prefix of a longer run.
  const Trajectory shorter = UniformBox(3, 100, 2.0, 1.0, 4.0, 17, 0.02);
  EXPECT_EQ(shorter.qd, a.qd.topRows(100));
}

TEST(Trajectory, RejectsBadArguments) {
  EXPECT_THROW(UniformBox(0, 10, 1.0, 1.0, 1.0, 1), std::invalid_argument);
  EXPECT_THROW(UniformBox(2, 10, -1.0, 1.0, 1.0, 1), std::invalid_argument);
  EXPECT_THROW(ViaPoints(2, 1.0, 0.01, 1, 1.0, 1.0, 1), std::invalid_argument);
  EXPECT_THROW(ViaPoints(2, 1.0, 0.0, 3, 1.0, 1.0, 1), std::invalid_argument);
  EXPECT_THROW(ViaPoints(2, 1.0, 0.01, 3, 0.0, 1.0, 1), std::invalid_argument);
  EXPECT_THROW(SumOfSines(2, 1.0, 0.01, 0, 1.0, 1.0, 1), std::invalid_argument);
  EXPECT_THROW(SumOfSines(2, -1.0, 0.01, 2, 1.0, 1.0, 1), std::invalid_argument);
}

// ---- data sets ---------------------------------------------------------------------------

TEST(Dataset, LayoutComponentsAndNormalisation) {
  PrintSeeds("LayoutComponentsAndNormalisation");
  JointFriction f;
  f.coulomb = 1.5;
  f.viscous = 0.8;
  f.smoothing_velocity = 0.02;
  for (std::uint64_t seed : kSeeds) {
    const Robot robot = RandomRobot(3, seed);
    SCOPED_TRACE(robot.name());
    const Trajectory tr = ViaPoints(3, 2.0, 0.01, 4, 1.0, 1.5, seed, ViaVelocity::kContinuous);
    for (TorqueNormalization normalization :
         {TorqueNormalization::kNone, TorqueNormalization::kPerJoint,
          TorqueNormalization::kGlobal}) {
      SimulationOptions options;
      options.friction = FrictionModel::Uniform(3, f);
      options.normalization = normalization;
      const Dataset data = Simulate(robot, tr, options);
      ASSERT_EQ(data.num_samples(), tr.num_samples());
      ASSERT_EQ(data.num_joints(), 3);
      ASSERT_EQ(data.X.cols(), 9);
      EXPECT_EQ(data.X.leftCols(3), tr.q);
      EXPECT_EQ(data.X.middleCols(3, 3), tr.qd);
      EXPECT_EQ(data.X.rightCols(3), tr.qdd);
      EXPECT_EQ(data.t, tr.t);

      // Y in N m equals KDL's inverse dynamics plus friction, sample by sample.
      for (Eigen::Index i = 0; i < tr.num_samples(); i += 37) {
        const Eigen::VectorXd q = tr.q.row(i), qd = tr.qd.row(i), qdd = tr.qdd.row(i);
        const Eigen::VectorXd tau =
            robot.InverseDynamics(q, qd, qdd) + options.friction->Torque(qd);
        const Eigen::VectorXd y = data.Y.row(i).transpose().cwiseProduct(data.torque_scale);
        EXPECT_LE((y - tau).cwiseAbs().maxCoeff(), 1e-12 * std::max(1.0, tau.norm()));
      }

      switch (normalization) {
        case TorqueNormalization::kNone:
          EXPECT_EQ(data.torque_scale, Eigen::VectorXd::Ones(3));
          break;
        case TorqueNormalization::kPerJoint:
          for (int j = 0; j < 3; ++j) EXPECT_DOUBLE_EQ(data.Y.col(j).cwiseAbs().maxCoeff(), 1.0);
          break;
        case TorqueNormalization::kGlobal:
          EXPECT_DOUBLE_EQ(data.Y.cwiseAbs().maxCoeff(), 1.0);
          EXPECT_EQ(data.torque_scale(0), data.torque_scale(2));
          break;
      }

      // The components add up to the (noise-free) targets, in the same units.
      const TorqueComponents parts = SimulateComponents(robot, tr, options);
      EXPECT_EQ(parts.torque_scale, data.torque_scale);
      EXPECT_LE((parts.Total() - data.Y).cwiseAbs().maxCoeff(),
                1e-9 * std::max(1.0, data.Y.cwiseAbs().maxCoeff()));
      EXPECT_GT(parts.friction.cwiseAbs().maxCoeff(), 0.0);
      EXPECT_GT(parts.coriolis.cwiseAbs().maxCoeff(), 0.0);
      EXPECT_GT(parts.gravity.cwiseAbs().maxCoeff(), 0.0);
    }
  }
}

TEST(Dataset, NoiseIsSeededWithTheRequestedSpread) {
  const Robot robot = TwoLinkArm();
  const Trajectory tr = UniformBox(2, 20000, kPi, 2.0, 5.0, 3);
  SimulationOptions clean;
  SimulationOptions noisy;
  noisy.noise_std = 0.3;
  noisy.seed = 99;
  const Dataset a = Simulate(robot, tr, clean);
  const Dataset b = Simulate(robot, tr, noisy);
  const Dataset c = Simulate(robot, tr, noisy);
  EXPECT_EQ(b.Y, c.Y);
  const Eigen::MatrixXd e = b.Y - a.Y;
  const double mean = e.mean();
  const double std_dev = std::sqrt((e.array() - mean).square().sum() / (e.size() - 1));
  // 40000 draws: the standard errors of the mean and std are 0.3/200 and 0.3/283.
  EXPECT_NEAR(mean, 0.0, 5.0 * 0.3 / 200.0);
  EXPECT_NEAR(std_dev, 0.3, 5.0 * 0.3 / 283.0);
  noisy.seed = 100;
  EXPECT_NE(Simulate(robot, tr, noisy).Y, b.Y);
}

TEST(Dataset, RejectsMismatchedInput) {
  const Robot robot = ThreeLinkArm();
  const Trajectory two_joints = UniformBox(2, 10, 1.0, 1.0, 1.0, 1);
  EXPECT_THROW(Simulate(robot, two_joints), std::invalid_argument);
  const Trajectory three_joints = UniformBox(3, 10, 1.0, 1.0, 1.0, 1);
  SimulationOptions options;
  options.friction = FrictionModel::Uniform(2, JointFriction());
  EXPECT_THROW(Simulate(robot, three_joints, options), std::invalid_argument);
  options.friction.reset();
  options.noise_std = -1.0;
  EXPECT_THROW(SimulateComponents(robot, three_joints, options), std::invalid_argument);
}

}  // namespace
}  // namespace sim
}  // namespace structgp

namespace structgp {
namespace {

TEST(RobotByName, GivesEachRobotAndRefusesOthers) {
  EXPECT_EQ(sim::RobotByName("two_link").name(), sim::TwoLinkArm().name());
  EXPECT_EQ(sim::RobotByName("two-link").num_joints(), 2);
  EXPECT_EQ(sim::RobotByName("three_link").num_joints(), 3);
  EXPECT_EQ(sim::RobotByName("puma560").num_joints(), 6);
  EXPECT_EQ(sim::RobotByName("panda").num_joints(), 7);
  EXPECT_EQ(sim::RobotByName("panda").convention(), sim::DhConvention::kModified);
  EXPECT_EQ(sim::RobotByName("random4").name(), sim::RandomRobot(4, 1).name());
  for (const char* bad : {"random8", "random0", "puma", "", "random"}) {
    try {
      sim::RobotByName(bad);
      ADD_FAILURE() << "accepted '" << bad << "'";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("unknown robot '" + std::string(bad) + "'"),
                std::string::npos)
          << e.what();
    }
  }
}

}  // namespace
}  // namespace structgp
