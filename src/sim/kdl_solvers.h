#ifndef STRUCTGP_SRC_SIM_KDL_SOLVERS_H_
#define STRUCTGP_SRC_SIM_KDL_SOLVERS_H_

// The KDL solvers and joint arrays needed to evaluate a robot's dynamics, built once for a
// chain and reused for many states. Not part of the public API: it exposes KDL types.

#include <Eigen/Core>
#include <kdl/chain.hpp>
#include <kdl/chaindynparam.hpp>
#include <kdl/chainidsolver_recursive_newton_euler.hpp>
#include <kdl/jntarray.hpp>
#include <kdl/jntspaceinertiamatrix.hpp>

namespace structgp {
namespace sim {
namespace internal {

// Workspace for one chain. The chain must outlive the workspace (KDL solvers keep a
// reference to it). Not safe for concurrent use; each thread needs its own.
class KdlSolvers {
 public:
  // gravity: gravitational acceleration in the chain's base frame, m/s^2.
  KdlSolvers(const KDL::Chain& chain, const Eigen::Vector3d& gravity);

  KdlSolvers(const KdlSolvers&) = delete;
  KdlSolvers& operator=(const KdlSolvers&) = delete;

  int num_joints() const { return num_joints_; }

  // Each call checks nothing about sizes: the caller passes vectors of num_joints() entries.
  // A negative KDL error code is turned into std::logic_error (it would mean an internal
  // inconsistency between chain and workspace).
  void InverseDynamics(const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                       const Eigen::VectorXd& qdd, Eigen::VectorXd* tau);
  void MassMatrix(const Eigen::VectorXd& q, Eigen::MatrixXd* mass);
  void Coriolis(const Eigen::VectorXd& q, const Eigen::VectorXd& qd, Eigen::VectorXd* coriolis);
  void Gravity(const Eigen::VectorXd& q, Eigen::VectorXd* gravity);

 private:
  int num_joints_;
  KDL::ChainIdSolver_RNE rne_;
  KDL::ChainDynParam dyn_param_;
  KDL::JntArray q_, qd_, qdd_, out_;
  KDL::JntSpaceInertiaMatrix mass_;
  KDL::Wrenches no_external_wrenches_;
};

}  // namespace internal
}  // namespace sim
}  // namespace structgp

#endif  // STRUCTGP_SRC_SIM_KDL_SOLVERS_H_
