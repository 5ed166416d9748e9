#include "kdl_solvers.h"

#include <stdexcept>
#include <string>

#include <kdl/frames.hpp>

namespace structgp {
namespace sim {
namespace internal {
namespace {

KDL::Vector ToKdl(const Eigen::Vector3d& v) { return KDL::Vector(v.x(), v.y(), v.z()); }

void CheckKdl(int code, const char* what) {
  if (code < 0) {
    throw std::logic_error(std::string("structgp::sim: KDL ") + what + " failed with code " +
                           std::to_string(code));
  }
}

}  // namespace

KdlSolvers::KdlSolvers(const KDL::Chain& chain, const Eigen::Vector3d& gravity)
    : num_joints_(static_cast<int>(chain.getNrOfJoints())),
      rne_(chain, ToKdl(gravity)),
      dyn_param_(chain, ToKdl(gravity)),
      q_(chain.getNrOfJoints()),
      qd_(chain.getNrOfJoints()),
      qdd_(chain.getNrOfJoints()),
      out_(chain.getNrOfJoints()),
      mass_(chain.getNrOfJoints()),
      no_external_wrenches_(chain.getNrOfSegments(), KDL::Wrench::Zero()) {}

void KdlSolvers::InverseDynamics(const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                                 const Eigen::VectorXd& qdd, Eigen::VectorXd* tau) {
  q_.data = q;
  qd_.data = qd;
  qdd_.data = qdd;
  CheckKdl(rne_.CartToJnt(q_, qd_, qdd_, no_external_wrenches_, out_),
           "ChainIdSolver_RNE::CartToJnt");
  *tau = out_.data;
}

void KdlSolvers::MassMatrix(const Eigen::VectorXd& q, Eigen::MatrixXd* mass) {
  q_.data = q;
  CheckKdl(dyn_param_.JntToMass(q_, mass_), "ChainDynParam::JntToMass");
  *mass = mass_.data;
}

void KdlSolvers::Coriolis(const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                          Eigen::VectorXd* coriolis) {
  q_.data = q;
  qd_.data = qd;
  CheckKdl(dyn_param_.JntToCoriolis(q_, qd_, out_), "ChainDynParam::JntToCoriolis");
  *coriolis = out_.data;
}

void KdlSolvers::Gravity(const Eigen::VectorXd& q, Eigen::VectorXd* gravity) {
  q_.data = q;
  CheckKdl(dyn_param_.JntToGravity(q_, out_), "ChainDynParam::JntToGravity");
  *gravity = out_.data;
}

}  // namespace internal
}  // namespace sim
}  // namespace structgp
