#include "structgp/feature/motor_feature_map.h"

#include <string>

#include "structgp/core/validate.h"

namespace structgp {

MotorFeatureMap::MotorFeatureMap(int num_joints) : num_joints_(num_joints) {
  RequireInRange("MotorFeatureMap num_joints", num_joints, 1, 1e9, true);
}

std::vector<FeatureBlock> MotorFeatureMap::blocks() const {
  return {FeatureBlock{"motor", 0, dim()}};
}

void MotorFeatureMap::Evaluate(const ConstVectorRef& x, VectorRef phi) const {
  if (x.size() != input_dim()) RequireSize("MotorFeatureMap::Evaluate x", x.size(), input_dim());
  if (phi.size() != dim()) RequireSize("MotorFeatureMap::Evaluate phi", phi.size(), dim());
  const int n = num_joints_;
  for (int j = 0; j < n; ++j) {
    phi[2 * j] = x[2 * n + j];
    phi[2 * j + 1] = x[n + j];
  }
}

int MotorFeatureMap::acceleration_index(int joint) const {
  RequireInRange("MotorFeatureMap joint (0-based)", joint, 0, num_joints_, true);
  return 2 * joint;
}

int MotorFeatureMap::velocity_index(int joint) const {
  RequireInRange("MotorFeatureMap joint (0-based)", joint, 0, num_joints_, true);
  return 2 * joint + 1;
}

std::vector<std::string> MotorFeatureMap::feature_names() const {
  std::vector<std::string> names;
  names.reserve(static_cast<size_t>(dim()));
  for (int j = 0; j < num_joints_; ++j) {
    names.push_back("acceleration@" + std::to_string(j + 1));
    names.push_back("velocity@" + std::to_string(j + 1));
  }
  return names;
}

}  // namespace structgp
