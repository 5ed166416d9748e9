#include "structgp/sim/friction.h"

#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

#include "structgp/core/validate.h"
#include "puma560_data.h"

namespace structgp {
namespace sim {
namespace {

double Sign(double x) { return static_cast<double>((x > 0.0) - (x < 0.0)); }

}  // namespace

FrictionModel::FrictionModel(std::vector<JointFriction> joints) : joints_(std::move(joints)) {
  if (joints_.empty()) {
    throw std::invalid_argument("FrictionModel: expected at least 1 joint, got 0");
  }
  for (std::size_t i = 0; i < joints_.size(); ++i) {
    const JointFriction& f = joints_[i];
    const std::string joint = "FrictionModel joint " + std::to_string(i + 1);
    RequireInRange(joint + " coulomb (N m)", f.coulomb, 0.0, HUGE_VAL, true);
    RequireInRange(joint + " viscous (N m s/rad)", f.viscous, 0.0, HUGE_VAL, true);
    RequireInRange(joint + " stribeck (N m)", f.stribeck, 0.0, HUGE_VAL, true);
    RequireInRange(joint + " stribeck_velocity (rad/s)", f.stribeck_velocity, 0.0, HUGE_VAL);
    RequireInRange(joint + " smoothing_velocity (rad/s)", f.smoothing_velocity, 0.0, HUGE_VAL,
                   true);
  }
}

FrictionModel FrictionModel::Uniform(int num_joints, const JointFriction& joint) {
  if (num_joints < 1) {
    throw std::invalid_argument("FrictionModel::Uniform: expected at least 1 joint, got " +
                                std::to_string(num_joints));
  }
  return FrictionModel(std::vector<JointFriction>(num_joints, joint));
}

double FrictionModel::JointTorque(int joint, double qd) const {
  const JointFriction& f = joints_.at(joint);
  const double s = f.smoothing_velocity > 0.0 ? std::tanh(qd / f.smoothing_velocity) : Sign(qd);
  double tau = f.coulomb * s + f.viscous * qd;
  if (f.stribeck > 0.0) {
    const double r = qd / f.stribeck_velocity;
    tau += f.stribeck * std::exp(-r * r) * s;
  }
  return tau;
}

Eigen::VectorXd FrictionModel::Torque(const Eigen::VectorXd& qd) const {
  RequireSize("FrictionModel::Torque: qd", qd.size(), num_joints());
  Eigen::VectorXd tau(qd.size());
  for (int j = 0; j < num_joints(); ++j) tau(j) = JointTorque(j, qd(j));
  return tau;
}

FrictionModel Puma560Friction(double smoothing_velocity) {
  std::vector<JointFriction> joints(6);
  for (int i = 0; i < 6; ++i) {
    const internal::Puma560Row& row = internal::kPuma560[i];
    const double g = std::abs(row.gear_ratio);
    joints[i].viscous = row.viscous * g * g;
    joints[i].coulomb = 0.5 * g * (std::abs(row.coulomb_positive) + std::abs(row.coulomb_negative));
    joints[i].smoothing_velocity = smoothing_velocity;
  }
  return FrictionModel(std::move(joints));
}

}  // namespace sim
}  // namespace structgp
