#ifndef STRUCTGP_CORE_NOISE_LEVEL_H_
#define STRUCTGP_CORE_NOISE_LEVEL_H_

/// @file
/// The level of the white noise in a series (a residual, a torque), from its successive
/// differences: what the diagnosis measures its effects against, and what a chain's
/// identification compares its residual with.

#include <vector>

#include "structgp/core/types.h"

namespace structgp {

/// The spread of the white noise in x, from its successive differences within segments
/// (segment_starts as SegmentStarts gives them; a difference never spans a restart): the median
/// absolute difference over 0.674 sqrt 2, which a slow wander of x does not move. 0 when no
/// segment has two rows.
double NoiseFromDifferences(const ConstVectorRef& x, const std::vector<int>& segment_starts);

}  // namespace structgp

#endif  // STRUCTGP_CORE_NOISE_LEVEL_H_
