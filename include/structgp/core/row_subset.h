#ifndef STRUCTGP_CORE_ROW_SUBSET_H_
#define STRUCTGP_CORE_ROW_SUBSET_H_

/// @file
/// The one rule by which the library takes fewer rows than it was given (a function-space fit
/// beyond its row limit, a kernel's hyper-parameters fitted on a subset, experiments that cap a
/// split): row k of a subset of M rows out of m is floor(k m / M), k = 0..M-1. The subset
/// starts at row 0, keeps time order and spreads evenly over the whole log with a constant
/// stride m / M (the last row is included only when M = m).

#include <vector>

#include "structgp/core/types.h"

namespace structgp {

/// Indices floor(k m / count), k = 0..count-1, when 0 < count < m; otherwise every row
/// 0..m-1. Throws std::invalid_argument when m < 0.
std::vector<int> EvenlySpacedRows(Eigen::Index m, Eigen::Index count);

/// The rows of X with the given indices, in that order. Throws std::invalid_argument on an
/// index out of range.
Matrix SelectRows(const ConstMatrixRef& X, const std::vector<int>& rows);

}  // namespace structgp

#endif  // STRUCTGP_CORE_ROW_SUBSET_H_
