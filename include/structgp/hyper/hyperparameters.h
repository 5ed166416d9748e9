#ifndef STRUCTGP_HYPER_HYPERPARAMETERS_H_
#define STRUCTGP_HYPER_HYPERPARAMETERS_H_

/// @file
/// Hyper-parameters of a feature-map model, all on a log scale where they are positive.
///
/// The prior variance of feature k in block b is
///     Lambda_k = lambda_k(shape) * exp(2 * log_block_scale[b]),
/// the noise variance is sigma_n^2 = exp(2 * log_noise_std), and output j is scaled by
/// s_j = exp(log_output_scale[j]): its prior and its noise are both multiplied by s_j^2, so all
/// outputs keep one shared posterior factor (see model/weight_space_gp.h).

#include "structgp/core/types.h"
#include "structgp/feature/feature_map.h"

namespace structgp {

struct Hyperparameters {
  /// Shape parameters of the feature map (FeatureMap::num_shape_parameters()).
  Vector shape;
  /// One per block of the feature map; 0 leaves the map's own prior unchanged.
  Vector log_block_scale;
  /// log sigma_n.
  double log_noise_std = -2.302585092994046;  // log(0.1)
  /// One per output; 0 for unit scale.
  Vector log_output_scale;

  /// The map's default shape, unit block and output scales, sigma_n = 0.1.
  static Hyperparameters Defaults(const FeatureMap& map, int num_outputs);

  double noise_variance() const;
  Vector output_scales() const;
  /// Throws std::invalid_argument when sizes do not match the map or values are not finite.
  void Validate(const FeatureMap& map, int num_outputs) const;
};

/// Lambda (size map.dim()) for these hyper-parameters. When d_lambda_d_shape is not null it
/// receives d Lambda / d shape (dim x num_shape_parameters).
Vector PriorVariance(const FeatureMap& map, const Hyperparameters& hyper,
                     Matrix* d_lambda_d_shape = nullptr);

}  // namespace structgp

#endif  // STRUCTGP_HYPER_HYPERPARAMETERS_H_
