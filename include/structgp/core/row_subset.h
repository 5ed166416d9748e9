#ifndef STRUCTGP_CORE_ROW_SUBSET_H_
#define STRUCTGP_CORE_ROW_SUBSET_H_

/// @file
/// The one rule by which the library takes fewer rows than it was given (a function-space fit
/// beyond its row limit, a kernel's hyper-parameters fitted on a subset, experiments that cap a
/// split): row k of a subset of M rows out of m is floor(k m / M), k = 0..M-1. The subset
/// starts at row 0, keeps time order and spreads evenly over the whole log with a constant
/// stride m / M (the last row is included only when M = m).
///
/// Inducing states are another matter: they must cover the states, not the time, and a constant
/// stride can alias with a periodic trajectory (every via point at rest, say). For them,
/// FarthestStateRows.

#include <vector>

#include "structgp/core/types.h"

namespace structgp {

/// Indices floor(k m / count), k = 0..count-1, when 0 < count < m; otherwise every row
/// 0..m-1. Throws std::invalid_argument when m < 0.
std::vector<int> EvenlySpacedRows(Eigen::Index m, Eigen::Index count);

/// count rows of X (all when count <= 0 or count >= m) chosen greedily to cover its states:
/// each column scaled by its standard deviation (columns that do not vary are ignored), the
/// first row the one farthest from the mean, each next one the farthest from those chosen
/// (Euclidean; ties to the earliest row). Returned in ascending order. O(m count cols).
std::vector<int> FarthestStateRows(const ConstMatrixRef& X, Eigen::Index count);

/// The rows of X with the given indices, in that order. Throws std::invalid_argument on an
/// index out of range.
Matrix SelectRows(const ConstMatrixRef& X, const std::vector<int>& rows);

}  // namespace structgp

#endif  // STRUCTGP_CORE_ROW_SUBSET_H_
