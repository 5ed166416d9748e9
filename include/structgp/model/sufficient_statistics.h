#ifndef STRUCTGP_MODEL_SUFFICIENT_STATISTICS_H_
#define STRUCTGP_MODEL_SUFFICIENT_STATISTICS_H_

/// @file
/// Everything a weight-space model needs from a data set: Phi^T Phi, Phi^T Y, sum y^2 and the
/// sample count. Memory is O(D^2 + D P), independent of the number of samples, so a data set
/// can be streamed in chunks; and a hyper-parameter search that only rescales the prior never
/// touches the data again.

#include "structgp/core/types.h"

namespace structgp {

struct SufficientStatistics {
  /// Phi^T Phi (D x D). Only the lower triangle is kept up to date.
  Matrix gram;
  /// Phi^T Y (D x P).
  Matrix cross;
  /// Per output, sum of y^2 (P).
  Vector y_squared;
  /// Number of samples accumulated.
  double count = 0.0;

  SufficientStatistics() = default;
  SufficientStatistics(int num_features, int num_outputs);

  int num_features() const { return static_cast<int>(gram.rows()); }
  int num_outputs() const { return static_cast<int>(cross.cols()); }

  /// Adds a chunk of samples: Phi (rows x D) and Y (rows x P). Uses a BLAS-3 symmetric rank-k
  /// update. Throws std::invalid_argument on a size mismatch or a non-finite value (nothing is
  /// added then).
  void Accumulate(const ConstMatrixRef& Phi, const ConstMatrixRef& Y);
};

}  // namespace structgp

#endif  // STRUCTGP_MODEL_SUFFICIENT_STATISTICS_H_
