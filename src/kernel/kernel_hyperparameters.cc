#include "structgp/kernel/kernel_hyperparameters.h"

#include <stdexcept>
#include <string>

namespace structgp {

Hyperparameters DefaultHyperparameters(const Kernel& kernel, int num_outputs) {
  if (num_outputs < 1) {
    throw std::invalid_argument("DefaultHyperparameters(kernel): expected num_outputs >= 1, got " +
                                std::to_string(num_outputs));
  }
  Hyperparameters h;
  h.shape = kernel.parameters();
  h.log_block_scale.resize(0);
  h.log_output_scale = Vector::Zero(num_outputs);
  return h;
}

void ValidateHyperparameters(const Hyperparameters& hyper, const Kernel& kernel,
                             int num_outputs) {
  hyper.Validate(kernel.num_parameters(), 0, num_outputs, "Hyperparameters (kernel)");
}

}  // namespace structgp
