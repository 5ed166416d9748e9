#ifndef STRUCTGP_FEATURE_FEATURE_HYPERPARAMETERS_H_
#define STRUCTGP_FEATURE_FEATURE_HYPERPARAMETERS_H_

/// @file
/// Hyperparameters (core/hyperparameters.h) of a feature-map model: their defaults, their
/// check against the map, and the prior variance Lambda they give.

#include "structgp/core/hyperparameters.h"
#include "structgp/core/types.h"
#include "structgp/feature/feature_map.h"

namespace structgp {

/// The map's default shape, unit block and output scales (num_outputs of them),
/// sigma_n = 0.1.
Hyperparameters DefaultHyperparameters(const FeatureMap& map, int num_outputs);

/// Throws std::invalid_argument when the sizes of hyper do not match the map
/// (num_shape_parameters(), blocks()) and num_outputs, or a value is not finite.
void ValidateHyperparameters(const Hyperparameters& hyper, const FeatureMap& map,
                             int num_outputs);

/// Lambda (size map.dim()) for these hyper-parameters (any number of outputs). When
/// d_lambda_d_shape is not null it receives d Lambda / d shape (dim x num_shape_parameters).
/// Throws std::invalid_argument when hyper does not match the map.
Vector PriorVariance(const FeatureMap& map, const Hyperparameters& hyper,
                     Matrix* d_lambda_d_shape = nullptr);

}  // namespace structgp

#endif  // STRUCTGP_FEATURE_FEATURE_HYPERPARAMETERS_H_
