#ifndef STRUCTGP_SRC_SIM_RANDOM_H_
#define STRUCTGP_SRC_SIM_RANDOM_H_

// Portable random draws for the simulator. std::mt19937_64 is fully specified by the C++
// standard, but the std::*_distribution classes are not, so the same seed could give other
// numbers with another standard library. The draws below are defined here, so a seed gives
// the same robots, trajectories and noise everywhere.

#include <cmath>
#include <cstdint>
#include <random>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace structgp {
namespace sim {
namespace internal {

// Uniform on [0, 1): the top 53 bits of one 64-bit draw.
inline double Uniform01(std::mt19937_64& rng) {
  constexpr double kTwoToMinus53 = 1.0 / 9007199254740992.0;
  return static_cast<double>(rng() >> 11) * kTwoToMinus53;
}

// Uniform on [lo, hi).
inline double Uniform(std::mt19937_64& rng, double lo, double hi) {
  return lo + (hi - lo) * Uniform01(rng);
}

// Standard normal by the Box-Muller transform (one of the pair is used).
inline double StandardNormal(std::mt19937_64& rng) {
  constexpr double kTwoPi = 6.283185307179586476925286766559;
  const double u1 = 1.0 - Uniform01(rng);  // in (0, 1], so the log is finite
  const double u2 = Uniform01(rng);
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(kTwoPi * u2);
}

// A rotation drawn uniformly from SO(3): a normalised 4-vector of independent normals is a
// uniformly distributed unit quaternion.
inline Eigen::Matrix3d RandomRotation(std::mt19937_64& rng) {
  Eigen::Quaterniond quaternion(StandardNormal(rng), StandardNormal(rng), StandardNormal(rng),
                                StandardNormal(rng));
  quaternion.normalize();
  return quaternion.toRotationMatrix();
}

}  // namespace internal
}  // namespace sim
}  // namespace structgp

#endif  // STRUCTGP_SRC_SIM_RANDOM_H_
