#include "structgp/feature/friction_feature_map.h"

#include <cmath>
#include <string>

#include "structgp/core/validate.h"

namespace structgp {

FrictionFeatureMap::FrictionFeatureMap(int num_joints, const FrictionOptions& options)
    : num_joints_(num_joints), options_(options) {
  RequireInRange("FrictionFeatureMap num_joints", num_joints, 1, 1e9, true);
  RequireInRange("FrictionFeatureMap sigma_f (rad/s)", options.sigma_f, 0.0, HUGE_VAL);
  dim_ = options.shared_offset ? 2 * num_joints + 1 : 3 * num_joints;
}

FrictionFeatureMap::FrictionFeatureMap(int num_joints, double sigma_f)
    : FrictionFeatureMap(num_joints, FrictionOptions{sigma_f, true}) {}

std::vector<FeatureBlock> FrictionFeatureMap::blocks() const {
  return {FeatureBlock{kBlockName, 0, dim_}};
}

void FrictionFeatureMap::Evaluate(const ConstVectorRef& x, VectorRef phi) const {
  if (x.size() != input_dim()) {
    RequireSize("FrictionFeatureMap::Evaluate x", x.size(), input_dim());
  }
  if (phi.size() != dim_) RequireSize("FrictionFeatureMap::Evaluate phi", phi.size(), dim_);
  const double inv_sigma_f = 1.0 / options_.sigma_f;
  const int stride = options_.shared_offset ? 2 : 3;
  for (int j = 0; j < num_joints_; ++j) {
    const double qd = x[num_joints_ + j];
    phi[stride * j] = qd;
    phi[stride * j + 1] = std::tanh(qd * inv_sigma_f);
    if (!options_.shared_offset) phi[stride * j + 2] = 1.0;
  }
  if (options_.shared_offset) phi[dim_ - 1] = 1.0;
}

FrictionIndices FrictionFeatureMap::indices(int joint) const {
  RequireInRange("FrictionFeatureMap::indices joint (0-based)", joint, 0, num_joints_, true);
  FrictionIndices ix;
  const int stride = options_.shared_offset ? 2 : 3;
  ix.viscous = stride * joint;
  ix.coulomb = stride * joint + 1;
  ix.offset = options_.shared_offset ? dim_ - 1 : stride * joint + 2;
  return ix;
}

std::vector<std::string> FrictionFeatureMap::feature_names() const {
  std::vector<std::string> names(static_cast<size_t>(dim_));
  for (int j = 0; j < num_joints_; ++j) {
    const FrictionIndices ix = indices(j);
    const std::string suffix = "@" + std::to_string(j + 1);
    names[static_cast<size_t>(ix.viscous)] = "viscous" + suffix;
    names[static_cast<size_t>(ix.coulomb)] = "coulomb" + suffix;
    names[static_cast<size_t>(ix.offset)] = options_.shared_offset ? "offset" : "offset" + suffix;
  }
  return names;
}

}  // namespace structgp
