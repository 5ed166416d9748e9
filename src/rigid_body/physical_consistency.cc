#include "structgp/rigid_body/physical_consistency.h"

#include <random>
#include <sstream>
#include <stdexcept>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include "structgp/core/validate.h"

namespace structgp {
namespace {

constexpr double kPi = 3.14159265358979323846;

LinkConsistency CheckLink(const std::string& name, const double* p, double armature) {
  LinkConsistency out;
  out.link = name;
  std::ostringstream problems;
  auto problem = [&problems](const std::string& text) {
    if (problems.tellp() > 0) problems << "; ";
    problems << text;
  };
  const double m = p[0];
  out.mass_positive = m > 0.0;
  if (!out.mass_positive) {
    std::ostringstream os;
    os << "mass " << m << " kg is not positive";
    problem(os.str());
  }
  out.armature_nonnegative = armature >= 0.0;
  if (!out.armature_nonnegative) {
    std::ostringstream os;
    os << "armature " << armature << " kg m^2 is negative";
    problem(os.str());
  }
  if (out.mass_positive) {
    const Eigen::Vector3d c = Eigen::Vector3d(p[1], p[2], p[3]) / m;
    Eigen::Matrix3d inertia;
    inertia << p[4], p[5], p[6],  //
        p[5], p[7], p[8],         //
        p[6], p[8], p[9];
    // About the centre of mass (the parallel-axis theorem backwards).
    const Eigen::Matrix3d about_com =
        inertia - m * (c.squaredNorm() * Eigen::Matrix3d::Identity() - c * c.transpose());
    const Eigen::Vector3d moments =
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(about_com, Eigen::EigenvaluesOnly)
            .eigenvalues();  // ascending
    out.inertia_positive_definite = moments(0) > 0.0;
    // With ascending moments the binding inequality is l0 + l1 >= l2.
    out.triangle_inequalities =
        moments(0) + moments(1) >= moments(2) - kTriangleTolerance * moments.cwiseAbs().sum();
    if (!out.inertia_positive_definite || !out.triangle_inequalities) {
      std::ostringstream os;
      os << "principal moments about the centre of mass " << moments.transpose() << " kg m^2"
         << (out.inertia_positive_definite ? "" : " are not all positive")
         << (!out.inertia_positive_definite && !out.triangle_inequalities ? " and" : "")
         << (out.triangle_inequalities ? "" : " violate the triangle inequality");
      problem(os.str());
    }
  } else {
    problem("no centre of mass (the inertia about it is undefined)");
  }
  out.message = problems.str();
  return out;
}

}  // namespace

std::string PhysicalConsistency::Summary() const {
  std::ostringstream os;
  for (const LinkConsistency& link : links) {
    if (!link.ok()) os << "link '" << link.link << "': " << link.message << "\n";
  }
  os << "M(q) positive definite at " << 100.0 * mass_matrix_pd_fraction << "% of "
     << configurations << " random configurations\n";
  return os.str();
}

PhysicalConsistency CheckPhysicalConsistency(const RigidBodyChain& chain, const Vector& pi,
                                             int configurations, std::uint64_t seed) {
  RequireSize("CheckPhysicalConsistency: parameters", pi.size(), chain.num_parameters());
  RequireFinite("CheckPhysicalConsistency: parameters", pi);
  if (configurations < 1) {
    throw std::invalid_argument("CheckPhysicalConsistency: expected at least 1 configuration, got " +
                                std::to_string(configurations));
  }
  const int n = chain.num_joints();
  PhysicalConsistency out;
  bool links_ok = true;
  for (int k = 0; k < n; ++k) {
    out.links.push_back(CheckLink(chain.link_names()[k], pi.data() + 10 * k, pi(10 * n + k)));
    links_ok = links_ok && out.links.back().ok();
  }
  const RigidBodyChain with = chain.WithParameters(pi);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> angle(-kPi, kPi);
  int positive_definite = 0;
  Vector q(n);
  for (int c = 0; c < configurations; ++c) {
    for (int j = 0; j < n; ++j) q(j) = angle(rng);
    const Eigen::LLT<Matrix> llt(with.MassMatrix(q));
    if (llt.info() == Eigen::Success) ++positive_definite;
  }
  out.configurations = configurations;
  out.mass_matrix_pd_fraction = static_cast<double>(positive_definite) / configurations;
  out.ok = links_ok && positive_definite == configurations;
  return out;
}

}  // namespace structgp
