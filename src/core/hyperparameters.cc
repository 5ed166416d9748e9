#include "structgp/core/hyperparameters.h"

#include <cmath>
#include <stdexcept>
#include <string>

#include "structgp/core/validate.h"

namespace structgp {

double Hyperparameters::noise_variance() const { return std::exp(2.0 * log_noise_std); }

Vector Hyperparameters::output_scales() const { return log_output_scale.array().exp(); }

Vector Hyperparameters::noise_stds() const {
  if (per_output.empty()) return (log_output_scale.array() + log_noise_std).exp().matrix();
  Vector stds(static_cast<Eigen::Index>(per_output.size()));
  for (size_t j = 0; j < per_output.size(); ++j) {
    const Hyperparameters& h = per_output[j];
    stds[static_cast<Eigen::Index>(j)] =
        h.log_output_scale.size() == 1 ? std::exp(h.log_output_scale[0] + h.log_noise_std)
                                       : std::exp(h.log_noise_std);
  }
  return stds;
}

Hyperparameters Hyperparameters::Output(Eigen::Index j) const {
  const Eigen::Index outputs =
      per_output.empty() ? log_output_scale.size() : static_cast<Eigen::Index>(per_output.size());
  if (j < 0 || j >= outputs) {
    throw std::out_of_range("Hyperparameters::Output: " + std::to_string(j) + " not in 0.." +
                            std::to_string(outputs - 1));
  }
  if (!per_output.empty()) return per_output[static_cast<size_t>(j)];
  Hyperparameters own;
  own.shape = shape;
  own.log_block_scale = log_block_scale;
  own.log_noise_std = log_noise_std;
  own.log_output_scale = log_output_scale.segment(j, 1);
  return own;
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
  if (per_output.empty()) return;
  RequireSize(what + ".per_output", static_cast<Eigen::Index>(per_output.size()), num_outputs,
              "entries (one per output, or none)");
  for (size_t j = 0; j < per_output.size(); ++j) {
    const std::string name = what + ".per_output[" + std::to_string(j) + "]";
    if (!per_output[j].per_output.empty()) {
      throw std::invalid_argument(name + ".per_output: expected none, got " +
                                  std::to_string(per_output[j].per_output.size()));
    }
    per_output[j].Validate(num_shape, num_blocks, 1, name);
  }
}

}  // namespace structgp
