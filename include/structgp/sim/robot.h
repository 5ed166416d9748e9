#ifndef STRUCTGP_SIM_ROBOT_H_
#define STRUCTGP_SIM_ROBOT_H_

/// @file
/// Simulated serial robots with revolute joints. The rigid-body dynamics are computed by
/// Orocos KDL (recursive Newton-Euler for the inverse dynamics, KDL::ChainDynParam for the
/// mass matrix, Coriolis/centrifugal and gravity terms); this header exposes Eigen types
/// only, so users do not need KDL headers.
///
/// Conventions. Joint angles q are in rad, velocities qd in rad/s, accelerations qdd in
/// rad/s^2, torques tau in N m; all joint vectors have num_joints() entries. The equation
/// of motion is
///     tau = M(q) qdd + C(q, qd) qd + G(q),
/// with gravity of kStandardGravity m/s^2 along -z of the world frame. The kinematics use
/// Denavit-Hartenberg parameters in either convention (DhConvention): standard (distal: the
/// frame of link i sits at the far end of link i and joint i turns about the z axis of frame
/// i-1) or modified (proximal, Craig's: frame i sits on joint i's axis and joint i turns about
/// its own z). A robot can also come from a URDF (Robot::FromUrdf): its kinematics are then the
/// URDF's, with gravity as UrdfOptions says.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "structgp/rigid_body/rigid_body_chain.h"

namespace KDL {
class Chain;
}  // namespace KDL

namespace structgp {
namespace sim {

/// Magnitude of the gravitational acceleration, m/s^2. Gravity points along -z of the world.
inline constexpr double kStandardGravity = 9.81;

/// Which Denavit-Hartenberg convention a robot's LinkParameters follow.
enum class DhConvention {
  /// Standard (distal) DH: link i's frame is at its far end; frame i-1 -> i is
  /// RotZ(q_i + theta_offset) TransZ(d) TransX(a) RotX(alpha).
  kStandard,
  /// Modified (proximal, J. J. Craig's) DH: link i's frame is on joint i's axis; frame i-1 -> i
  /// is RotX(alpha) TransX(a) RotZ(q_i + theta_offset) TransZ(d), so row i's a and alpha are the
  /// a_{i-1}, alpha_{i-1} of the textbooks' tables.
  kModified,
};

/// Kinematic and inertial parameters of one link and the revolute joint that drives it.
struct LinkParameters {
  /// DH parameters in the robot's DhConvention: link length a (m), twist alpha (rad), offset d
  /// (m) and the constant joint-angle offset theta_offset (rad); the joint angle is
  /// q + theta_offset.
  double a = 0.0;
  double alpha = 0.0;
  double d = 0.0;
  double theta_offset = 0.0;
  /// Mass, kg (>= 0).
  double mass = 0.0;
  /// Centre of mass in the link frame i, m.
  Eigen::Vector3d com = Eigen::Vector3d::Zero();
  /// Rotational inertia about the centre of mass, in the axes of link frame i, kg m^2.
  /// Symmetric positive semi-definite.
  Eigen::Matrix3d inertia = Eigen::Matrix3d::Zero();
  /// Armature: inertia of the motor rotor and gears reflected to the joint (rotor inertia
  /// times gear ratio squared), kg m^2 (>= 0). Adds to the diagonal entry of M(q).
  double armature = 0.0;
};

/// The three rigid-body terms of the inverse dynamics at one state, each N m (size N).
struct DynamicsComponents {
  Eigen::VectorXd inertial;  ///< M(q) qdd
  Eigen::VectorXd coriolis;  ///< C(q, qd) qd (Coriolis and centrifugal)
  Eigen::VectorXd gravity;   ///< G(q)
};

/// An N-joint serial robot with revolute joints. Immutable after construction; copies are
/// cheap (they share the model) and every method is const and safe to call concurrently.
/// Each call builds its own small KDL solver workspace (a few allocations).
class Robot {
 public:
  /// Builds the robot from one LinkParameters per joint (1 <= N). base_rotation is the
  /// orientation of the DH base frame 0 in the world frame (gravity is -z of the world);
  /// the identity makes joint 1 turn about the vertical. Throws std::invalid_argument on
  /// an empty link list, a negative or non-finite mass or armature, an inertia that is not
  /// symmetric positive semi-definite, or a base_rotation that is not a rotation matrix.
  /// The triangle inequalities of the principal moments are not enforced (published
  /// models such as the PUMA 560 list only the inertia terms that matter).
  Robot(std::string name, std::vector<LinkParameters> links,
        const Eigen::Matrix3d& base_rotation = Eigen::Matrix3d::Identity(),
        DhConvention convention = DhConvention::kStandard);

