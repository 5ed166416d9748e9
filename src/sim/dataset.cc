#include "structgp/sim/dataset.h"

#include <cmath>
#include <optional>
#include <random>
#include <string>

#include "structgp/core/validate.h"
#include "kdl_solvers.h"
#include "random.h"

namespace structgp {
namespace sim {
namespace {

void Validate(const char* what, const Robot& robot, const Trajectory& trajectory,
              const SimulationOptions& options) {
  const std::string prefix = std::string(what) + ": ";
  const int n = robot.num_joints();
  const Eigen::Index m = trajectory.q.rows();
  RequireSize(prefix + "trajectory.q columns", trajectory.q.cols(), n, "joints");
  RequireSize(prefix + "trajectory.qd columns", trajectory.qd.cols(), n, "joints");
  RequireSize(prefix + "trajectory.qdd columns", trajectory.qdd.cols(), n, "joints");
  RequireSize(prefix + "trajectory.qd rows", trajectory.qd.rows(), m, "samples");
  RequireSize(prefix + "trajectory.qdd rows", trajectory.qdd.rows(), m, "samples");
  RequireSize(prefix + "trajectory.t", trajectory.t.size(), m, "samples");
  RequireFinite(prefix + "trajectory.q", trajectory.q);
  RequireFinite(prefix + "trajectory.qd", trajectory.qd);
  RequireFinite(prefix + "trajectory.qdd", trajectory.qdd);
  if (options.friction) {
    RequireSize(prefix + "options.friction", options.friction->num_joints(), n, "joints");
  }
  RequireInRange(prefix + "options.noise_std", options.noise_std, 0.0, HUGE_VAL, true);
}

// Friction torques, m x N (zero without a model).
Eigen::MatrixXd FrictionTorques(const Trajectory& trajectory,
                                const std::optional<FrictionModel>& friction) {
  Eigen::MatrixXd tau = Eigen::MatrixXd::Zero(trajectory.qd.rows(), trajectory.qd.cols());
  if (!friction) return tau;
  for (Eigen::Index i = 0; i < tau.rows(); ++i) {
    for (int j = 0; j < friction->num_joints(); ++j) {
      tau(i, j) = friction->JointTorque(j, trajectory.qd(i, j));
    }
  }
  return tau;
}

// Noise-free torques, m x N, N m: KDL recursive Newton-Euler plus friction.
Eigen::MatrixXd NoiseFreeTorques(const Robot& robot, const Trajectory& trajectory,
                                 const std::optional<FrictionModel>& friction) {
  internal::KdlSolvers solvers(robot.chain(), robot.gravity_in_base());
  Eigen::MatrixXd tau = FrictionTorques(trajectory, friction);
  Eigen::VectorXd q, qd, qdd, tau_i;
  for (Eigen::Index i = 0; i < tau.rows(); ++i) {
    q = trajectory.q.row(i).transpose();
    qd = trajectory.qd.row(i).transpose();
    qdd = trajectory.qdd.row(i).transpose();
    solvers.InverseDynamics(q, qd, qdd, &tau_i);
    tau.row(i) += tau_i.transpose();
  }
  return tau;
}

Eigen::VectorXd TorqueScale(const Eigen::MatrixXd& tau, TorqueNormalization normalization) {
  Eigen::VectorXd scale = Eigen::VectorXd::Ones(tau.cols());
  if (tau.rows() == 0) return scale;
  switch (normalization) {
    case TorqueNormalization::kNone:
      break;
    case TorqueNormalization::kPerJoint:
      for (Eigen::Index j = 0; j < tau.cols(); ++j) {
        const double max_abs = tau.col(j).cwiseAbs().maxCoeff();
        if (max_abs > 0.0) scale(j) = max_abs;
      }
      break;
    case TorqueNormalization::kGlobal: {
      const double max_abs = tau.cwiseAbs().maxCoeff();
      if (max_abs > 0.0) scale.setConstant(max_abs);
      break;
    }
  }
  return scale;
}

}  // namespace

Dataset Simulate(const Robot& robot, const Trajectory& trajectory,
                 const SimulationOptions& options) {
  Validate("Simulate", robot, trajectory, options);
  const int n = robot.num_joints();
  const Eigen::Index m = trajectory.num_samples();

  Dataset data;
  data.t = trajectory.t;
  data.X.resize(m, 3 * n);
  data.X << trajectory.q, trajectory.qd, trajectory.qdd;
  const Eigen::MatrixXd tau = NoiseFreeTorques(robot, trajectory, options.friction);
  data.torque_scale = TorqueScale(tau, options.normalization);
  data.Y = tau * data.torque_scale.cwiseInverse().asDiagonal();
  if (options.noise_std > 0.0) {
    std::mt19937_64 rng(options.seed);
    for (Eigen::Index i = 0; i < m; ++i) {
      for (int j = 0; j < n; ++j) data.Y(i, j) += options.noise_std * internal::StandardNormal(rng);
    }
  }
  return data;
}

TorqueComponents SimulateComponents(const Robot& robot, const Trajectory& trajectory,
                                    const SimulationOptions& options) {
  Validate("SimulateComponents", robot, trajectory, options);
  const int n = robot.num_joints();
  const Eigen::Index m = trajectory.num_samples();

  TorqueComponents components;
  // The scale comes from the same recursive Newton-Euler torques as in Simulate, so that the
  // two functions divide by bit-identical scales.
  components.torque_scale =
      TorqueScale(NoiseFreeTorques(robot, trajectory, options.friction), options.normalization);
  components.inertial.resize(m, n);
  components.coriolis.resize(m, n);
  components.gravity.resize(m, n);
  components.friction = FrictionTorques(trajectory, options.friction);

  internal::KdlSolvers solvers(robot.chain(), robot.gravity_in_base());
  Eigen::VectorXd q, qd, qdd, term;
  Eigen::MatrixXd mass;
  for (Eigen::Index i = 0; i < m; ++i) {
    q = trajectory.q.row(i).transpose();
    qd = trajectory.qd.row(i).transpose();
    qdd = trajectory.qdd.row(i).transpose();
    solvers.MassMatrix(q, &mass);
    components.inertial.row(i) = (mass * qdd).transpose();
    solvers.Coriolis(q, qd, &term);
    components.coriolis.row(i) = term.transpose();
    solvers.Gravity(q, &term);
    components.gravity.row(i) = term.transpose();
  }
  const Eigen::VectorXd inverse_scale = components.torque_scale.cwiseInverse();
  components.inertial = components.inertial * inverse_scale.asDiagonal();
  components.coriolis = components.coriolis * inverse_scale.asDiagonal();
  components.gravity = components.gravity * inverse_scale.asDiagonal();
  components.friction = components.friction * inverse_scale.asDiagonal();
  return components;
}

RobotData ToRobotData(const Dataset& dataset, const std::string& source) {
  RobotData out;
  out.num_joints = dataset.num_joints();
  out.X = dataset.X;
  out.Y = dataset.Y * dataset.torque_scale.asDiagonal();
  out.t = dataset.t;
  out.source = source;
  return out;
}

}  // namespace sim
}  // namespace structgp
