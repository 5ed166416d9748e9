#ifndef STRUCTGP_CORE_HYPERPARAMETERS_H_
#define STRUCTGP_CORE_HYPERPARAMETERS_H_

/// @file
/// The hyper-parameters of every model, all on a log scale where they are positive. One type
/// for the feature-map (weight-space) form and the kernel (function-space) form:
///
/// | field            | feature map (FeatureMap)                 | kernel (Kernel)              |
/// |------------------|------------------------------------------|------------------------------|
/// | shape            | FeatureMap::num_shape_parameters() values | Kernel::parameters() (all)  |
/// | log_block_scale  | one per FeatureMap::blocks() entry        | empty                        |
/// | log_noise_std    | log sigma_n                               | log sigma_n                  |
/// | log_output_scale | one per output                            | one per output               |
///
/// Feature map: the prior variance of feature k in block b is
///     Lambda_k = lambda_k(shape) * exp(2 * log_block_scale[b])
/// (PriorVariance in feature/feature_hyperparameters.h). Kernel: `shape` holds the kernel's
/// parameters in the layout of Kernel::parameters() and Kernel::WithParameters (its block
/// scales, if it has any, are among them). Both: the noise variance is
/// sigma_n^2 = exp(2 * log_noise_std), and output j is scaled by s_j = exp(log_output_scale[j]):
/// its prior and its noise are both multiplied by s_j^2, so all outputs keep one shared
/// posterior factor (see model/weight_space_gp.h).
///
/// The checks against a map or a kernel (sizes) and the defaults live next to them:
/// feature/feature_hyperparameters.h and kernel/kernel_hyperparameters.h.

#include <string>

#include "structgp/core/types.h"

namespace structgp {

struct Hyperparameters {
  /// Feature map: its shape parameters. Kernel: all of its parameters (see the file comment).
  Vector shape;
  /// Feature map: one per block, 0 leaves the map's own prior unchanged. Kernel: empty.
  Vector log_block_scale;
  /// log sigma_n.
  double log_noise_std = -2.302585092994046;  // log(0.1)
  /// One per output; 0 for unit scale.
  Vector log_output_scale;

  /// sigma_n^2.
  double noise_variance() const;
  /// s_j = exp(log_output_scale[j]).
  Vector output_scales() const;
  /// Each output's noise standard deviation s_j sigma_n = exp(log_noise_std +
  /// log_output_scale[j]), in the output's units.
  Vector noise_stds() const;

  /// Throws std::invalid_argument ("<what>.shape: expected N, got M") when the sizes differ
  /// from the given ones, a value is not finite, or log_noise_std lies outside (-50, 50).
  void Validate(Eigen::Index num_shape, Eigen::Index num_blocks, Eigen::Index num_outputs,
                const std::string& what = "Hyperparameters") const;
};

}  // namespace structgp

#endif  // STRUCTGP_CORE_HYPERPARAMETERS_H_
