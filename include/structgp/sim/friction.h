#ifndef STRUCTGP_SIM_FRICTION_H_
#define STRUCTGP_SIM_FRICTION_H_

/// @file
/// Joint friction for simulated data: per joint, Coulomb + viscous + optional Stribeck
/// friction as a function of the joint velocity only,
///     tau_f(qd) = F_c s(qd) + F_v qd + F_s exp(-(qd / v_s)^2) s(qd),
/// where s(qd) = sign(qd) (with sign(0) = 0), or tanh(qd / w) when a smoothing velocity
/// w > 0 is given. tau_f has the sign of qd: it is the extra torque, N m, that the motor
/// supplies to overcome friction, so a measured torque is tau = tau_rigid_body + tau_f.

#include <vector>

#include <Eigen/Core>

namespace structgp {
namespace sim {

/// Friction parameters of one joint. All are >= 0.
struct JointFriction {
  /// Coulomb friction F_c, N m.
  double coulomb = 0.0;
  /// Viscous friction F_v, N m s/rad.
  double viscous = 0.0;
  /// Stribeck excess F_s (static minus Coulomb friction), N m. 0 disables the term.
  double stribeck = 0.0;
  /// Stribeck velocity v_s, rad/s (> 0).
  double stribeck_velocity = 0.1;
  /// Width w of the tanh that replaces sign(qd), rad/s. 0 means the discontinuous sign.
  double smoothing_velocity = 0.0;
};

/// Friction torques of an N-joint robot. Immutable after construction.
class FrictionModel {
 public:
  /// One JointFriction per joint. Throws std::invalid_argument on an empty list or on a
  /// negative or non-finite parameter (or a stribeck_velocity that is not > 0).
  explicit FrictionModel(std::vector<JointFriction> joints);

  /// The same parameters for each of num_joints >= 1 joints.
  static FrictionModel Uniform(int num_joints, const JointFriction& joint);

  int num_joints() const { return static_cast<int>(joints_.size()); }
  const std::vector<JointFriction>& joints() const { return joints_; }

  /// tau_f(qd), N m (size N), for joint velocities qd (rad/s, size N). Throws
  /// std::invalid_argument on a size mismatch.
  Eigen::VectorXd Torque(const Eigen::VectorXd& qd) const;

  /// The friction torque of joint `joint` (0-based) at velocity qd (rad/s), N m.
  double JointTorque(int joint, double qd) const;

 private:
  std::vector<JointFriction> joints_;
};

/// Joint-side friction of the PUMA 560 from the motor-side values of Corke and
/// Armstrong-Helouvry (ICRA 1994; see Puma560 in robot.h): viscous F_v = B G^2 and Coulomb
/// F_c = |G| (|Tc+| + |Tc-|) / 2 (the model here is symmetric, so the two directions are
/// averaged), for motor viscous friction B, Coulomb friction Tc+/Tc- and gear ratio G. No
/// Stribeck term; sign(qd) unless smoothing_velocity > 0 (rad/s) is given.
FrictionModel Puma560Friction(double smoothing_velocity = 0.0);

}  // namespace sim
}  // namespace structgp

#endif  // STRUCTGP_SIM_FRICTION_H_
