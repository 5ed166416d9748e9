#ifndef STRUCTGP_INTERNAL_POL_CONSTANTS_H_
#define STRUCTGP_INTERNAL_POL_CONSTANTS_H_

/// @file
/// What the kernels of k_pol's three terms (PolFormulaKernel, PolChainKernel) compute from
/// their parameters alone, and how their gradient is assembled (not API).

#include "structgp/core/types.h"

namespace structgp {

namespace internal {

/// theta = 1 / (1 + sigma), c_psi = (1 + theta)^-N, the block scales s_b^2 and the derivatives
/// in log sigma, from the parameters (log sigma, log s_I, log s_C [, log s_G]).
struct PolConstants {
  double theta = 0.5;
  double d_theta = 0.0;  ///< d theta / d log sigma = -theta (1 - theta)
  double c_psi = 1.0;
  double d_c_psi = 0.0;  ///< d c_psi / d log sigma
  double scale_inertial = 1.0;
  double scale_coriolis = 1.0;
  double scale_gravity = 1.0;  ///< 0 without the gravity block

  PolConstants() = default;
  /// From k_pol's shape (the maps' MakePolShape) and the block scales.
  PolConstants(const Vector& parameters, int num_joints, bool include_gravity);
};

/// dk = (d k / d log sigma, 2 s_I^2 k_I, 2 s_C^2 k_C [, 2 s_G^2 k_G]) from the terms k_b
/// (block scales applied): d (s^2 k_b) / d log s = 2 s^2 k_b.
inline void PolGradient(double inertial, double coriolis, double gravity, double d_log_sigma,
                        bool include_gravity, VectorRef dk) {
  dk[0] = d_log_sigma;
  dk[1] = 2.0 * inertial;
  dk[2] = 2.0 * coriolis;
  if (include_gravity) dk[3] = 2.0 * gravity;
}

}  // namespace internal
}  // namespace structgp

#endif  // STRUCTGP_INTERNAL_POL_CONSTANTS_H_
