#ifndef STRUCTGP_MODEL_SUFFICIENT_STATISTICS_H_
#define STRUCTGP_MODEL_SUFFICIENT_STATISTICS_H_

/// @file
/// Everything a weight-space model needs from a data set: Phi^T Phi, Phi^T Y, sum y^2 and the
/// sample count. Memory is O(D^2 + D P), independent of the number of samples, so a data set
/// can be streamed in chunks; and a hyper-parameter search that only rescales the prior never
/// touches the data again.

#include <Eigen/Core>

#include "structgp/core/types.h"
#include "structgp/feature/feature_map.h"

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
  /// Adds the same statistics given transposed: PhiT (D x rows, one sample per column, as a
  /// feature map writes them contiguously) and Y (rows x P). Same checks as Accumulate.
  void AccumulateTransposed(const ConstMatrixRef& PhiT, const ConstMatrixRef& Y);
  /// Adds the statistics of another set of samples (same D and P; throws otherwise).
  void Merge(const SufficientStatistics& other);
};

/// Default rows per chunk of AccumulateStatistics: 1024 samples of D = 512 features are 4 MiB,
/// enough for the rank-k update to run at BLAS-3 speed.
inline constexpr Eigen::Index kDefaultChunkRows = 1024;

/// How AccumulateStatistics streams the data.
struct AccumulateOptions {
  /// Samples whose features are held at once, per worker (>= 1).
  Eigen::Index chunk_rows = kDefaultChunkRows;
  /// Worker threads (>= 1). Each takes a contiguous range of rows and its own statistics;
  /// the partial sums are added at the end in worker order, so a result depends on
  /// num_threads only through the order of floating-point additions (relative differences
  /// of order m * epsilon at worst, ~1e-14 in practice) and is reproducible for a given
  /// num_threads.
  int num_threads = 1;
};

/// The sufficient statistics of the samples X (m x input_dim) -> Y (m x P) under `map`,
/// computed in chunks: features are evaluated chunk_rows samples at a time and added by a
/// symmetric rank-k update. Memory: num_threads x (D^2 + chunk_rows x D + D x P) doubles,
/// never m x D. Throws std::invalid_argument on sizes, options or non-finite values (naming
/// the row). With num_threads > 1, map.Evaluate must be safe to call concurrently: every map of
/// the library is (a NystromFeatureMap on a kernel of your own is when that kernel's Evaluate
/// is; see nystrom_feature_map.h).
SufficientStatistics AccumulateStatistics(const FeatureMap& map, const ConstMatrixRef& X,
                                          const ConstMatrixRef& Y,
                                          const AccumulateOptions& options = {});

}  // namespace structgp

#endif  // STRUCTGP_MODEL_SUFFICIENT_STATISTICS_H_
