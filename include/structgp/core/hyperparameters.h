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
/// Per-joint hyper-parameters: when `per_output` is not empty, output j is a Gaussian process of
/// its own with per_output[j] (its own shape, block scales, noise and one output scale), the
/// outputs no longer share one posterior factor, and the shared fields hold the set the
/// per-output ones started from (FitModel: the data-derived start, the hyper-prior's centre),
/// which the model does not use. Costs: P factors instead of one (weight space: P x D^2 memory
/// and P x O(D^2) per online sample; function space: P kernel matrices).
///
/// The checks against a map or a kernel (sizes) and the defaults live next to them:
/// feature/feature_hyperparameters.h and kernel/kernel_hyperparameters.h.

#include <string>
#include <vector>

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
  /// Empty: the fields above serve every output. Otherwise one set per output, each with one
  /// output scale and no per_output of its own (see the file comment).
  std::vector<Hyperparameters> per_output;

  /// True when each output has its own set (per_output not empty).
  bool is_per_output() const { return !per_output.empty(); }
  /// Output j's set as a single-output set (one output scale, no per_output): per_output[j],
  /// or the shared fields with output j's scale. Throws std::out_of_range for a j outside
  /// the outputs.
  Hyperparameters Output(Eigen::Index j) const;

  /// sigma_n^2 of the shared fields.
  double noise_variance() const;
  /// s_j = exp(log_output_scale[j]) of the shared fields.
  Vector output_scales() const;
  /// Each output's noise standard deviation s_j sigma_n = exp(log_noise_std +
  /// log_output_scale[j]), in the output's units; per output, from that output's own set.
  Vector noise_stds() const;

  /// Throws std::invalid_argument ("<what>.shape: expected N, got M") when the sizes differ
  /// from the given ones, a value is not finite, or log_noise_std lies outside (-50, 50); the
  /// same for every per_output entry (one output scale each), of which there must be
  /// num_outputs or none.
  void Validate(Eigen::Index num_shape, Eigen::Index num_blocks, Eigen::Index num_outputs,
                const std::string& what = "Hyperparameters") const;
};

}  // namespace structgp

#endif  // STRUCTGP_CORE_HYPERPARAMETERS_H_
