#ifndef STRUCTGP_SRC_SIM_PUMA560_DATA_H_
#define STRUCTGP_SRC_SIM_PUMA560_DATA_H_

// Parameters of the Unimation PUMA 560 in standard DH convention, from P. Corke and
// B. Armstrong-Helouvry, "A search for consensus among model parameters reported for the
// PUMA 560 robot", Proc. IEEE ICRA 1994, pp. 1608-1613, as tabulated in the Robotics
// Toolbox model `puma560`. SI units; centres of mass in the link frame, inertias about the
// centre of mass in link-frame axes. Rotor inertia, gear ratio and friction are on the
// motor side; Coulomb friction is given for positive and negative motor velocity.

namespace structgp {
namespace sim {
namespace internal {

struct Puma560Row {
  double a;              // m
  double alpha;          // rad
  double d;              // m
  double mass;           // kg
  double cx, cy, cz;     // m
  double ixx, iyy, izz;  // kg m^2
  double rotor_inertia;  // kg m^2, motor side
  double gear_ratio;     // motor turns per joint turn (sign: direction of the motor)
  double viscous;        // N m s/rad, motor side
  double coulomb_positive, coulomb_negative;  // N m, motor side
};

inline constexpr double kPuma560HalfPi = 1.57079632679489661923;

inline constexpr Puma560Row kPuma560[6] = {
    {0.0, kPuma560HalfPi, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.35, 0.0, 200e-6, -62.6111, 1.48e-3, 0.395,
     -0.435},
    {0.4318, 0.0, 0.0, 17.4, -0.3638, 0.006, 0.2275, 0.13, 0.524, 0.539, 200e-6, 107.815, 0.817e-3,
     0.126, -0.071},
    {0.0203, -kPuma560HalfPi, 0.15005, 4.8, -0.0203, -0.0141, 0.070, 0.066, 0.086, 0.0125, 200e-6,
     -53.7063, 1.38e-3, 0.132, -0.105},
    {0.0, kPuma560HalfPi, 0.4318, 0.82, 0.0, 0.019, 0.0, 1.8e-3, 1.3e-3, 1.8e-3, 33e-6, 76.0364,
     71.2e-6, 11.2e-3, -16.9e-3},
    {0.0, -kPuma560HalfPi, 0.0, 0.34, 0.0, 0.0, 0.0, 0.3e-3, 0.4e-3, 0.3e-3, 33e-6, 71.923, 82.6e-6,
     9.26e-3, -14.5e-3},
    {0.0, 0.0, 0.0, 0.09, 0.0, 0.0, 0.032, 0.15e-3, 0.15e-3, 0.04e-3, 33e-6, 76.686, 36.7e-6,
     3.96e-3, -10.5e-3},
};

}  // namespace internal
}  // namespace sim
}  // namespace structgp

#endif  // STRUCTGP_SRC_SIM_PUMA560_DATA_H_
