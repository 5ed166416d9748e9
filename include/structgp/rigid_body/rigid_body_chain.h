#ifndef STRUCTGP_RIGID_BODY_RIGID_BODY_CHAIN_H_
#define STRUCTGP_RIGID_BODY_RIGID_BODY_CHAIN_H_

/// @file
/// A serial chain of rigid bodies read from a URDF, its inverse dynamics and its inertial
/// parameter regressor. Orocos KDL computes the dynamics (recursive Newton-Euler, ChainDynParam);
/// the URDF is read by urdfdom and turned into a KDL tree by kdl_parser. This header exposes
/// Eigen types only.
///
/// Conventions. Joint angles q in rad, velocities qd in rad/s, accelerations qdd in rad/s^2,
/// torques in N m; every joint vector has num_joints() entries, ordered from root to tip. The
/// equation of motion is
///     tau = M(q) qdd + C(q, qd) qd + G(q) = Y(q, qd, qdd) pi,
/// linear in the inertial parameters pi (see num_parameters()).
///
/// The chain. From the root link to the tip link of the URDF's tree. Revolute and continuous
/// joints move; a link behind a fixed joint is rigidly part of the moving link before it and
/// its inertia is lumped into that link (also for fixed-joint branches hanging off the chain,
/// such as a sensor or a flange). Links before the first moving joint carry no torque and have
/// no parameters. Branches hanging off the chain behind a moving joint (and everything past the
/// tip) are not part of the model.

#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "structgp/core/types.h"

namespace KDL {
class Chain;
}  // namespace KDL

namespace structgp {

/// Which part of a URDF's tree makes the chain, and the gravity acting on it.
struct UrdfOptions {
  /// Name of the chain's base link; empty: the URDF's root link.
  std::string root;
  /// Name of the chain's last link; empty: the single leaf of the tree below root (an error
  /// naming the leaves when there are several).
  std::string tip;
  /// Gravitational acceleration in the root link's frame, m/s^2.
  Eigen::Vector3d gravity{0.0, 0.0, -9.81};
};

/// An N-joint serial chain of rigid bodies with its inertial parameters.
///
/// Parameters. 10 per moving link k (k = 1..N, the link driven by joint k, with every link
/// lumped into it), in this order:
///     [m, m cx, m cy, m cz, Ixx, Ixy, Ixz, Iyy, Iyz, Izz]
/// mass (kg), first moments (kg m) and the inertia tensor's entries about the link frame's
/// origin, in the link frame's axes (kg m^2; Ixy is the matrix entry, -integral of x y dm, as
/// in URDF), then one armature per joint (rotor inertia reflected to the joint, kg m^2; it adds
/// armature_j qdd_j to tau_j), P = num_parameters() = 11 N. The link frame is the URDF frame of
/// the moving link (the child link of joint k). A URDF has no armature: FromUrdf* give 0.
///
/// Immutable after construction; copies are cheap (they share the KDL data) and every const
/// method is safe to call concurrently. Regressor with a Workspace never allocates; the other
/// evaluations build small KDL solvers per call.
class RigidBodyChain {
 public:
  /// Reads the URDF file at `path` (see FromUrdfString). Throws std::invalid_argument naming
  /// the file when it cannot be read.
  static RigidBodyChain FromUrdfFile(const std::string& path, const UrdfOptions& options = {});

  /// Reads a URDF document. `source` names it in error messages (a file name). Throws
  /// std::invalid_argument, naming `source` and the problem, on: XML or URDF urdfdom cannot
  /// parse (with urdfdom's own messages); a root or tip link the URDF does not have (listing
  /// its links); a tip not below the root; several leaves below the root and no tip (listing
  /// them); a prismatic, floating or planar joint on the chain or lumped into it; no moving
  /// joint between root and tip; a non-finite gravity.
  static RigidBodyChain FromUrdfString(const std::string& xml, const UrdfOptions& options = {},
                                       const std::string& source = "<string>");

  /// Number of moving (revolute or continuous) joints N.
  int num_joints() const;
  /// The moving joints' URDF names, root to tip.
  const std::vector<std::string>& joint_names() const;
  /// The moving links' URDF names (the child link of each moving joint), root to tip.
  const std::vector<std::string>& link_names() const;
  /// The URDF's robot name.
  const std::string& robot_name() const;
  /// The chain's root and tip link names.
  const std::string& root() const;
  const std::string& tip() const;
  /// Where the chain was read from (the file name, or FromUrdfString's `source`).
  const std::string& source() const;
  /// The URDF document the chain was read from (model files keep it, so that a model carries
  /// its robot).
  const std::string& urdf() const;
  /// Gravitational acceleration in the root frame, m/s^2.
  const Eigen::Vector3d& gravity() const;

