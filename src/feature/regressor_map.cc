#include "structgp/feature/regressor_map.h"

#include <cmath>
#include <stdexcept>
#include <string>

#include "structgp/core/validate.h"

namespace structgp {

Vector RegressorMap::prior_mean() const { return Vector::Zero(dim()); }

Vector RegressorMap::prior_std() const { return Vector::Ones(dim()); }

std::vector<std::string> RegressorMap::component_names() const {
  std::vector<std::string> names;
  for (const FeatureBlock& block : blocks()) names.push_back(block.name);
  return names;
}

void RegressorMap::Evaluate(const ConstVectorRef& x, MatrixRef psi) const {
  const std::unique_ptr<Scratch> scratch = MakeScratch();
  Evaluate(x, psi, scratch.get());
}

void RegressorMap::EvaluateComponent(int component, const ConstVectorRef& x, MatrixRef psi,
                                     Scratch* scratch) const {
  const std::vector<FeatureBlock> all = blocks();
  if (component < 0 || component >= static_cast<int>(all.size())) {
    throw std::invalid_argument("RegressorMap::EvaluateComponent: component " +
                                std::to_string(component) + " out of range [0, " +
                                std::to_string(all.size()) + ")");
  }
  Evaluate(x, psi, scratch);
  const FeatureBlock& block = all[static_cast<size_t>(component)];
  psi.leftCols(block.begin).setZero();
  psi.rightCols(dim() - block.begin - block.size).setZero();
}

Vector RegressorPriorVariance(const RegressorMap& map, const ConstVectorRef& log_block_scale) {
  const std::vector<FeatureBlock> blocks = map.blocks();
  RequireSize("RegressorPriorVariance log_block_scale", log_block_scale.size(),
              static_cast<Eigen::Index>(blocks.size()), "entries (one per block)");
  Vector lambda = map.prior_std().array().square().matrix();
  for (size_t b = 0; b < blocks.size(); ++b) {
    lambda.segment(blocks[b].begin, blocks[b].size) *=
        std::exp(2.0 * log_block_scale[static_cast<Eigen::Index>(b)]);
  }
  return lambda;
}

}  // namespace structgp
