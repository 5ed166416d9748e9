#ifndef STRUCTGP_KERNEL_KERNEL_HYPERPARAMETERS_H_
#define STRUCTGP_KERNEL_KERNEL_HYPERPARAMETERS_H_

/// @file
/// Hyperparameters (core/hyperparameters.h) of a kernel model: `shape` holds the kernel's
/// parameters (Kernel::parameters() layout), log_block_scale is empty.

#include "structgp/core/hyperparameters.h"
#include "structgp/kernel/kernel.h"

namespace structgp {

/// The kernel's parameters as shape, no block scales, sigma_n = 0.1, unit output scales.
/// Throws std::invalid_argument when num_outputs < 1.
Hyperparameters DefaultHyperparameters(const Kernel& kernel, int num_outputs);

/// Throws std::invalid_argument when shape does not have kernel.num_parameters() entries,
/// log_block_scale is not empty, log_output_scale does not have num_outputs entries, or a
/// value is not finite.
void ValidateHyperparameters(const Hyperparameters& hyper, const Kernel& kernel,
                             int num_outputs);

}  // namespace structgp

#endif  // STRUCTGP_KERNEL_KERNEL_HYPERPARAMETERS_H_
