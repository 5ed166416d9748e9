#ifndef STRUCTGP_SRC_RIGID_BODY_KDL_INERTIA_H_
#define STRUCTGP_SRC_RIGID_BODY_KDL_INERTIA_H_

// The 10 inertial parameters of a link as a KDL::RigidBodyInertia and back. Not part of the
// API: it exposes KDL types.

#include <array>

#include <Eigen/Core>
#include <kdl/rigidbodyinertia.hpp>

namespace structgp {
namespace internal {

inline constexpr int kLinkParameters = 10;

// The basis inertias E_j, j = 0..9: the inertia whose parameter vector [m, m cx, m cy, m cz,
// Ixx, Ixy, Ixz, Iyy, Iyz, Izz] is the j-th unit vector. Built with KDL's own arithmetic (its
// constructor takes the mass, the centre of mass and the inertia about it, so a pure first
// moment is a difference of such inertias); every entry is 0 or +-1, exactly.
const std::array<KDL::RigidBodyInertia, kLinkParameters>& BasisInertias();

// sum_j p_j E_j (p: 10 entries, any values: the inertia need not be physical).
KDL::RigidBodyInertia InertiaFromParameters(const double* p);

// The parameters of an inertia, written to p (10 entries). Exact for inertias made by
// InertiaFromParameters up to rounding; the first moments are m * COG, so an inertia of zero
// mass gives zero first moments (the case of every lumped URDF inertia).
void ParametersFromInertia(const KDL::RigidBodyInertia& inertia, double* p);

}  // namespace internal
}  // namespace structgp

#endif  // STRUCTGP_SRC_RIGID_BODY_KDL_INERTIA_H_
