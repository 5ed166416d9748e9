#include "kdl_inertia.h"

#include <kdl/frames.hpp>
#include <kdl/rotationalinertia.hpp>

namespace structgp {
namespace internal {
namespace {

std::array<KDL::RigidBodyInertia, kLinkParameters> MakeBasis() {
  using KDL::RigidBodyInertia;
  using KDL::RotationalInertia;
  using KDL::Vector;
  const RigidBodyInertia unit_mass(1.0, Vector::Zero(), RotationalInertia::Zero());
  // A unit mass at the unit vector e has first moment e and inertia |e|^2 1 - e e^T about the
  // origin; taking away the unit mass at the origin and that rotational inertia leaves e alone.
  auto first_moment = [&](const Vector& e, const RotationalInertia& parallel_axis) {
    return RigidBodyInertia(1.0, e, RotationalInertia::Zero()) + (-1.0) * unit_mass +
           (-1.0) * RigidBodyInertia(0.0, Vector::Zero(), parallel_axis);
  };
  auto rotational = [](double ixx, double iyy, double izz, double ixy, double ixz, double iyz) {
    return RigidBodyInertia(0.0, Vector::Zero(), RotationalInertia(ixx, iyy, izz, ixy, ixz, iyz));
  };
  return {
      unit_mass,
      first_moment(Vector(1, 0, 0), RotationalInertia(0, 1, 1, 0, 0, 0)),
      first_moment(Vector(0, 1, 0), RotationalInertia(1, 0, 1, 0, 0, 0)),
      first_moment(Vector(0, 0, 1), RotationalInertia(1, 1, 0, 0, 0, 0)),
      rotational(1, 0, 0, 0, 0, 0),  // Ixx
      rotational(0, 0, 0, 1, 0, 0),  // Ixy
      rotational(0, 0, 0, 0, 1, 0),  // Ixz
      rotational(0, 1, 0, 0, 0, 0),  // Iyy
      rotational(0, 0, 0, 0, 0, 1),  // Iyz
      rotational(0, 0, 1, 0, 0, 0),  // Izz
  };
}

}  // namespace

const std::array<KDL::RigidBodyInertia, kLinkParameters>& BasisInertias() {
  static const std::array<KDL::RigidBodyInertia, kLinkParameters> basis = MakeBasis();
  return basis;
}

KDL::RigidBodyInertia InertiaFromParameters(const double* p) {
  const auto& basis = BasisInertias();
  KDL::RigidBodyInertia inertia = KDL::RigidBodyInertia::Zero();
  for (int j = 0; j < kLinkParameters; ++j) inertia = inertia + p[j] * basis[j];
  return inertia;
}

void ParametersFromInertia(const KDL::RigidBodyInertia& inertia, double* p) {
  const double m = inertia.getMass();
  const KDL::Vector h = m * inertia.getCOG();
  const KDL::RotationalInertia rot = inertia.getRotationalInertia();
  // RotationalInertia::data is the 3x3 matrix, row-major (symmetric).
  const double* i = rot.data;
  const double values[kLinkParameters] = {m, h.x(), h.y(), h.z(), i[0], i[1], i[2], i[4], i[5], i[8]};
  for (int j = 0; j < kLinkParameters; ++j) p[j] = values[j];
}

}  // namespace internal
}  // namespace structgp
