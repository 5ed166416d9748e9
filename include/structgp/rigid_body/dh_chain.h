#ifndef STRUCTGP_RIGID_BODY_DH_CHAIN_H_
#define STRUCTGP_RIGID_BODY_DH_CHAIN_H_

/// @file
/// A serial chain of revolute joints given by the kinematic numbers its torques depend on, and
/// written as a URDF: the space that IdentifyChain (fit/chain_identification.h) searches.
///
/// Kinematic parameters, modified DH (J. J. Craig): the frame of joint i is that of joint i-1
/// moved by RotX(alpha_i) TransX(a_i) RotZ(theta_i) TransZ(d_i), and joint i turns about its z
/// axis. "tilt" is alpha_1 (axis 1 leans from the vertical, gravity along -z of the root), then
/// theta_1, alpha_2, a_2, and theta_i, d_i, alpha_{i+1}, a_{i+1} for i = 2..N-1: 4N - 4 numbers
/// (1 for N = 1). The others change no torque: a_1 and d_1 move the whole arm along or away from
/// axis 1, theta_N and d_N only move link N's frame, whose inertial parameters absorb it. Angles
/// in rad, lengths in m. The same torques can come from several chains (with two parallel axes
/// only the sum of the offsets along them shows, for example).

#include <optional>
#include <string>
#include <vector>

#include "structgp/core/types.h"

namespace structgp {

class RigidBodyChain;

/// One kinematic parameter: which DH number of which joint it is.
struct ChainKinematicParameter {
  enum class Field { kAlpha, kA, kTheta, kD };
  int joint = 0;  ///< 0-based
  Field field = Field::kAlpha;
  std::string name;  ///< "tilt", "theta1", "alpha2", "a2", ...
  /// a or d: a length (m); otherwise an angle (rad).
  bool is_length() const { return field == Field::kA || field == Field::kD; }
};

/// The kinematic parameters of an N-joint chain, in order (N >= 1; throws
/// std::invalid_argument otherwise).
std::vector<ChainKinematicParameter> ChainKinematicLayout(int num_joints);
/// 4N - 4 for N >= 2, 1 for N = 1 (the tilt): ChainKinematicLayout(N).size().
int NumChainKinematicParameters(int num_joints);
/// The names of ChainKinematicLayout(N), in order.
std::vector<std::string> ChainKinematicNames(int num_joints);

/// The URDF of the chain with these kinematic parameters: root link "base", moving joints
/// "joint1".."jointN" (continuous, about z), links "link1".."linkN" each with the placeholder
/// inertial 1 kg at the link origin, inertia 0.01 kg m^2 about each axis. Throws
/// std::invalid_argument for a wrong size, a non-finite entry, or a robot name with other
/// characters than letters, digits, '_', '-' and '.'.
std::string ChainUrdf(int num_joints, const ConstVectorRef& kinematics,
                      const std::string& robot_name = "identified_chain");

/// The kinematic parameters of a URDF that ChainUrdf wrote, as it wrote it (its comment holds
/// the DH numbers of each joint; the document written again from them must be this one, its
/// numbers to 1e-9 relative, the rest character for character), so that a chain found by
/// IdentifyChain can be searched again from where it was; nullopt for any other URDF: a
/// manufacturer's, or one edited since (a new robot name is no edit).
std::optional<Vector> ChainKinematicsOfUrdf(const std::string& urdf);

/// The same for a chain read from a URDF: its kinematic parameters when the URDF is one
/// ChainUrdf wrote, read whole (all its joints, "base" to the last link) under the gravity
/// IdentifyChain assumes (0, 0, -9.81 in the root frame); nullopt otherwise (a part of such a
/// URDF, another gravity, any other URDF).
std::optional<Vector> ChainKinematicsOf(const RigidBodyChain& chain);

/// Throws std::invalid_argument, naming `where`, for a robot name that a URDF's XML cannot hold
/// as written (other characters than letters, digits, '_', '-' and '.').
void CheckRobotName(const std::string& where, const std::string& name);

}  // namespace structgp

#endif  // STRUCTGP_RIGID_BODY_DH_CHAIN_H_
