#ifndef STRUCTGP_HYPER_CROSS_VALIDATION_H_
#define STRUCTGP_HYPER_CROSS_VALIDATION_H_

/// @file
/// Blocked k-fold cross-validation of a feature-map model, and the paper's evaluation split.
///
/// Samples along a trajectory are strongly correlated, so a random split into folds leaks
/// every held-out sample's neighbours into the training set and rewards over-fitting. Here
/// the folds are contiguous blocks of rows in time order, never random rows (paper,
/// Sec. V-VI).
///
/// Cost. The data are read once: FoldStatistics evaluates the features of every row and adds
/// them to the SufficientStatistics of the row's fold. The model of fold f is then fitted on
/// the statistics of all the other folds, total minus fold f (O(D^2)), and its held-out
/// squared error follows from fold f's own statistics (G_f = Phi_f^T Phi_f, B_f = Phi_f^T Y_f):
///     sum_{i in f} ||y_i - W^T phi_i||^2 = sum_{i in f} ||y_i||^2 - 2 tr(W^T B_f) + tr(W^T G_f W).
/// A cross-validation is therefore k O(D^3) solves, independent of the number of samples, and
/// a grid of candidates re-uses the same statistics. Memory: O(k (D^2 + D P)).

#include <utility>
#include <vector>

#include "structgp/core/status.h"
#include "structgp/core/row_subset.h"  // SelectRows
#include "structgp/core/segments.h"
#include "structgp/core/types.h"
#include "structgp/feature/feature_map.h"
#include "structgp/feature/feature_hyperparameters.h"
#include "structgp/model/sufficient_statistics.h"

namespace structgp {

/// The sufficient statistics of each contiguous fold of a data set, from one pass over it.
/// Immutable after construction.
class FoldStatistics {
 public:
  /// X: m x map.input_dim(), Y: m x P (P >= 1), folds = SegmentFolds(m, num_folds,
  /// segment_starts) with 2 <= num_folds <= m (core/segments.h: whole trajectories per fold
  /// when the log has enough of them; the default, one segment, gives ContiguousFolds).
  /// Features are evaluated in chunks of at most 512 rows. Throws std::invalid_argument on bad
  /// sizes, a bad fold count, bad segment starts or NaN/Inf.
  FoldStatistics(const FeatureMap& map, const ConstMatrixRef& X, const ConstMatrixRef& Y,
                 int num_folds, const std::vector<int>& segment_starts = {0});

  int num_folds() const { return static_cast<int>(folds_.size()); }
  int num_features() const { return total_.num_features(); }
  int num_outputs() const { return total_.num_outputs(); }
  /// Number of rows m.
  int num_rows() const { return folds_.empty() ? 0 : folds_.back().second; }
  /// Rows of every fold, [begin, end).
  const std::vector<std::pair<int, int>>& folds() const { return folds_; }
  /// Statistics of the rows of fold f.
  const SufficientStatistics& fold(int f) const { return fold_.at(static_cast<size_t>(f)); }
  /// Per output, the sum of the targets of fold f (P); with fold(f).y_squared it gives the
  /// held-out target variance.
  const Vector& target_sum(int f) const { return target_sum_.at(static_cast<size_t>(f)); }
  /// Statistics of all rows.
  const SufficientStatistics& total() const { return total_; }
  /// Statistics of every fold but f: total() minus fold(f) (lower triangle of the Gram
  /// matrix). O(D^2).
  SufficientStatistics Training(int f) const;

 private:
  std::vector<std::pair<int, int>> folds_;
  std::vector<SufficientStatistics> fold_;
  std::vector<Vector> target_sum_;
  SufficientStatistics total_;
};

/// Held-out error of one fold.
struct FoldError {
  /// Held-out rows [begin, end).
  int begin = 0;
  int end = 0;
  /// Outcome of the fit on the other folds; when not kOk the errors are +infinity.
  Status status = Status::kOk;
  /// Per output: root mean squared error over the held-out rows (units of the targets).
  Vector rms;
  /// Per output: mean squared error / variance of the held-out targets (+infinity when that
  /// variance is 0).
  Vector nmse;
};

struct CrossValidationResult {
  std::vector<FoldError> folds;
  /// Per output, pooled over all rows (each row is held out exactly once): RMS error, and the
  /// mean squared error divided by the variance of all targets (+infinity when any fold
  /// failed or that variance is 0).
  Vector rms;
  Vector nmse;
  /// Mean of nmse over the outputs: the criterion SelectByCrossValidation minimises.
  double mean_nmse = 0.0;
  int num_failed_folds = 0;
};

/// Blocked cross-validation of the weight-space model with the map's features and `hyper`:
/// for every fold, the posterior mean given the other folds, scored on the fold. k O(D^3)
/// solves. Throws std::invalid_argument when hyper or the statistics do not match the map.
CrossValidationResult BlockedCrossValidation(const FeatureMap& map, const FoldStatistics& data,
                                             const Hyperparameters& hyper);

/// The same from the data: FoldStatistics(map, X, Y, num_folds), then the above.
CrossValidationResult BlockedCrossValidation(const FeatureMap& map, const ConstMatrixRef& X,
                                             const ConstMatrixRef& Y, int num_folds,
                                             const Hyperparameters& hyper);

/// Candidates for SelectByCrossValidation: `base` with shape[shape_index] set to each of
/// shape_values and log_noise_std to each of log_noise_values (shape is the slow index). An
/// empty list keeps base's value. E.g. a log sigma grid x a log noise grid for k_pol.
/// Throws std::invalid_argument when shape_values is not empty and shape_index is out of
/// range.
std::vector<Hyperparameters> HyperparameterGrid(const Hyperparameters& base,
                                                const std::vector<double>& shape_values,
                                                const std::vector<double>& log_noise_values,
                                                int shape_index = 0);

/// The candidate with the smallest blocked-CV mean_nmse (the first on ties), at k O(D^3)
/// solves per candidate on the same statistics. `results`, when not null, receives one
/// CrossValidationResult per candidate; `best_index`, when not null, the index of the
/// returned candidate, or -1 when every candidate failed (then candidates.front() is
/// returned). Throws std::invalid_argument when candidates is empty or one does not match.
Hyperparameters SelectByCrossValidation(const FeatureMap& map, const FoldStatistics& data,
                                        const std::vector<Hyperparameters>& candidates,
                                        std::vector<CrossValidationResult>* results = nullptr,
                                        int* best_index = nullptr);

/// Row indices of a training set and a test set.
struct TrainTestSplit {
  std::vector<int> train;  ///< increasing
  std::vector<int> test;   ///< increasing
};

/// The paper's protocol: within each trajectory, train on its first rows and test on the
/// rest. trajectory_ids holds one id per row; the rows sharing an id form one trajectory, in
/// row order (they need not be contiguous). Of a trajectory of n rows the first
/// round(train_fraction * n) are for training. Throws std::invalid_argument unless
/// 0 <= train_fraction <= 1.
TrainTestSplit TrainTestSplitPerTrajectory(const std::vector<int>& trajectory_ids,
                                           double train_fraction = 1.0 / 3.0);

/// The same with trajectories given as row ranges [begin, end) (non-overlapping, any order).
/// Throws std::invalid_argument on a range with begin < 0 or end < begin, on overlapping
/// ranges, or a bad fraction.
TrainTestSplit TrainTestSplitPerSegment(const std::vector<std::pair<int, int>>& segments,
                                        double train_fraction = 1.0 / 3.0);

}  // namespace structgp

#endif  // STRUCTGP_HYPER_CROSS_VALIDATION_H_
