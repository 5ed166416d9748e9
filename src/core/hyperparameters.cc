#include "structgp/core/hyperparameters.h"

#include <cmath>

#include "structgp/core/validate.h"

namespace structgp {

double Hyperparameters::noise_variance() const { return std::exp(2.0 * log_noise_std); }

Vector Hyperparameters::output_scales() const { return log_output_scale.array().exp(); }

Vector Hyperparameters::noise_stds() const {
  return (log_output_scale.array() + log_noise_std).exp().matrix();
}

void Hyperparameters::Validate(Eigen::Index num_shape, Eigen::Index num_blocks,
                               Eigen::Index num_outputs, const std::string& what) const {
  RequireSize(what + ".shape", shape.size(), num_shape);
  RequireSize(what + ".log_block_scale", log_block_scale.size(), num_blocks);
  RequireSize(what + ".log_output_scale", log_output_scale.size(), num_outputs);
  RequireFinite(what + ".shape", shape);
  RequireFinite(what + ".log_block_scale", log_block_scale);
  RequireFinite(what + ".log_output_scale", log_output_scale);
  RequireInRange(what + ".log_noise_std", log_noise_std, -50.0, 50.0);
}

}  // namespace structgp
