#include "structgp/hyper/hyperparameters.h"

#include <cmath>

#include "structgp/core/validate.h"

namespace structgp {

Hyperparameters Hyperparameters::Defaults(const FeatureMap& map, int num_outputs) {
  Hyperparameters h;
  h.shape = map.default_shape_parameters();
  h.log_block_scale = Vector::Zero(static_cast<Eigen::Index>(map.blocks().size()));
  h.log_output_scale = Vector::Zero(num_outputs);
  return h;
}

double Hyperparameters::noise_variance() const { return std::exp(2.0 * log_noise_std); }

Vector Hyperparameters::output_scales() const { return log_output_scale.array().exp(); }

void Hyperparameters::Validate(const FeatureMap& map, int num_outputs) const {
  RequireSize("Hyperparameters.shape", shape.size(), map.num_shape_parameters());
  RequireSize("Hyperparameters.log_block_scale", log_block_scale.size(),
              static_cast<Eigen::Index>(map.blocks().size()));
  RequireSize("Hyperparameters.log_output_scale", log_output_scale.size(), num_outputs);
  RequireFinite("Hyperparameters.shape", shape);
  RequireFinite("Hyperparameters.log_block_scale", log_block_scale);
  RequireFinite("Hyperparameters.log_output_scale", log_output_scale);
  RequireInRange("Hyperparameters.log_noise_std", log_noise_std, -50.0, 50.0);
}

Vector PriorVariance(const FeatureMap& map, const Hyperparameters& hyper,
                     Matrix* d_lambda_d_shape) {
  hyper.Validate(map, static_cast<int>(hyper.log_output_scale.size()));
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
