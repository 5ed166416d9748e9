#ifndef STRUCTGP_SIM_TRAJECTORY_H_
#define STRUCTGP_SIM_TRAJECTORY_H_

/// @file
/// Joint-space trajectories for simulated data sets. Velocities and accelerations are the
/// analytic derivatives of the positions (no numerical differentiation). Every generator is
/// deterministic in its seed, on every platform.

#include <cstdint>

#include <Eigen/Core>

namespace structgp {
namespace sim {

/// m samples of an N-joint trajectory, one sample per row.
struct Trajectory {
  Eigen::VectorXd t;    ///< Sample times, s (size m).
  Eigen::MatrixXd q;    ///< Joint angles, rad (m x N).
  Eigen::MatrixXd qd;   ///< Joint velocities, rad/s (m x N).
  Eigen::MatrixXd qdd;  ///< Joint accelerations, rad/s^2 (m x N).

  Eigen::Index num_samples() const { return q.rows(); }
  int num_joints() const { return static_cast<int>(q.cols()); }
};

/// num_samples independent states, each coordinate uniform: q in [-q_range, q_range] rad,
/// qd in [-qd_range, qd_range] rad/s, qdd in [-qdd_range, qdd_range] rad/s^2 (ranges >= 0).
/// qd and qdd are not derivatives of q here. Times are t_i = i * dt (s, dt > 0), only to
/// order the samples. Throws std::invalid_argument on num_joints < 1, num_samples < 0 or a
/// bad range or dt.
Trajectory UniformBox(int num_joints, Eigen::Index num_samples, double q_range, double qd_range,
                      double qdd_range, std::uint64_t seed, double dt = 0.01);

/// How a ViaPoints trajectory passes its via points.
enum class ViaVelocity {
  /// Stop at every via point: zero velocity and acceleration there.
  kStop,
  /// Pass through every via point with the central-difference velocity
  /// (p_{k+1} - p_{k-1}) / (2 T_seg) and zero acceleration: velocity and acceleration are
  /// continuous along the whole trajectory. Between via points the path may overshoot the
  /// via points' range [-q_range, q_range] somewhat.
  kContinuous,
};

/// A smooth point-to-point trajectory through num_vias >= 2 random via points, each joint
/// uniform in [-q_range, q_range] rad (with kStop, q stays in that range throughout). Consecutive
/// via points are joined by quintic (5th-order) polynomials in time with the boundary velocities
/// and accelerations set by `via_velocity`; after the last via point the path returns to the first,
/// so the motion is a closed loop. Each segment lasts T_seg = duration / (num_vias * speed_scale)
/// s: with speed_scale = 1 the loop is traversed once in `duration`, with speed_scale = s it is
/// traversed s times, with velocities s times and accelerations s^2 times as large. Slow and
/// fast trajectories made with the same seed therefore follow the same path in joint space.
/// Samples at t = 0, dt, 2 dt, ... < duration (m = ceil(duration / dt) samples).
/// Throws std::invalid_argument on num_joints < 1, duration <= 0, dt <= 0, num_vias < 2,
/// speed_scale <= 0 or q_range < 0.
Trajectory ViaPoints(int num_joints, double duration, double dt, int num_vias, double speed_scale,
                     double q_range, std::uint64_t seed,
                     ViaVelocity via_velocity = ViaVelocity::kStop);

/// A periodic excitation trajectory: for each joint n,
///     q_n(t) = sum_{k=1..K} c_nk sin(2 pi k f0 t + phi_nk),
/// with K = num_harmonics >= 1, f0 = base_frequency > 0 (Hz), random phases phi_nk and
/// random positive amplitudes c_nk proportional to 1/k that sum to `amplitude` (rad, >= 0),
/// so |q_n(t)| <= amplitude. Samples at t = 0, dt, ... < duration (m = ceil(duration / dt)).
/// Throws std::invalid_argument on a bad argument.
Trajectory SumOfSines(int num_joints, double duration, double dt, int num_harmonics,
                      double base_frequency, double amplitude, std::uint64_t seed);

}  // namespace sim
}  // namespace structgp

#endif  // STRUCTGP_SIM_TRAJECTORY_H_
