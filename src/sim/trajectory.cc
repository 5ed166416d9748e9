#include "structgp/sim/trajectory.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "structgp/core/validate.h"
#include "random.h"

namespace structgp {
namespace sim {
namespace {

constexpr double kTwoPi = 6.283185307179586476925286766559;

// Relative slack when counting samples, so that duration / dt = 1000 - 1e-13 (rounding of an
// exact multiple) still gives 1000 samples and not 1001.
constexpr double kSampleCountSlack = 1e-9;

void RequireJoints(const char* what, int num_joints) {
  if (num_joints < 1) {
    throw std::invalid_argument(std::string(what) + ": expected at least 1 joint, got " +
                                std::to_string(num_joints));
  }
}

// Samples t = 0, dt, ... < duration.
Trajectory Allocate(int num_joints, double duration, double dt) {
  const auto m = static_cast<Eigen::Index>(std::ceil(duration / dt - kSampleCountSlack));
  Trajectory trajectory;
  trajectory.t.resize(m);
  for (Eigen::Index i = 0; i < m; ++i) trajectory.t(i) = static_cast<double>(i) * dt;
  trajectory.q.resize(m, num_joints);
  trajectory.qd.resize(m, num_joints);
  trajectory.qdd.resize(m, num_joints);
  return trajectory;
}

// Quintic p(tau), tau in [0, T], with p(0) = p0, p'(0) = v0, p''(0) = a0, p(T) = p1,
// p'(T) = v1, p''(T) = a1. Written as p0 + v0 tau + a0 tau^2 / 2 + x s^3 + y s^4 + z s^5 with
// s = tau / T; x, y, z solve the three end conditions.
struct Quintic {
  Quintic(double p0, double v0, double a0, double p1, double v1, double a1, double duration)
      : c0(p0), c1(v0), c2(0.5 * a0), T(duration) {
    const double rest = p1 - p0 - v0 * T - 0.5 * a0 * T * T;  // what x + y + z must add up to
    const double slope = (v1 - v0 - a0 * T) * T;
    const double curve = (a1 - a0) * T * T;
    x = 10.0 * rest - 4.0 * slope + 0.5 * curve;
    y = -15.0 * rest + 7.0 * slope - curve;
    z = 6.0 * rest - 3.0 * slope + 0.5 * curve;
  }

  void Evaluate(double tau, double* p, double* v, double* a) const {
    const double s = tau / T;
    const double s2 = s * s;
    *p = c0 + tau * (c1 + tau * c2) + s2 * s * (x + s * (y + s * z));
    *v = c1 + 2.0 * c2 * tau + s2 * (3.0 * x + s * (4.0 * y + s * 5.0 * z)) / T;
    *a = 2.0 * c2 + s * (6.0 * x + s * (12.0 * y + s * 20.0 * z)) / (T * T);
  }

