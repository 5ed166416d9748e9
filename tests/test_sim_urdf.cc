// The simulator's DH robots as URDF (sim::ToUrdf, data/urdf/) against the DH robots themselves:
// the same inverse dynamics through kdl_parser's reading of the document.

#include <cmath>
#include <fstream>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>

#include <gtest/gtest.h>
#include <kdl/chainfksolverpos_recursive.hpp>
#include <kdl/jntarray.hpp>

#include "structgp/rigid_body/physical_consistency.h"
#include "structgp/rigid_body/rigid_body_chain.h"
#include "structgp/sim/robot.h"
#include "structgp/sim/urdf.h"

namespace structgp {
namespace sim {
namespace {

const std::string kUrdfDir = std::string(STRUCTGP_SOURCE_DIR) + "/data/urdf";

std::vector<Robot> BuiltIn() { return {TwoLinkArm(), ThreeLinkArm(), Puma560(), Panda(), Ur10()}; }

// The DH robot with its armature removed (URDF has none).
Robot WithoutArmature(const Robot& robot) {
  std::vector<LinkParameters> links = robot.links();
  for (LinkParameters& link : links) link.armature = 0.0;
  return Robot(robot.name(), links, robot.base_rotation(), robot.convention());
}

// Inverse dynamics of two models of one robot on random states. The URDF's frames are the DH
// frames up to rotations written as roll-pitch-yaw with 17 digits, so the torques agree to a
// few ulps of the largest; 1e-10 relative leaves room for the conversions.
void ExpectSameDynamics(const Robot& dh, const RigidBodyChain& chain, std::uint64_t seed) {
  ASSERT_EQ(chain.num_joints(), dh.num_joints());
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  const int n = dh.num_joints();
  for (int trial = 0; trial < 50; ++trial) {
    Eigen::VectorXd q(n), qd(n), qdd(n);
    for (int j = 0; j < n; ++j) {
      q(j) = 3.1 * unit(rng);
      qd(j) = 2.0 * unit(rng);
      qdd(j) = 5.0 * unit(rng);
    }
    const Eigen::VectorXd want = dh.InverseDynamics(q, qd, qdd);
    const Eigen::VectorXd got = chain.InverseDynamics(q, qd, qdd);
    EXPECT_LT((got - want).norm(), 1e-10 * want.norm())
        << dh.name() << " trial " << trial << "\n dh   " << want.transpose() << "\n urdf "
        << got.transpose();
    EXPECT_LT((chain.MassMatrix(q) - dh.MassMatrix(q)).norm(), 1e-10 * dh.MassMatrix(q).norm());
  }
}

TEST(SimUrdfTest, UrdfAndDhGiveTheSameInverseDynamics) {
  for (const Robot& robot : BuiltIn()) {
    SCOPED_TRACE(robot.name());
    const RigidBodyChain chain = RigidBodyChain::FromUrdfString(ToUrdf(robot));
    EXPECT_EQ(chain.robot_name(), robot.name());
    EXPECT_EQ(chain.root(), "world");
    EXPECT_EQ(chain.tip(), "tool");
    EXPECT_EQ(chain.parameters().tail(robot.num_joints()), Eigen::VectorXd::Zero(robot.num_joints()));
    ExpectSameDynamics(WithoutArmature(robot), chain, 1);
    // The armature put back: the DH robot as it is.
    ExpectSameDynamics(robot, ToRigidBodyChain(robot), 2);
  }
}

// The Panda's modified-DH kinematics against its published home pose: at q = 0 frame 7 sits
// at (0.088, 0, 1.033) m with z pointing down (the flange, 0.107 m further along z_7, is at
// (0.088, 0, 0.926) m), joint 2's axis is the base's y axis and joint 4's is -y.
TEST(SimUrdfTest, PandaHomePose) {
  const Robot panda = Panda();
  ASSERT_EQ(panda.num_joints(), 7);
  EXPECT_EQ(panda.convention(), DhConvention::kModified);
  KDL::ChainFkSolverPos_recursive fk(panda.chain());
  KDL::JntArray q(7);
  KDL::Frame frame;
  ASSERT_GE(fk.JntToCart(q, frame), 0);
  EXPECT_NEAR(frame.p.x(), 0.088, 1e-12);
  EXPECT_NEAR(frame.p.y(), 0.0, 1e-12);
  EXPECT_NEAR(frame.p.z(), 1.033, 1e-12);
  EXPECT_NEAR(frame.M.UnitZ().z(), -1.0, 1e-12);
  const KDL::Vector flange = frame * KDL::Vector(0.0, 0.0, 0.107);
  EXPECT_NEAR(flange.z(), 0.926, 1e-12);
  ASSERT_GE(fk.JntToCart(q, frame, 2), 0);
  EXPECT_NEAR(frame.M.UnitZ().y(), 1.0, 1e-12);
  ASSERT_GE(fk.JntToCart(q, frame, 4), 0);
  EXPECT_NEAR(frame.M.UnitZ().y(), -1.0, 1e-12);
  EXPECT_NEAR(frame.p.x(), 0.0825, 1e-12);
  EXPECT_NEAR(frame.p.z(), 0.649, 1e-12);
  // Joint 1 turns about the vertical: no gravity torque on it, and its turn moves frame 7 on
  // a circle of radius 0.088 m about the z axis.
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(7);
  Eigen::VectorXd turned = zero;
  turned(0) = 0.5;
  for (int k = 0; k < 7; ++k) q(k) = turned(k);
  ASSERT_GE(fk.JntToCart(q, frame), 0);
  EXPECT_NEAR(frame.p.x(), 0.088 * std::cos(0.5), 1e-12);
  EXPECT_NEAR(frame.p.y(), 0.088 * std::sin(0.5), 1e-12);
  EXPECT_NEAR(panda.InverseDynamics(turned, zero, zero)(0), 0.0, 1e-12);
  // A physically valid robot: positive masses, inertias that satisfy the triangle
  // inequalities, M(q) positive definite.
  const RigidBodyChain chain = ToRigidBodyChain(panda);
  const PhysicalConsistency consistency = CheckPhysicalConsistency(chain, chain.parameters());
  EXPECT_TRUE(consistency.ok);
  EXPECT_EQ(consistency.mass_matrix_pd_fraction, 1.0);
}

// The UR10's published table against hand statics: at q = 0 (stretched out horizontally)
// frame 6 sits at (a2 + a3, -(d4 + d6), d1 - d5) and joints 2 and 3 hold the links' weight on
// their lever arms along x (upper arm's centre of mass 0.612 - 0.38 m from joint 2, forearm's
// 0.5723 - 0.24 m from joint 3, the wrist's 4.365 kg at the elbow's 0.5723 m beyond it); at
// the upright pose (q2 = q4 = -pi/2) gravity loads no joint.
TEST(SimUrdfTest, Ur10StretchedAndUpright) {
  const Robot ur10 = Ur10();
  ASSERT_EQ(ur10.num_joints(), 6);
  KDL::ChainFkSolverPos_recursive fk(ur10.chain());
  KDL::JntArray q(6);
  KDL::Frame frame;
  ASSERT_GE(fk.JntToCart(q, frame), 0);
  EXPECT_NEAR(frame.p.x(), -0.612 - 0.5723, 1e-12);
  EXPECT_NEAR(frame.p.y(), -(0.163941 + 0.0922), 1e-12);
  EXPECT_NEAR(frame.p.z(), 0.1273 - 0.1157, 1e-12);
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(6);
  const Eigen::VectorXd stretched = ur10.InverseDynamics(zero, zero, zero);
  const double wrist = 2.0 + 2.0 + 0.365;
  const double shoulder =
      kStandardGravity *
      (12.7 * (0.612 - 0.38) + 4.27 * (0.612 + 0.5723 - 0.24) + wrist * (0.612 + 0.5723));
  const double elbow = kStandardGravity * (4.27 * (0.5723 - 0.24) + wrist * 0.5723);
  EXPECT_NEAR(std::abs(stretched(1)), shoulder, 1e-9 * shoulder);
  EXPECT_NEAR(std::abs(stretched(2)), elbow, 1e-9 * elbow);
  EXPECT_NEAR(stretched(0), 0.0, 1e-12);
  Eigen::VectorXd upright = zero;
  upright(1) = upright(3) = -0.5 * 3.14159265358979323846;
  EXPECT_LT(ur10.InverseDynamics(upright, zero, zero).norm(), 1e-12);
  const RigidBodyChain chain = ToRigidBodyChain(ur10);
  const PhysicalConsistency consistency = CheckPhysicalConsistency(chain, chain.parameters());
  EXPECT_TRUE(consistency.ok);
  EXPECT_EQ(consistency.mass_matrix_pd_fraction, 1.0);
}

TEST(SimUrdfTest, RandomRobotsToo) {
  for (int n = 1; n <= 7; ++n) {
    const Robot robot = RandomRobot(n, 40 + n);
    SCOPED_TRACE(robot.name());
    ExpectSameDynamics(robot, ToRigidBodyChain(robot), 3);
  }
}

TEST(SimUrdfTest, ShippedFilesAreCurrent) {
  for (const Robot& robot : BuiltIn()) {
    const std::string path = kUrdfDir + "/" + robot.name() + ".urdf";
    std::ifstream in(path, std::ios::binary);
    ASSERT_TRUE(in) << "missing " << path;
    std::ostringstream text;
    text << in.rdbuf();
    EXPECT_EQ(text.str(), ToUrdf(robot))
        << path << " is not what sim::ToUrdf writes: regenerate the files with "
        << "`build/tests/generate_urdfs data/urdf`";
  }
}

TEST(SimUrdfTest, RobotFromUrdfFile) {
  const Robot dh = Puma560();
  const Robot urdf = Robot::FromUrdf(kUrdfDir + "/puma560.urdf");
  EXPECT_EQ(urdf.name(), "puma560");
  EXPECT_EQ(urdf.num_joints(), 6);
  EXPECT_TRUE(urdf.links().empty());
  ExpectSameDynamics(WithoutArmature(dh), RigidBodyChain::FromUrdfFile(kUrdfDir + "/puma560.urdf"), 4);
  // The Robot's own evaluations (KDL on the URDF's chain) and its components.
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  Eigen::VectorXd q(6), qd(6), qdd(6);
  for (int j = 0; j < 6; ++j) {
    q(j) = 3.0 * unit(rng);
    qd(j) = unit(rng);
    qdd(j) = unit(rng);
  }
  const Eigen::VectorXd want = WithoutArmature(dh).InverseDynamics(q, qd, qdd);
  EXPECT_LT((urdf.InverseDynamics(q, qd, qdd) - want).norm(), 1e-10 * want.norm());
  const DynamicsComponents c = urdf.Components(q, qd, qdd);
  EXPECT_LT((c.inertial + c.coriolis + c.gravity - want).norm(), 1e-10 * want.norm());
  // A robot from a chain with armature keeps it.
  const Robot with_armature = Robot::FromRigidBodyChain(ToRigidBodyChain(dh));
  const Eigen::VectorXd dh_tau = dh.InverseDynamics(q, qd, qdd);
  EXPECT_LT((with_armature.InverseDynamics(q, qd, qdd) - dh_tau).norm(), 1e-10 * dh_tau.norm());
  // No DH parameters to write.
  try {
    ToUrdf(urdf);
    ADD_FAILURE() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(),
                 "ToUrdf: robot 'puma560' was read from a URDF and has no DH parameters");
  }
}

}  // namespace
}  // namespace sim
}  // namespace structgp