  /// P = 11 N: 10 inertial parameters per link, then one armature per joint.
  int num_parameters() const;
  /// "m@k", "mcx@k", "mcy@k", "mcz@k", "Ixx@k", "Ixy@k", "Ixz@k", "Iyy@k", "Iyz@k", "Izz@k"
  /// for link k = 1..N, then "armature@k".
  std::vector<std::string> parameter_names() const;
  /// The chain's parameters pi (the URDF's values, lumped; armature 0 from a URDF).
  const Vector& parameters() const;
  /// The same kinematics with parameters pi (P entries, finite; physical consistency is not
  /// required: see CheckPhysicalConsistency). Throws std::invalid_argument otherwise.
  RigidBodyChain WithParameters(const Vector& pi) const;
  /// The chain with a point mass (kg) at c (m, in the last link's frame) added to its last link:
  /// a payload. Its inertial parameters add m, m c and m (|c|^2 1 - c c^T) to the link's.
  /// Throws std::invalid_argument for a negative or non-finite mass or a non-finite c.
  RigidBodyChain WithPayload(double mass, const Eigen::Vector3d& c) const;

  /// tau = M(q) qdd + C(q, qd) qd + G(q), N m, by KDL's recursive Newton-Euler solver (the
  /// armature included). Throws std::invalid_argument on a wrong size or a non-finite entry.
  Vector InverseDynamics(const ConstVectorRef& q, const ConstVectorRef& qd,
                         const ConstVectorRef& qdd) const;
  /// M(q), N x N, kg m^2, by KDL::ChainDynParam (armature on the diagonal).
  Matrix MassMatrix(const ConstVectorRef& q) const;
  /// C(q, qd) qd and G(q), N m, by KDL::ChainDynParam.
  Vector Coriolis(const ConstVectorRef& q, const ConstVectorRef& qd) const;
  Vector Gravity(const ConstVectorRef& q) const;

  /// Which terms of the inverse dynamics a regressor reproduces.
  enum class Terms {
    kAll,        ///< M(q) qdd + C(q, qd) qd + G(q)
    kInertial,   ///< M(q) qdd (armature included)
    kCoriolis,   ///< C(q, qd) qd
    kGravity,    ///< G(q)
  };

  /// Scratch memory of Regressor for one thread: a copy of the chain's kinematics and its KDL
  /// solvers. Made by MakeWorkspace; works for this chain and every chain WithParameters makes
  /// from it (they share the kinematics). Move-only.
  class Workspace {
   public:
    Workspace(Workspace&&) noexcept;
    Workspace& operator=(Workspace&&) noexcept;
    ~Workspace();

   private:
    friend class RigidBodyChain;
    struct Impl;
    explicit Workspace(std::unique_ptr<Impl> impl);
    std::unique_ptr<Impl> impl_;
  };
  Workspace MakeWorkspace() const;

  /// The regressor Y (N x P): the selected terms of the inverse dynamics are Y pi for every
  /// parameter vector pi of this kinematics. Column j is KDL's recursive Newton-Euler torque of
  /// the chain whose only inertia is basis inertia j, evaluated on the chain cut after that
  /// link (the joints past it get 0); the armature columns are qdd_j on joint j for kAll and
  /// kInertial, zero otherwise. 10 N evaluations of 1..N joints: about 70 us at N = 7
  /// (bench/bench_rigid_body). Y must be N x P. Never allocates. Throws
  /// std::invalid_argument on a wrong size, a non-finite entry, or a workspace of another
  /// kinematics (the message is only built then).
  void Regressor(const ConstVectorRef& q, const ConstVectorRef& qd, const ConstVectorRef& qdd,
                 Terms terms, MatrixRef Y, Workspace& workspace) const;
  /// The same, allocating its workspace and result.
  Matrix Regressor(const ConstVectorRef& q, const ConstVectorRef& qd, const ConstVectorRef& qdd,
                   Terms terms = Terms::kAll) const;

  /// The KDL chain with these parameters (fixed segments kept, with zero inertia; armature as
  /// the joints' inertia). For users of other KDL solvers, who include and link KDL themselves.
  const KDL::Chain& kdl_chain() const;

 private:
  struct Kinematics;
  struct Model;
  explicit RigidBodyChain(std::shared_ptr<const Model> model);
  void RequireState(const char* what, const ConstVectorRef& v) const;
  std::shared_ptr<const Model> model_;
};

}  // namespace structgp

#endif  // STRUCTGP_RIGID_BODY_RIGID_BODY_CHAIN_H_
