#ifndef STRUCTGP_RIGID_BODY_CHAIN_IDENTIFICATION_H_
#define STRUCTGP_RIGID_BODY_CHAIN_IDENTIFICATION_H_

/// @file
/// The kinematics of a serial chain of revolute joints found from its joint torques alone, for
/// robots whose URDF is not at hand: the result is a URDF, which the `rbd` models then use as
/// they use a manufacturer's (their inertial parameters are identified from the data).
///
/// The hypothesis space is the rigid-body dynamics of every N-joint revolute chain: where each
/// joint axis lies relative to the one before it (4 numbers, modified Denavit-Hartenberg) and how
/// the first leans against gravity, 4N - 4 numbers in all, with the 11 N inertial parameters
/// (armature included) and, optionally, viscous and Coulomb friction per joint. For fixed
/// kinematics the torques are linear in the inertial parameters and friction coefficients, so
/// least squares eliminates them (variable projection); the kinematics are searched by
/// Levenberg-Marquardt (Ceres, forward differences) from many random starts on evenly spaced
/// rows, each joint's torque divided by its RMS: every start a few iterations on few rows, the
/// best of them to the end; the start of least cost wins and is refined on more rows.
///
/// Kinematic parameters (ChainKinematicNames), modified DH (J. J. Craig): the frame of joint i
/// is that of joint i-1 moved by RotX(alpha_i) TransX(a_i) RotZ(theta_i) TransZ(d_i), and joint i
/// turns about its z axis. "tilt" is alpha_1 (axis 1 leans from the vertical, gravity along -z of
/// the root), then theta_1, alpha_2, a_2, and theta_i, d_i, alpha_{i+1}, a_{i+1} for
/// i = 2..N-1. The others change no torque: a_1 and d_1 move the whole arm along or away from
/// axis 1, theta_N and d_N only move link N's frame, whose inertial parameters absorb it. Angles
/// in rad, lengths in m. The same torques can come from several chains (with two parallel axes
/// only the sum of the offsets along them shows, for example); the URDF is one of them, which is
/// all a model of the torques needs, not a kinematic calibration.

#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "structgp/core/types.h"

namespace structgp {

struct ChainIdentificationOptions {
  /// Viscous and Coulomb friction columns per joint in the least squares (a real arm's friction
  /// would otherwise bend the kinematics to explain it).
  bool friction = true;
  /// Velocity width of the Coulomb term tanh(qd / width), rad/s (> 0).
  double friction_width = 0.01;
  /// Evenly spaced rows of the kinematic search (>= 2; each cost evaluation is a regressor per
  /// row: about 70 us a row at 7 joints).
  int search_rows = 400;
  /// Evenly spaced rows on which the best start is searched again to the end (more than
  /// search_rows; less or equal: no refinement).
  int refine_rows = 2000;
  /// Random starts (>= 1), and the generator's seed. Each is screened: screen_iterations
  /// iterations on screen_rows evenly spaced rows; the kept_starts of least cost then go on to
  /// the end on search_rows rows (all of them when kept_starts >= starts: no screening).
  int starts = 64;
  std::uint64_t seed = 1;
  int kept_starts = 8;
  int screen_rows = 150;
  int screen_iterations = 15;
  /// A start of one's own (NumChainKinematicParameters entries, or empty): kinematics known
  /// roughly, searched to the end beside the kept random starts (it is start number `starts`).
  Vector initial_kinematics;
  /// After the starts: each length of the best chain set to 0 in turn and searched again from
  /// there, kept when the cost falls by 1% (intersecting and coplanar axes that a random start
  /// misses).
  bool length_moves = true;
  /// Levenberg-Marquardt iterations per start (>= 1).
  int max_iterations = 100;
  /// Starts searched at once (>= 1).
  int num_threads = 1;
  /// Name of the robot in the URDF.
  std::string robot_name = "identified_chain";
};

struct ChainIdentificationSummary {
  /// The kinematic parameters of the best start (ChainKinematicNames).
  Vector kinematics;
  /// The kept starts (0-based indices among the random starts, least screening cost first) and
  /// each one's final cost: the mean over the search rows and joints of the squared residual of
  /// the least squares, each joint's torque divided by its RMS (so 1e-4 is a residual of 1% of
  /// every joint's torque).
  std::vector<int> starts;
  std::vector<double> start_costs;
  /// The random start (0-based) whose kinematics won.
  int best_start = -1;
  /// The cost after the length moves, and how many were kept (NaN, 0 without them).
  double moved_cost = std::numeric_limits<double>::quiet_NaN();
  int moves_kept = 0;
  /// The best start's cost after the refinement on refine_rows rows (NaN without it).
  double refined_cost = std::numeric_limits<double>::quiet_NaN();
  /// Per joint, in the torques' units: the RMS of the torque, and of the least-squares residual
  /// on every row with the identified kinematics (the noise, where the chain and the friction
  /// explain the rest).
  Vector torque_rms;
  Vector residual_rms;
  /// Kept starts whose cost is within 1% of the best one's (the same minimum found again).
  int starts_at_best = 0;
  /// The identified chain as a URDF document (placeholder inertias: 1 kg, 0.01 kg m^2).
  std::string urdf;
};

/// 4N - 4 for N >= 2, 1 for N = 1 (the tilt).
int NumChainKinematicParameters(int num_joints);
/// "tilt", "theta1", "alpha2", "a2", "theta2", "d2", "alpha3", "a3", ...
std::vector<std::string> ChainKinematicNames(int num_joints);

/// The URDF of the chain with these kinematic parameters: root link "base", moving joints
/// "joint1".."jointN" (continuous, about z), links "link1".."linkN" each with the placeholder
/// inertial 1 kg at the link origin, inertia 0.01 kg m^2 about each axis. Throws
/// std::invalid_argument for a wrong size, a non-finite entry, or a robot name with other
/// characters than letters, digits, '_', '-' and '.'.
std::string ChainUrdf(int num_joints, const ConstVectorRef& kinematics,
                      const std::string& robot_name = "identified_chain");

/// Searches the kinematics of X's rows (q, qd, qdd of N joints: 3N columns) from the torques Y
/// (N columns). Throws std::invalid_argument on mismatched sizes, a non-finite entry, a joint
/// whose torque is zero throughout, an option out of range, a robot name with other characters
/// than letters, digits, '_', '-' and '.', or fewer rows (of the data, search_rows, or
/// screen_rows when screening) than give twice as many torques as linear parameters (11 N,
/// 13 N with friction: 26 rows). std::runtime_error when no start gives a chain that can be
/// evaluated.
ChainIdentificationSummary IdentifyChain(const ConstMatrixRef& X, const ConstMatrixRef& Y,
                                         const ChainIdentificationOptions& options = {});

}  // namespace structgp

#endif  // STRUCTGP_RIGID_BODY_CHAIN_IDENTIFICATION_H_
