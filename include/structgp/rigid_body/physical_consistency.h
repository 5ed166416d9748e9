#ifndef STRUCTGP_RIGID_BODY_PHYSICAL_CONSISTENCY_H_
#define STRUCTGP_RIGID_BODY_PHYSICAL_CONSISTENCY_H_

/// @file
/// Whether inertial parameters (identified ones, typically) describe physical rigid bodies.

#include <cstdint>
#include <string>
#include <vector>

#include "structgp/core/types.h"
#include "structgp/rigid_body/rigid_body_chain.h"

namespace structgp {

/// Physical consistency of one link's parameters.
struct LinkConsistency {
  std::string link;                        ///< URDF name of the moving link
  bool mass_positive = false;              ///< m > 0
  bool inertia_positive_definite = false;  ///< inertia about the centre of mass is PD
  bool triangle_inequalities = false;      ///< its principal moments satisfy them
  bool armature_nonnegative = false;       ///< armature >= 0
  /// Empty when consistent, else what fails with the values ("mass -0.2 kg is not positive").
  std::string message;
  bool ok() const {
    return mass_positive && inertia_positive_definite && triangle_inequalities &&
           armature_nonnegative;
  }
};

/// Physical consistency of a parameter vector for a chain.
struct PhysicalConsistency {
  std::vector<LinkConsistency> links;  ///< one per moving link, root to tip
  int configurations = 0;              ///< random configurations tried
  /// Fraction of them at which M(q) is positive definite (Cholesky succeeds).
  double mass_matrix_pd_fraction = 0.0;
  /// Every link consistent and M(q) positive definite at every configuration tried.
  bool ok = false;
  /// One line per inconsistent link and the M(q) fraction.
  std::string Summary() const;
};

/// Checks pi (chain.num_parameters() entries) link by link: positive mass; the inertia about
/// the centre of mass (I - m (|c|^2 1 - c c^T), c = first moments / m) positive definite with
/// principal moments satisfying the triangle inequalities (relative tolerance
/// kTriangleTolerance: a thin rod is on the boundary); armature >= 0. Then M(q) at
/// `configurations` joint vectors drawn uniformly from [-pi, pi]^N (std::mt19937_64 seeded
/// with `seed`). Throws std::invalid_argument on a wrong size, a non-finite entry or
/// configurations < 1.
PhysicalConsistency CheckPhysicalConsistency(const RigidBodyChain& chain, const Vector& pi,
                                             int configurations = 1000,
                                             std::uint64_t seed = 1);

/// Relative tolerance of the triangle inequalities (of the sum of the principal moments).
inline constexpr double kTriangleTolerance = 1e-9;

}  // namespace structgp

#endif  // STRUCTGP_RIGID_BODY_PHYSICAL_CONSISTENCY_H_
