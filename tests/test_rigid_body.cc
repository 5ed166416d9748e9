// RigidBodyChain (src/rigid_body): chains from URDF, the regressor against KDL's own dynamics,
// lumping of fixed links against KDL's tree solver on the unlumped tree, the error messages, and
// an allocation-free regressor.

#include <algorithm>
#include <cmath>
#include <functional>
#include <vector>
#include <cstdio>
#include <fstream>
#include <map>
#include <random>
#include <stdexcept>
#include <string>

#include <Eigen/LU>
#include <gtest/gtest.h>
#include <kdl/jntarray.hpp>
#include <kdl/tree.hpp>
#include <kdl/treeidsolver_recursive_newton_euler.hpp>
#include <kdl_parser/kdl_parser.hpp>

#include "alloc_counter.h"
#include "structgp/rigid_body/physical_consistency.h"
#include "structgp/rigid_body/rigid_body_chain.h"
#include "urdf_test_util.h"

namespace structgp {
namespace {

using Terms = RigidBodyChain::Terms;
using testing::RandomUrdf;
using testing::RandomUrdfOptions;

RandomUrdfOptions Random(int num_joints, bool fixed_links = false, bool fixed_branches = false,
                         std::uint64_t seed = 1) {
  RandomUrdfOptions o;
  o.num_joints = num_joints;
  o.fixed_links = fixed_links;
  o.fixed_branches = fixed_branches;
  o.seed = seed;
  return o;
}

UrdfOptions Chain(const std::string& root, const std::string& tip,
                  const Eigen::Vector3d& gravity = Eigen::Vector3d(0.0, 0.0, -9.81)) {
  UrdfOptions o;
  o.root = root;
  o.tip = tip;
  o.gravity = gravity;
  return o;
}

struct State {
  Vector q, qd, qdd;
};

State RandomState(int n, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  State s{Vector(n), Vector(n), Vector(n)};
  for (int j = 0; j < n; ++j) {
    s.q(j) = 3.1 * unit(rng);
    s.qd(j) = 2.0 * unit(rng);
    s.qdd(j) = 5.0 * unit(rng);
  }
  return s;
}

double RelativeError(const Vector& got, const Vector& want) {
  return (got - want).norm() / std::max(want.norm(), 1e-300);
}

// Relative agreement of the regressor with KDL (the same solver, other inertias): both sides
// sum O(P) terms of size |tau|, so a few hundred ulps of |tau|.
constexpr double kRegressorTolerance = 1e-12;

std::string ExpectInvalid(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  ADD_FAILURE() << "no std::invalid_argument";
  return "";
}

TEST(RigidBodyChainTest, ReadsNamesAndSizes) {
  const RigidBodyChain chain = RigidBodyChain::FromUrdfString(
      RandomUrdf(Random(7, true)), {}, "random.urdf");
  EXPECT_EQ(chain.num_joints(), 7);
  EXPECT_EQ(chain.num_parameters(), 77);
  EXPECT_EQ(chain.robot_name(), "random");
  EXPECT_EQ(chain.root(), "world");
  EXPECT_EQ(chain.tip(), "link7");
  EXPECT_EQ(chain.source(), "random.urdf");
  ASSERT_EQ(chain.joint_names().size(), 7u);
  EXPECT_EQ(chain.joint_names()[0], "joint1");
  EXPECT_EQ(chain.link_names()[6], "link7");
  const std::vector<std::string> names = chain.parameter_names();
  ASSERT_EQ(names.size(), 77u);
  EXPECT_EQ(names[0], "m@1");
  EXPECT_EQ(names[21], "mcx@3");
  EXPECT_EQ(names[24], "Ixx@3");
  EXPECT_EQ(names[29], "Izz@3");
  EXPECT_EQ(names[72], "armature@3");
  // The URDF's masses: link 2 carries its flange.
  EXPECT_GT(chain.parameters()(0), 0.0);
  EXPECT_EQ(chain.parameters().tail(7), Vector::Zero(7));
}

// Y(x) pi reproduces KDL's recursive Newton-Euler torque on random states, for every term.
TEST(RigidBodyChainTest, RegressorTimesParametersIsKdlInverseDynamics) {
  for (const std::uint64_t seed : {1u, 2u, 3u}) {
    const RigidBodyChain chain = RigidBodyChain::FromUrdfString(
        RandomUrdf(Random(7, true, true, seed)),
        Chain("", "link7"));
    std::mt19937_64 rng(100 + seed);
    const Vector pi = chain.parameters();
    for (int trial = 0; trial < 20; ++trial) {
      const State s = RandomState(7, rng);
      const Vector tau = chain.InverseDynamics(s.q, s.qd, s.qdd);
      EXPECT_LT(RelativeError(chain.Regressor(s.q, s.qd, s.qdd) * pi, tau), kRegressorTolerance)
          << "seed " << seed << " trial " << trial;
    }
  }
}

// The three terms add up to kAll and each matches KDL::ChainDynParam's M qdd, C, G.
TEST(RigidBodyChainTest, TermsMatchChainDynParam) {
  // Armature on, so that the inertial term's armature columns count.
  const RigidBodyChain urdf = RigidBodyChain::FromUrdfString(RandomUrdf(Random(7, false, false, 7)));
  Vector pi = urdf.parameters();
  for (int k = 0; k < 7; ++k) pi(70 + k) = 0.1 * (k + 1);
  const RigidBodyChain chain = urdf.WithParameters(pi);
  std::mt19937_64 rng(8);
  for (int trial = 0; trial < 10; ++trial) {
    const State s = RandomState(7, rng);
    const Matrix all = chain.Regressor(s.q, s.qd, s.qdd, Terms::kAll);
    const Matrix inertial = chain.Regressor(s.q, s.qd, s.qdd, Terms::kInertial);
    const Matrix coriolis = chain.Regressor(s.q, s.qd, s.qdd, Terms::kCoriolis);
    const Matrix gravity = chain.Regressor(s.q, s.qd, s.qdd, Terms::kGravity);
    EXPECT_LT((inertial + coriolis + gravity - all).norm(), 1e-12 * all.norm());
    const Vector mqdd = chain.MassMatrix(s.q) * s.qdd;
    EXPECT_LT(RelativeError(inertial * pi, mqdd), kRegressorTolerance);
    EXPECT_LT(RelativeError(coriolis * pi, chain.Coriolis(s.q, s.qd)), kRegressorTolerance);
    EXPECT_LT(RelativeError(gravity * pi, chain.Gravity(s.q)), kRegressorTolerance);
    EXPECT_LT(RelativeError(all * pi, chain.InverseDynamics(s.q, s.qd, s.qdd)),
              kRegressorTolerance);
  }
}

// WithParameters builds the inertias from the 10 numbers (KDL arithmetic on basis inertias);
// FromUrdf keeps kdl_parser's own: the same dynamics by two constructions.
TEST(RigidBodyChainTest, WithParametersRoundTripsAndRebuildsTheSameDynamics) {
  const RigidBodyChain chain =
      RigidBodyChain::FromUrdfString(RandomUrdf(Random(7, true, false, 4)));
  const RigidBodyChain rebuilt = chain.WithParameters(chain.parameters());
  EXPECT_EQ(rebuilt.parameters(), chain.parameters());
  std::mt19937_64 rng(5);
  for (int trial = 0; trial < 10; ++trial) {
    const State s = RandomState(7, rng);
    EXPECT_LT(RelativeError(rebuilt.InverseDynamics(s.q, s.qd, s.qdd),
                            chain.InverseDynamics(s.q, s.qd, s.qdd)),
              1e-13);
  }
  // Other parameters, not physical ones included: stored as given, dynamics linear in them.
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  Vector p(chain.num_parameters());
  for (int i = 0; i < p.size(); ++i) p(i) = unit(rng);
  const RigidBodyChain other = chain.WithParameters(p);
  EXPECT_EQ(other.parameters(), p);
  EXPECT_EQ(other.joint_names(), chain.joint_names());
  const State s = RandomState(7, rng);
  EXPECT_LT(RelativeError(other.InverseDynamics(s.q, s.qd, s.qdd),
                          chain.Regressor(s.q, s.qd, s.qdd) * p),
            kRegressorTolerance);
  // The armature adds armature_j qdd_j, KDL's joint inertia.
  Vector with_armature = chain.parameters();
  with_armature.tail(7).setConstant(0.25);
  EXPECT_LT((chain.WithParameters(with_armature).InverseDynamics(s.q, s.qd, s.qdd) -
             chain.InverseDynamics(s.q, s.qd, s.qdd) - 0.25 * s.qdd)
                .norm(),
            1e-12 * chain.InverseDynamics(s.q, s.qd, s.qdd).norm());
}

// A payload added by its parameters equals the same point mass written into the URDF as a fixed
// link on the last link (lumped by the URDF reader, an independent path).
TEST(RigidBodyChainTest, WithPayloadEqualsAPointMassLinkInTheUrdf) {
  const std::string xml = RandomUrdf(Random(7, false, false, 9));
  const RigidBodyChain chain = RigidBodyChain::FromUrdfString(xml);
  const Eigen::Vector3d c(0.03, -0.02, 0.05);
  std::string loaded = xml;
  loaded.insert(loaded.rfind("</robot>"),
                "  <link name=\"payload\"><inertial><origin xyz=\"0 0 0\" rpy=\"0 0 0\"/>"
                "<mass value=\"2\"/><inertia ixx=\"0\" iyy=\"0\" izz=\"0\" ixy=\"0\" "
                "ixz=\"0\" iyz=\"0\"/></inertial></link>\n  <joint name=\"payload_joint\" "
                "type=\"fixed\"><parent link=\"link7\"/><child link=\"payload\"/><origin "
                "xyz=\"0.03 -0.02 0.05\" rpy=\"0 0 0\"/></joint>\n");
  const RigidBodyChain reference = RigidBodyChain::FromUrdfString(loaded);
  ASSERT_EQ(reference.num_joints(), 7);
  const RigidBodyChain with = chain.WithPayload(2.0, c);
  std::mt19937_64 rng(6);
  for (int trial = 0; trial < 10; ++trial) {
    const State s = RandomState(7, rng);
    EXPECT_LT(RelativeError(with.InverseDynamics(s.q, s.qd, s.qdd),
                            reference.InverseDynamics(s.q, s.qd, s.qdd)),
              1e-10);
  }
  EXPECT_GT(RelativeError(chain.InverseDynamics(Vector::Zero(7), Vector::Zero(7), Vector::Zero(7)),
                          with.InverseDynamics(Vector::Zero(7), Vector::Zero(7), Vector::Zero(7))),
            1e-3);
  EXPECT_THROW(chain.WithPayload(-1.0, c), std::invalid_argument);
}

// The lumped chain against KDL's tree solver on the unlumped tree (fixed links and fixed
// branches as their own segments).
TEST(RigidBodyChainTest, LumpedFixedLinksGiveTheUnlumpedTreeDynamics) {
  const std::string xml =
      RandomUrdf(Random(6, true, true, 11));
  const Eigen::Vector3d gravity(0.3, -1.2, -9.7);
  const RigidBodyChain chain =
      RigidBodyChain::FromUrdfString(xml, Chain("", "flange6", gravity));
  ASSERT_EQ(chain.num_joints(), 6);
  KDL::Tree tree;
  ASSERT_TRUE(kdl_parser::treeFromString(xml, tree));
  ASSERT_EQ(tree.getNrOfJoints(), 6u);
  KDL::TreeIdSolver_RNE solver(tree, KDL::Vector(gravity.x(), gravity.y(), gravity.z()));
  // The tree's joint numbering (q_nr) by joint name.
  std::map<std::string, int> index;
  for (const auto& entry : tree.getSegments()) {
    const KDL::Segment& segment = GetTreeElementSegment(entry.second);
    if (segment.getJoint().getType() != KDL::Joint::Fixed) {
      index[segment.getJoint().getName()] = GetTreeElementQNr(entry.second);
    }
  }
  std::mt19937_64 rng(12);
  for (int trial = 0; trial < 10; ++trial) {
    const State s = RandomState(6, rng);
    KDL::JntArray q(6), qd(6), qdd(6), tau(6);
    for (int k = 0; k < 6; ++k) {
      const int i = index.at(chain.joint_names()[k]);
      q(i) = s.q(k);
      qd(i) = s.qd(k);
      qdd(i) = s.qdd(k);
    }
    ASSERT_GE(solver.CartToJnt(q, qd, qdd, KDL::WrenchMap(), tau), 0);
    Vector want(6);
    for (int k = 0; k < 6; ++k) want(k) = tau(index.at(chain.joint_names()[k]));
    EXPECT_LT(RelativeError(chain.InverseDynamics(s.q, s.qd, s.qdd), want), 1e-12);
    EXPECT_LT(RelativeError(chain.Regressor(s.q, s.qd, s.qdd) * chain.parameters(), want),
              kRegressorTolerance);
  }
}

TEST(RigidBodyChainTest, SubchainBetweenNamedLinks) {
  const std::string xml = RandomUrdf(Random(7, false, false, 21));
  const RigidBodyChain full = RigidBodyChain::FromUrdfString(xml);
  const RigidBodyChain part = RigidBodyChain::FromUrdfString(xml, Chain("link2", "link5"));
  EXPECT_EQ(part.num_joints(), 3);
  EXPECT_EQ(part.joint_names()[0], "joint3");
  EXPECT_EQ(part.parameters().head(30), full.parameters().segment(20, 30))
      << "the link parameters are in each link's own frame, whatever the root";
}

TEST(RigidBodyChainTest, RegressorWithWorkspaceDoesNotAllocate) {
  const RigidBodyChain chain = RigidBodyChain::FromUrdfString(RandomUrdf(Random(7, true)));
  RigidBodyChain::Workspace workspace = chain.MakeWorkspace();
  const RigidBodyChain other = chain.WithParameters(2.0 * chain.parameters());
  std::mt19937_64 rng(3);
  const State s = RandomState(7, rng);
  Matrix y(7, 77), y_other(7, 77);
  const Matrix want = chain.Regressor(s.q, s.qd, s.qdd);
  chain.Regressor(s.q, s.qd, s.qdd, Terms::kAll, y, workspace);  // warm
  {
    structgp::testing::AllocationCounter guard;
    for (const Terms terms : {Terms::kAll, Terms::kInertial, Terms::kCoriolis, Terms::kGravity}) {
      chain.Regressor(s.q, s.qd, s.qdd, terms, y, workspace);
    }
    // A chain made by WithParameters shares the kinematics, and the workspace.
    other.Regressor(s.q, s.qd, s.qdd, Terms::kAll, y_other, workspace);
    if (!structgp::testing::CountsEveryAllocation()) {
      GTEST_SKIP() << structgp::testing::kIncompleteCountReason;
    }
    EXPECT_EQ(guard.count(), 0u);
  }
  EXPECT_EQ(y_other, want);
}

TEST(RigidBodyChainTest, RegressorRejectsBadArguments) {
  const RigidBodyChain chain = RigidBodyChain::FromUrdfString(RandomUrdf(Random(3)));
  RigidBodyChain::Workspace workspace = chain.MakeWorkspace();
  Matrix y(3, 33);
  const Vector ok = Vector::Zero(3);
  EXPECT_EQ(ExpectInvalid([&] { chain.Regressor(Vector::Zero(2), ok, ok, Terms::kAll, y, workspace); }),
            "RigidBodyChain: q: expected 3 entries, got 2");
  Vector nan = ok;
  nan(1) = std::nan("");
  EXPECT_NE(ExpectInvalid([&] { chain.Regressor(ok, nan, ok, Terms::kAll, y, workspace); })
                .find("RigidBodyChain: qd"),
            std::string::npos);
  Matrix wrong(3, 30);
  EXPECT_EQ(ExpectInvalid([&] { chain.Regressor(ok, ok, ok, Terms::kAll, wrong, workspace); }),
            "RigidBodyChain::Regressor: Y must be 3 x 33, got 3 x 30");
  const RigidBodyChain stranger = RigidBodyChain::FromUrdfString(RandomUrdf(Random(3)));
  EXPECT_NE(ExpectInvalid([&] { stranger.Regressor(ok, ok, ok, Terms::kAll, y, workspace); })
                .find("workspace was made by a chain of other kinematics"),
            std::string::npos);
  EXPECT_NE(ExpectInvalid([&] { chain.WithParameters(Vector::Zero(32)); })
                .find("expected 33 entries, got 32"),
            std::string::npos);
}

// ---- bad URDF input -------------------------------------------------------------------------

const char kTwoJoints[] = R"(<robot name="r">
  <link name="base"/>
  <link name="a"><inertial><mass value="1"/><inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="b"><inertial><mass value="1"/><inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="a"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="j2" type="JOINT2_TYPE"><parent link="a"/><child link="b"/><origin xyz="0.3 0 0"/><axis xyz="0 1 0"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  EXTRA
</robot>)";

std::string TwoJoints(const std::string& type, const std::string& extra = "") {
  std::string xml = kTwoJoints;
  xml.replace(xml.find("JOINT2_TYPE"), 11, type);
  xml.replace(xml.find("EXTRA"), 5, extra);
  return xml;
}

TEST(RigidBodyChainErrorsTest, MissingFile) {
  EXPECT_EQ(ExpectInvalid([] { RigidBodyChain::FromUrdfFile("/nonexistent/robot.urdf"); }),
            "URDF file '/nonexistent/robot.urdf': cannot open (No such file or directory)");
}

TEST(RigidBodyChainErrorsTest, MalformedXmlAndUrdf) {
  const std::string path = ::testing::TempDir() + "/malformed.urdf";
  std::ofstream(path) << "<robot name=\"r\"><link name=\"a\"></robot";
  const std::string xml_error = ExpectInvalid([&] { RigidBodyChain::FromUrdfFile(path); });
  EXPECT_EQ(xml_error.rfind(path + ": not a valid URDF (urdfdom's parser failed", 0), 0u)
      << xml_error;
  std::remove(path.c_str());
  // Well-formed XML, not a URDF: urdfdom's message is passed on.
  const std::string no_robot = ExpectInvalid([] { RigidBodyChain::FromUrdfString("<model/>", {}, "m.urdf"); });
  EXPECT_EQ(no_robot.rfind("m.urdf: not a valid URDF (urdfdom's parser failed: ", 0), 0u) << no_robot;
  EXPECT_NE(no_robot.find("robot"), std::string::npos) << no_robot;
  // A joint whose child link does not exist.
  const std::string dangling = ExpectInvalid([] {
    RigidBodyChain::FromUrdfString(TwoJoints("revolute", R"(<joint name="j3" type="fixed"><parent link="b"/><child link="ghost"/></joint>)"), {}, "d.urdf");
  });
  EXPECT_EQ(dangling.rfind("d.urdf: not a valid URDF", 0), 0u) << dangling;
  EXPECT_NE(dangling.find("ghost"), std::string::npos) << dangling;
}

TEST(RigidBodyChainErrorsTest, RootOrTipNotFound) {
  EXPECT_EQ(ExpectInvalid([] { RigidBodyChain::FromUrdfString(TwoJoints("revolute"), Chain("bse", ""), "r.urdf"); }),
            "r.urdf: root link 'bse' not found; the links are 'a', 'b', 'base'");
  EXPECT_EQ(ExpectInvalid([] { RigidBodyChain::FromUrdfString(TwoJoints("revolute"), Chain("", "c"), "r.urdf"); }),
            "r.urdf: tip link 'c' not found; the links are 'a', 'b', 'base'");
}

TEST(RigidBodyChainErrorsTest, NoChainFromRootToTip) {
  EXPECT_EQ(ExpectInvalid([] { RigidBodyChain::FromUrdfString(TwoJoints("revolute"), Chain("b", "a"), "r.urdf"); }),
            "r.urdf: no chain from root 'b' to tip 'a': 'a' is not below 'b'");
}

TEST(RigidBodyChainErrorsTest, SeveralLeavesWithoutTip) {
  const std::string xml = TwoJoints(
      "revolute",
      R"(<link name="c"/><joint name="j3" type="revolute"><parent link="a"/><child link="c"/><axis xyz="1 0 0"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>)");
  EXPECT_EQ(ExpectInvalid([&] { RigidBodyChain::FromUrdfString(xml, {}, "r.urdf"); }),
            "r.urdf: the tree below 'base' has 2 leaves ('b', 'c'): name the chain's tip link");
  EXPECT_EQ(RigidBodyChain::FromUrdfString(xml, Chain("", "c")).joint_names(),
            (std::vector<std::string>{"j1", "j3"}));
}

TEST(RigidBodyChainErrorsTest, UnsupportedJointTypes) {
  for (const std::string type : {"prismatic", "floating", "planar"}) {
    EXPECT_EQ(ExpectInvalid([&] { RigidBodyChain::FromUrdfString(TwoJoints(type), {}, "r.urdf"); }),
              "r.urdf: joint 'j2' is " + type +
                  ": only revolute and continuous joints are supported (and fixed ones, whose "
                  "links are lumped)");
  }
  // Continuous and fixed are fine.
  EXPECT_EQ(RigidBodyChain::FromUrdfString(TwoJoints("continuous")).num_joints(), 2);
  EXPECT_EQ(RigidBodyChain::FromUrdfString(TwoJoints("fixed")).num_joints(), 1);
}

TEST(RigidBodyChainErrorsTest, NoMovingJoint) {
  EXPECT_EQ(ExpectInvalid([] { RigidBodyChain::FromUrdfString(TwoJoints("fixed"), Chain("a", ""), "r.urdf"); }),
            "r.urdf: the chain from 'a' to 'b' has no moving (revolute or continuous) joint");
}

TEST(RigidBodyChainErrorsTest, NonFiniteGravity) {
  EXPECT_EQ(ExpectInvalid([] {
              RigidBodyChain::FromUrdfString(TwoJoints("revolute"),
                                             Chain("", "", Eigen::Vector3d(0, HUGE_VAL, -9.81)), "r.urdf");
            }),
            "r.urdf: gravity must be finite, got (0, inf, -9.81) m/s^2");
}

// ---- physical consistency -------------------------------------------------------------------

TEST(PhysicalConsistencyTest, UrdfParametersAreConsistent) {
  const RigidBodyChain chain = RigidBodyChain::FromUrdfString(RandomUrdf(Random(7, true)));
  const PhysicalConsistency c = CheckPhysicalConsistency(chain, chain.parameters(), 200);
  EXPECT_TRUE(c.ok) << c.Summary();
  EXPECT_EQ(c.mass_matrix_pd_fraction, 1.0);
  EXPECT_EQ(c.configurations, 200);
  ASSERT_EQ(c.links.size(), 7u);
  for (const LinkConsistency& link : c.links) EXPECT_TRUE(link.ok()) << link.message;
}

TEST(PhysicalConsistencyTest, NamesWhatIsWrong) {
  const RigidBodyChain chain = RigidBodyChain::FromUrdfString(RandomUrdf(Random(3)));
  Vector pi = chain.parameters();
  pi(0) = -0.5;  // link 1: negative mass
  // Link 2: a point mass at its centre of mass (inertia about the COM zero: not PD).
  const double m2 = pi(10);
  const Eigen::Vector3d c2 = pi.segment<3>(11) / m2;
  const Eigen::Matrix3d point =
      m2 * (c2.squaredNorm() * Eigen::Matrix3d::Identity() - c2 * c2.transpose());
  pi.segment<6>(14) << point(0, 0), point(0, 1), point(0, 2), point(1, 1), point(1, 2), point(2, 2);
  // Link 3: principal moments about the COM violating the triangle inequality (Izz too big).
  pi(29) += 10.0;
  pi(32) = -0.01;  // armature of joint 3
  const PhysicalConsistency c = CheckPhysicalConsistency(chain, pi, 100, 5);
  EXPECT_FALSE(c.ok);
  EXPECT_FALSE(c.links[0].mass_positive);
  EXPECT_EQ(c.links[0].message.rfind("mass -0.5 kg is not positive", 0), 0u) << c.links[0].message;
  EXPECT_TRUE(c.links[1].mass_positive);
  EXPECT_FALSE(c.links[1].inertia_positive_definite);
  EXPECT_NE(c.links[1].message.find("are not all positive"), std::string::npos) << c.links[1].message;
  EXPECT_TRUE(c.links[2].inertia_positive_definite);
  EXPECT_FALSE(c.links[2].triangle_inequalities);
  EXPECT_FALSE(c.links[2].armature_nonnegative);
  EXPECT_NE(c.links[2].message.find("violate the triangle inequality"), std::string::npos);
  EXPECT_NE(c.links[2].message.find("armature -0.01 kg m^2 is negative"), std::string::npos);
  EXPECT_NE(c.Summary().find("link 'link1': mass -0.5 kg"), std::string::npos) << c.Summary();
}

// M(q) + a e1 e1^T is positive definite exactly when a > -1 / (M(q)^-1)_11: a negative armature
// on joint 1 between the extremes of that threshold makes M indefinite in some configurations.
// The fraction is checked against the threshold computed directly at the same configurations.
TEST(PhysicalConsistencyTest, MassMatrixFractionAgainstThreshold) {
  const RigidBodyChain chain = RigidBodyChain::FromUrdfString(RandomUrdf(Random(4)));
  constexpr int kConfigurations = 300;
  constexpr std::uint64_t kSeed = 9;
  // The configurations CheckPhysicalConsistency draws (its documented distribution).
  std::mt19937_64 rng(kSeed);
  std::uniform_real_distribution<double> angle(-3.14159265358979323846, 3.14159265358979323846);
  std::vector<double> thresholds;
  Vector q(4);
  for (int c = 0; c < kConfigurations; ++c) {
    for (int j = 0; j < 4; ++j) q(j) = angle(rng);
    thresholds.push_back(1.0 / chain.MassMatrix(q).inverse()(0, 0));
  }
  std::vector<double> sorted = thresholds;
  std::sort(sorted.begin(), sorted.end());
  const double armature = -0.5 * (sorted[kConfigurations / 3] + sorted[kConfigurations / 3 + 1]);
  int want = 0;
  for (const double t : thresholds) want += armature > -t ? 1 : 0;
  Vector pi = chain.parameters();
  pi(40) = armature;
  const PhysicalConsistency c = CheckPhysicalConsistency(chain, pi, kConfigurations, kSeed);
  EXPECT_EQ(c.mass_matrix_pd_fraction, static_cast<double>(want) / kConfigurations);
  EXPECT_GT(c.mass_matrix_pd_fraction, 0.5);
  EXPECT_LT(c.mass_matrix_pd_fraction, 0.8);
  EXPECT_FALSE(c.ok);
  EXPECT_FALSE(c.links[0].armature_nonnegative);
  EXPECT_NE(ExpectInvalid([&] { CheckPhysicalConsistency(chain, pi, 0); }).find("at least 1"),
            std::string::npos);
}

}  // namespace
}  // namespace structgp
