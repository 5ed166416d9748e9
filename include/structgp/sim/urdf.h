#ifndef STRUCTGP_SIM_URDF_H_
#define STRUCTGP_SIM_URDF_H_

/// @file
/// The simulator's DH robots as URDF documents and as rigid-body chains.
///
/// A standard-DH link i moves frame i-1 to frame i by Rz(q_i + theta_i) Tz(d_i) Tx(a_i)
/// Rx(alpha_i); a URDF joint applies its fixed origin, then turns about its axis. The URDF frame
/// of link i is therefore frame i-1 turned by Rz(theta_i + q_i) (joint i turns about z), the
/// rest of DH link i, B_i = Tz(d_i) Tx(a_i) Rx(alpha_i), goes into the origin of joint i+1, and
/// link i's inertial (centre of mass and inertia, given in DH frame i) sits at B_i in its URDF
/// frame. A fixed joint with origin R_base from the link "world" (gravity along its -z) to
/// "base" (DH frame 0) carries the base rotation, and one with origin B_N from link N to "tool"
/// gives DH frame N. Joints are "continuous", named joint1..jointN, links link1..linkN.
///
/// A modified-DH link i moves frame i-1 to frame i by Rx(alpha) Tx(a) Rz(q_i + theta_i) Tz(d_i)
/// and frame i lies on joint i's axis, so the URDF frame of link i is DH frame i itself: joint
/// i's origin is Rx(alpha) Tx(a) Rz(theta_i) Tz(d_i), its axis z, and the inertial sits at the
/// centre of mass with no rotation; "tool" is DH frame N.
///
/// URDF has no armature (reflected rotor inertia): the document lists each joint's in a comment
/// only, and a chain read from it has armature 0; ToRigidBodyChain puts it back.

#include <string>

#include "structgp/rigid_body/rigid_body_chain.h"
#include "structgp/sim/robot.h"

namespace structgp {
namespace sim {

/// The URDF document of a DH robot (each number the shortest decimal that reads back to the
/// same double). Throws std::invalid_argument for a robot read from a URDF (no DH
/// parameters).
std::string ToUrdf(const Robot& robot);

/// The robot as a rigid-body chain from "world" to "tool" with gravity (0, 0, -9.81) m/s^2 in
/// the world frame and the armature of the DH links: the chain of RigidBodyChain::FromUrdfString
/// (ToUrdf(robot)) with the armature parameters set. Throws std::invalid_argument for a robot
/// read from a URDF, like ToUrdf.
RigidBodyChain ToRigidBodyChain(const Robot& robot);

}  // namespace sim
}  // namespace structgp

#endif  // STRUCTGP_SIM_URDF_H_