  /// A robot with the kinematics and inertias of a URDF's chain (RigidBodyChain::FromUrdfFile:
  /// the same options and errors); its gravity is options.gravity, in the root link's frame.
  /// Named after the URDF's robot. Such a robot has no DH parameters: links() is empty,
  /// base_rotation() the identity and gravity_in_base() the chain's gravity.
  static Robot FromUrdf(const std::string& path, const UrdfOptions& options = {});
  /// The same from a chain already read (its armature included); name empty: the chain's
  /// robot name.
  static Robot FromRigidBodyChain(const RigidBodyChain& chain, std::string name = "");

  const std::string& name() const;
  int num_joints() const;
  /// The DH links (empty for a robot from a URDF).
  const std::vector<LinkParameters>& links() const;
  const Eigen::Matrix3d& base_rotation() const;
  /// The convention of links() (kStandard for a robot from a URDF).
  DhConvention convention() const;
  /// Gravitational acceleration expressed in the DH base frame 0, m/s^2.
  Eigen::Vector3d gravity_in_base() const;
  /// The KDL chain (one segment per joint, frames in base frame 0). For users who want
  /// other KDL solvers; they must include the KDL headers and link KDL themselves.
  const KDL::Chain& chain() const;

  /// tau = M(q) qdd + C(q, qd) qd + G(q), N m, by KDL's recursive Newton-Euler solver.
  /// Throws std::invalid_argument when an argument does not have N entries.
  Eigen::VectorXd InverseDynamics(const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                                  const Eigen::VectorXd& qdd) const;

  /// The three terms of the inverse dynamics, from KDL::ChainDynParam.
  DynamicsComponents Components(const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                                const Eigen::VectorXd& qdd) const;

  /// The joint-space mass matrix M(q), N x N, kg m^2 (symmetric positive definite whenever
  /// every joint moves some mass).
  Eigen::MatrixXd MassMatrix(const Eigen::VectorXd& q) const;

  /// qdd solving M(q) qdd = tau - C(q, qd) qd - G(q), rad/s^2 (Cholesky of M). Throws
  /// std::runtime_error when M(q) is not numerically positive definite, which happens only
  /// for robots in which some joint moves no mass (never for the factories below).
  Eigen::VectorXd ForwardDynamics(const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                                  const Eigen::VectorXd& tau) const;

