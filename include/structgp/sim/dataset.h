#ifndef STRUCTGP_SIM_DATASET_H_
#define STRUCTGP_SIM_DATASET_H_

/// @file
/// Simulated inverse-dynamics data sets: the torques a robot needs to follow a trajectory,
/// with optional joint friction, measurement noise and normalisation.
///
/// For sample i, the noise-free torque (N m) is
///     tau_i = M(q_i) qdd_i + C(q_i, qd_i) qd_i + G(q_i) + tau_f(qd_i),
/// and the data set holds Y_i = tau_i ./ torque_scale + e_i with e_i ~ N(0, noise_std^2 I).

#include <cstdint>
#include <optional>
#include <string>

#include <Eigen/Core>

#include "structgp/io/robot_data.h"
#include "structgp/sim/friction.h"
#include "structgp/sim/robot.h"
#include "structgp/sim/trajectory.h"

namespace structgp {
namespace sim {

/// Inputs and targets for an N-joint robot, one sample per row (m samples).
struct Dataset {
  Eigen::VectorXd t;  ///< Sample times, s (size m).
  /// States, m x 3N: columns q_1..q_N (rad), qd_1..qd_N (rad/s), qdd_1..qdd_N (rad/s^2).
  Eigen::MatrixXd X;
  /// Joint torques, m x N, in N m divided by torque_scale (column j by torque_scale(j)).
  Eigen::MatrixXd Y;
  /// Per-joint divisor applied to the torques, N m (size N); all ones without
  /// normalisation. Multiply Y's columns by it to get N m back.
  Eigen::VectorXd torque_scale;

  Eigen::Index num_samples() const { return X.rows(); }
  int num_joints() const { return static_cast<int>(Y.cols()); }
};

/// How the simulated torques are scaled.
enum class TorqueNormalization {
  /// Torques in N m (torque_scale = 1).
  kNone,
  /// Each joint divided by its own max_i |tau_ij|, so that max |Y_j| = 1 per joint.
  kPerJoint,
  /// All joints divided by the one max_ij |tau_ij|, so that max |Y| = 1 overall.
  kGlobal,
};

/// Knobs of Simulate.
struct SimulationOptions {
  /// Joint friction added to the rigid-body torques; none when empty. Must have N joints.
  std::optional<FrictionModel> friction;
  /// Standard deviation of the additive Gaussian noise, in the units of Y (N m without
  /// normalisation, else a fraction of the scale). >= 0.
  double noise_std = 0.0;
  /// The scale is computed from the noise-free torques, so it does not depend on the noise
  /// draw; with noise, |Y| can exceed 1 slightly. A joint whose torque is zero throughout
  /// keeps scale 1.
  TorqueNormalization normalization = TorqueNormalization::kNone;
  /// Seed of the noise generator (std::mt19937_64).
  std::uint64_t seed = 0;
};

/// The noise-free torque terms of every sample, each m x N in the units of Y (N m divided
/// by torque_scale). inertial + coriolis + gravity + friction is the noise-free Y.
struct TorqueComponents {
  Eigen::MatrixXd inertial;      ///< M(q) qdd
  Eigen::MatrixXd coriolis;      ///< C(q, qd) qd
  Eigen::MatrixXd gravity;       ///< G(q)
  Eigen::MatrixXd friction;      ///< tau_f(qd) (zero without a friction model)
  Eigen::VectorXd torque_scale;  ///< As in Dataset, N m (size N).

  /// inertial + coriolis + gravity + friction.
  Eigen::MatrixXd Total() const { return inertial + coriolis + gravity + friction; }
};

/// Simulates the torques of `robot` along `trajectory` (KDL recursive Newton-Euler).
/// Throws std::invalid_argument when the trajectory or the friction model does not have
/// robot.num_joints() joints, or on a negative noise_std.
Dataset Simulate(const Robot& robot, const Trajectory& trajectory,
                 const SimulationOptions& options = SimulationOptions());

/// The data set as robot data in N m (Y's columns multiplied back by torque_scale), with its
/// times, as if read from `source` (which only names it in messages).
RobotData ToRobotData(const Dataset& dataset, const std::string& source = "");

/// The noise-free terms of the same torques, scaled exactly as Simulate scales them with the
/// same options (options.noise_std and options.seed are not used).
TorqueComponents SimulateComponents(const Robot& robot, const Trajectory& trajectory,
                                    const SimulationOptions& options = SimulationOptions());

}  // namespace sim
}  // namespace structgp

#endif  // STRUCTGP_SIM_DATASET_H_
