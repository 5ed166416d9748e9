#include "structgp/feature/feature_hyperparameters.h"

#include <cmath>

namespace structgp {

Hyperparameters DefaultHyperparameters(const FeatureMap& map, int num_outputs) {
  Hyperparameters h;
  h.shape = map.default_shape_parameters();
  h.log_block_scale = Vector::Zero(static_cast<Eigen::Index>(map.blocks().size()));
  h.log_output_scale = Vector::Zero(num_outputs);
  return h;
}

void ValidateHyperparameters(const Hyperparameters& hyper, const FeatureMap& map,
                             int num_outputs) {
  hyper.Validate(map.num_shape_parameters(), static_cast<Eigen::Index>(map.blocks().size()),
                 num_outputs);
}

Vector PriorVariance(const FeatureMap& map, const Hyperparameters& hyper,
                     Matrix* d_lambda_d_shape) {
  ValidateHyperparameters(hyper, map, static_cast<int>(hyper.log_output_scale.size()));
  Vector lambda(map.dim());
  map.PriorVariance(hyper.shape, lambda, d_lambda_d_shape);
  const auto blocks = map.blocks();
  for (size_t b = 0; b < blocks.size(); ++b) {
    const double scale = std::exp(2.0 * hyper.log_block_scale[static_cast<Eigen::Index>(b)]);
    lambda.segment(blocks[b].begin, blocks[b].size) *= scale;
    // No shape parameters: the Jacobian has no columns (and may have no storage, where even a
    // block of it would offset a null pointer).
    if (d_lambda_d_shape != nullptr && d_lambda_d_shape->cols() > 0) {
      d_lambda_d_shape->middleRows(blocks[b].begin, blocks[b].size) *= scale;
    }
  }
  return lambda;
}

}  // namespace structgp