 private:
  struct Model;
  explicit Robot(std::shared_ptr<const Model> model);
  std::shared_ptr<const Model> model_;
};

/// A robot with N = num_joints in [1, 7] and random parameters drawn from a generator
/// seeded with `seed` (the same seed gives the same robot on every platform):
/// - DH: a in [0.1, 0.5] m, d in [0, 0.3] m, theta_offset in [-pi/4, pi/4] rad, twist
///   alpha alternating +pi/2, -pi/2, +pi/2, ...;
/// - mass in [0.5, 5] kg; centre of mass in [-0.15, 0.15]^3 m of the link frame;
/// - inertia of a solid box with random edge lengths in [0.04, 0.4] m, turned by a random
///   rotation: symmetric positive definite, principal moments satisfying the triangle
///   inequalities.
/// The base is turned (base_rotation = rotation by pi/2 about x) so that joint 1 turns about a
/// horizontal axis and gravity loads every joint, also for N = 1. Name "random<N>_seed<seed>".
/// Throws std::invalid_argument unless 1 <= num_joints <= 7.
Robot RandomRobot(int num_joints, std::uint64_t seed);

/// A planar two-link arm moving in a vertical plane (both joint axes horizontal; q = 0
/// stretches the arm horizontally, positive q lifts it). Link lengths 0.4 and 0.3 m, masses
/// 2.0 and 1.0 kg, centres of mass at mid-link, inertias of solid rods of radius 3 cm.
/// Name "two_link_arm".
Robot TwoLinkArm();

/// A three-joint spatial arm: a vertical waist joint followed by a horizontal shoulder and
/// elbow (DH: d1 = 0.3 m, alpha1 = pi/2; a2 = 0.4 m; a3 = 0.3 m), link masses 3.0, 2.0 and
/// 1.0 kg, centres of mass at mid-link, rod-like inertias. Name "three_link_arm".
Robot ThreeLinkArm();

/// The Unimation PUMA 560 with the standard-DH kinematic and link inertial parameters of
/// P. Corke and B. Armstrong-Helouvry, "A search for consensus among model parameters
/// reported for the PUMA 560 robot", Proc. IEEE ICRA 1994, pp. 1608-1613 (as also used by
/// the Robotics Toolbox `puma560` model), which build on B. Armstrong, O. Khatib and
/// J. Burdick, "The explicit dynamic model and inertial parameters of the PUMA 560 arm",
/// Proc. IEEE ICRA 1986. Includes the armature (motor rotor inertia times gear ratio
/// squared) of that model; friction is separate (see Puma560Friction in friction.h).
/// Name "puma560".
Robot Puma560();

/// A 7-joint arm with the kinematics of the Franka Emika Panda (Franka's published modified-DH
/// table: d1 = 0.333, d3 = 0.316, a4 = 0.0825, a5 = -0.0825, d5 = 0.384, a7 = 0.088 m; twists
/// 0, -pi/2, pi/2, pi/2, -pi/2, pi/2, pi/2; the flange's 0.107 m is not part of the chain),
/// the link masses and centres of mass identified by C. Gaz, M. Cognetti, A. Oliva,
/// P. Robuffo Giordano and A. De Luca, "Dynamic identification of the Franka Emika Panda robot
/// with retrieval of feasible parameters using penalty-based optimization", IEEE RA-L 4(4),
/// 2019, and rotational inertias about the centres of mass as reported by F. Diaz Ledezma and
/// S. Haddadin (IEEE-RAS Humanoids 2017; positive definite, triangle inequalities hold: the
/// inertia tensors as commonly transcribed from the former are not all positive definite). Joint 1 is vertical, gravity
/// along -z of the base. No armature (the Panda's is not published with these). Name "panda".
Robot Panda();

/// A 6-joint arm with the kinematics and link masses of the Universal Robots UR10 (CB series):
/// the standard-DH table and the masses and centres of mass that Universal Robots publishes
/// ("Parameters for calculations of kinematics and dynamics": d1 = 0.1273, a2 = -0.612,
/// a3 = -0.5723, d4 = 0.163941, d5 = 0.1157, d6 = 0.0922 m; twists pi/2, 0, 0, pi/2, -pi/2, 0;
/// masses 7.1, 12.7, 4.27, 2.0, 2.0, 0.365 kg). Its joint angles are the controller's (all zero:
/// the arm stretched out horizontally; q2 = q4 = -pi/2: upright). The rotational inertias are
/// not published: those of solid cylinders of the links' size (an estimate, good as the prior
/// of an rbd fit that the data correct). Joint 1 is vertical, gravity along -z of the base.
/// No armature. Name "ur10".
Robot Ur10();

/// The simulator's robots by name: "two_link", "three_link", "puma560", "panda", "ur10", and
/// "random1" .. "random7" (RandomRobot(N, 1)); '-' may stand for '_' ("two-link"). Throws
/// std::invalid_argument naming the robot and listing the names.
Robot RobotByName(const std::string& name);

}  // namespace sim
}  // namespace structgp

#endif  // STRUCTGP_SIM_ROBOT_H_