  double c0, c1, c2, T;
  double x = 0.0, y = 0.0, z = 0.0;
};

}  // namespace

Trajectory UniformBox(int num_joints, Eigen::Index num_samples, double q_range, double qd_range,
                      double qdd_range, std::uint64_t seed, double dt) {
  RequireJoints("UniformBox", num_joints);
  if (num_samples < 0) {
    throw std::invalid_argument("UniformBox: expected num_samples >= 0, got " +
                                std::to_string(num_samples));
  }
  RequireInRange("UniformBox: q_range (rad)", q_range, 0.0, HUGE_VAL, true);
  RequireInRange("UniformBox: qd_range (rad/s)", qd_range, 0.0, HUGE_VAL, true);
  RequireInRange("UniformBox: qdd_range (rad/s^2)", qdd_range, 0.0, HUGE_VAL, true);
  RequireInRange("UniformBox: dt (s)", dt, 0.0, HUGE_VAL);
  std::mt19937_64 rng(seed);
  Trajectory trajectory;
  trajectory.t.resize(num_samples);
  trajectory.q.resize(num_samples, num_joints);
  trajectory.qd.resize(num_samples, num_joints);
  trajectory.qdd.resize(num_samples, num_joints);
  // Sample by sample (q, then qd, then qdd), so that a longer run extends a shorter one.
  for (Eigen::Index i = 0; i < num_samples; ++i) {
    trajectory.t(i) = static_cast<double>(i) * dt;
    for (int j = 0; j < num_joints; ++j)
      trajectory.q(i, j) = internal::Uniform(rng, -q_range, q_range);
    for (int j = 0; j < num_joints; ++j)
      trajectory.qd(i, j) = internal::Uniform(rng, -qd_range, qd_range);
    for (int j = 0; j < num_joints; ++j) {
      trajectory.qdd(i, j) = internal::Uniform(rng, -qdd_range, qdd_range);
    }
  }
  return trajectory;
}

Trajectory ViaPoints(int num_joints, double duration, double dt, int num_vias, double speed_scale,
                     double q_range, std::uint64_t seed, ViaVelocity via_velocity) {
  RequireJoints("ViaPoints", num_joints);
  RequireInRange("ViaPoints: duration (s)", duration, 0.0, HUGE_VAL);
  RequireInRange("ViaPoints: dt (s)", dt, 0.0, HUGE_VAL);
  if (num_vias < 2) {
    throw std::invalid_argument("ViaPoints: expected num_vias >= 2, got " +
                                std::to_string(num_vias));
  }
  RequireInRange("ViaPoints: speed_scale", speed_scale, 0.0, HUGE_VAL);
  RequireInRange("ViaPoints: q_range (rad)", q_range, 0.0, HUGE_VAL, true);

  std::mt19937_64 rng(seed);
  Eigen::MatrixXd vias(num_vias, num_joints);  // row k: via point k
  for (int k = 0; k < num_vias; ++k) {
    for (int j = 0; j < num_joints; ++j) vias(k, j) = internal::Uniform(rng, -q_range, q_range);
  }
  const double segment_duration = duration / (num_vias * speed_scale);
  Eigen::MatrixXd via_velocities = Eigen::MatrixXd::Zero(num_vias, num_joints);
  if (via_velocity == ViaVelocity::kContinuous) {
    for (int k = 0; k < num_vias; ++k) {
      const int next = (k + 1) % num_vias;
      const int previous = (k + num_vias - 1) % num_vias;
      via_velocities.row(k) = (vias.row(next) - vias.row(previous)) / (2.0 * segment_duration);
    }
  }
  // One quintic per (segment of the loop, joint), built once.
  std::vector<Quintic> segments;
  segments.reserve(static_cast<std::size_t>(num_vias) * num_joints);
  for (int k = 0; k < num_vias; ++k) {
    const int next = (k + 1) % num_vias;
    for (int j = 0; j < num_joints; ++j) {
      segments.emplace_back(vias(k, j), via_velocities(k, j), 0.0, vias(next, j),
                            via_velocities(next, j), 0.0, segment_duration);
    }
  }

  Trajectory trajectory = Allocate(num_joints, duration, dt);
  for (Eigen::Index i = 0; i < trajectory.num_samples(); ++i) {
    const double t = trajectory.t(i);
    const double whole = std::floor(t / segment_duration);
    const double tau = std::max(0.0, t - whole * segment_duration);
    const auto k = static_cast<long long>(whole) % num_vias;
    for (int j = 0; j < num_joints; ++j) {
      segments[static_cast<std::size_t>(k * num_joints + j)].Evaluate(
          tau, &trajectory.q(i, j), &trajectory.qd(i, j), &trajectory.qdd(i, j));
    }
  }
  return trajectory;
}

Trajectory SumOfSines(int num_joints, double duration, double dt, int num_harmonics,
                      double base_frequency, double amplitude, std::uint64_t seed) {
  RequireJoints("SumOfSines", num_joints);
  RequireInRange("SumOfSines: duration (s)", duration, 0.0, HUGE_VAL);
  RequireInRange("SumOfSines: dt (s)", dt, 0.0, HUGE_VAL);
  if (num_harmonics < 1) {
    throw std::invalid_argument("SumOfSines: expected num_harmonics >= 1, got " +
                                std::to_string(num_harmonics));
  }
  RequireInRange("SumOfSines: base_frequency (Hz)", base_frequency, 0.0, HUGE_VAL);
  RequireInRange("SumOfSines: amplitude (rad)", amplitude, 0.0, HUGE_VAL, true);

  std::mt19937_64 rng(seed);
  Eigen::MatrixXd coefficient(num_joints, num_harmonics);
  Eigen::MatrixXd phase(num_joints, num_harmonics);
  for (int j = 0; j < num_joints; ++j) {
    for (int k = 0; k < num_harmonics; ++k) {
      coefficient(j, k) = internal::Uniform(rng, 0.5, 1.0) / (k + 1);
      phase(j, k) = internal::Uniform(rng, 0.0, kTwoPi);
    }
    coefficient.row(j) *= amplitude / coefficient.row(j).sum();
  }

  Trajectory trajectory = Allocate(num_joints, duration, dt);
  trajectory.q.setZero();
  trajectory.qd.setZero();
  trajectory.qdd.setZero();
  for (Eigen::Index i = 0; i < trajectory.num_samples(); ++i) {
    const double t = trajectory.t(i);
    for (int k = 0; k < num_harmonics; ++k) {
      const double omega = kTwoPi * (k + 1) * base_frequency;  // rad/s
      for (int j = 0; j < num_joints; ++j) {
        const double angle = omega * t + phase(j, k);
        const double c = coefficient(j, k);
        const double sine = std::sin(angle);
        trajectory.q(i, j) += c * sine;
        trajectory.qd(i, j) += c * omega * std::cos(angle);
        trajectory.qdd(i, j) -= c * omega * omega * sine;
      }
    }
  }
  return trajectory;
}

}  // namespace sim
}  // namespace structgp
