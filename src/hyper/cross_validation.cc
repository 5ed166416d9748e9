#include "structgp/hyper/cross_validation.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <stdexcept>
#include <string>

#include "structgp/core/validate.h"
#include "structgp/model/weight_space_gp.h"

namespace structgp {
namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();
// Rows whose features are evaluated together: bounds the temporary Phi at 512 x D.
constexpr int kChunkRows = 512;

void RequireFraction(const char* who, double train_fraction) {
  RequireInRange(std::string(who) + " train_fraction", train_fraction, 0.0, 1.0, true, true);
}

// Appends the first round(fraction n) rows of `rows` to train and the others to test.
void SplitTrajectory(const std::vector<int>& rows, double train_fraction, TrainTestSplit* split) {
  const auto n = static_cast<long>(rows.size());
  const long num_train = std::min(n, std::lround(train_fraction * static_cast<double>(n)));
  for (long i = 0; i < n; ++i) {
    (i < num_train ? split->train : split->test).push_back(rows[static_cast<size_t>(i)]);
  }
}

void SortSplit(TrainTestSplit* split) {
  std::sort(split->train.begin(), split->train.end());
  std::sort(split->test.begin(), split->test.end());
}

// Variance of n targets with the given sum and sum of squares (0 when n == 0).
double Variance(double n, double sum, double sum_squares) {
  if (n <= 0.0) return 0.0;
  const double mean = sum / n;
  return std::max(0.0, sum_squares / n - mean * mean);
}

}  // namespace

FoldStatistics::FoldStatistics(const FeatureMap& map, const ConstMatrixRef& X,
                               const ConstMatrixRef& Y, int num_folds,
                               const std::vector<int>& segment_starts) {
  RequireSize("FoldStatistics X", X.cols(), map.input_dim(), "columns");
  RequireSize("FoldStatistics Y", Y.rows(), X.rows(), "rows (as in X)");
  if (Y.cols() < 1) throw std::invalid_argument("FoldStatistics: Y has no columns");
  const int m = static_cast<int>(X.rows());
  if (num_folds < 2 || num_folds > m) {
    throw std::invalid_argument("FoldStatistics: expected 2 <= num_folds <= m, got num_folds = " +
                                std::to_string(num_folds) + ", m = " + std::to_string(m));
  }
  RequireFinite("FoldStatistics X", X);
  RequireFinite("FoldStatistics Y", Y);
  const int D = map.dim();
  const int P = static_cast<int>(Y.cols());
  folds_ = SegmentFolds(m, num_folds, segment_starts);
  total_ = SufficientStatistics(D, P);
  Matrix Phi;
  for (const auto& [begin, end] : folds_) {
    SufficientStatistics stats(D, P);
    for (int row = begin; row < end; row += kChunkRows) {
      const int rows = std::min(kChunkRows, end - row);
      map.EvaluateRows(X.middleRows(row, rows), &Phi);
      stats.Accumulate(Phi, Y.middleRows(row, rows));
    }
    target_sum_.push_back(Y.middleRows(begin, end - begin).colwise().sum().transpose());
    total_.gram += stats.gram;
    total_.cross += stats.cross;
    total_.y_squared += stats.y_squared;
    total_.count += stats.count;
    fold_.push_back(std::move(stats));
  }
}

SufficientStatistics FoldStatistics::Training(int f) const {
  const SufficientStatistics& held_out = fold(f);
  SufficientStatistics training = total_;
  training.gram.triangularView<Eigen::Lower>() -= held_out.gram;
  training.cross -= held_out.cross;
  training.y_squared -= held_out.y_squared;
  training.count -= held_out.count;
  return training;
}

CrossValidationResult BlockedCrossValidation(const FeatureMap& map, const FoldStatistics& data,
                                             const Hyperparameters& hyper) {
  RequireSize("BlockedCrossValidation statistics", data.num_features(), map.dim(), "features");
  const int P = data.num_outputs();
  ValidateHyperparameters(hyper, map, P);
  const Vector lambda = PriorVariance(map, hyper);
  WeightSpaceGP model(lambda, hyper.noise_variance(), P, hyper.output_scales());

  CrossValidationResult result;
  Vector total_sse = Vector::Zero(P);
  Vector total_sum = Vector::Zero(P);
  for (int f = 0; f < data.num_folds(); ++f) {
    const SufficientStatistics& held_out = data.fold(f);
    FoldError error;
    error.begin = data.folds()[static_cast<size_t>(f)].first;
    error.end = data.folds()[static_cast<size_t>(f)].second;
    error.status = model.Fit(data.Training(f));
    total_sum += data.target_sum(f);
    if (error.status != Status::kOk) {
      error.rms = Vector::Constant(P, kInfinity);
      error.nmse = Vector::Constant(P, kInfinity);
      ++result.num_failed_folds;
      result.folds.push_back(std::move(error));
      continue;
    }
    const Matrix& W = model.weights();
    // G W with G = Phi_f^T Phi_f, of which only the lower triangle is kept.
    const Matrix gram_w = held_out.gram.selfadjointView<Eigen::Lower>() * W;
    error.rms.resize(P);
    error.nmse.resize(P);
    const double n = held_out.count;
    for (int j = 0; j < P; ++j) {
      // Rounding can make the expanded square slightly negative when the fit is exact.
      const double sse =
          std::max(0.0, held_out.y_squared[j] - 2.0 * W.col(j).dot(held_out.cross.col(j)) +
                            W.col(j).dot(gram_w.col(j)));
      total_sse[j] += sse;
      const double mse = sse / n;
      const double variance = Variance(n, data.target_sum(f)[j], held_out.y_squared[j]);
      error.rms[j] = std::sqrt(mse);
      error.nmse[j] = variance > 0.0 ? mse / variance : kInfinity;
    }
    result.folds.push_back(std::move(error));
  }

  const SufficientStatistics& total = data.total();
  result.rms.resize(P);
  result.nmse.resize(P);
  for (int j = 0; j < P; ++j) {
    if (result.num_failed_folds > 0) {
      result.rms[j] = kInfinity;
      result.nmse[j] = kInfinity;
      continue;
    }
    const double mse = total_sse[j] / total.count;
    const double variance = Variance(total.count, total_sum[j], total.y_squared[j]);
    result.rms[j] = std::sqrt(mse);
    result.nmse[j] = variance > 0.0 ? mse / variance : kInfinity;
  }
  result.mean_nmse = result.nmse.mean();
  return result;
}

CrossValidationResult BlockedCrossValidation(const FeatureMap& map, const ConstMatrixRef& X,
                                             const ConstMatrixRef& Y, int num_folds,
                                             const Hyperparameters& hyper) {
  return BlockedCrossValidation(map, FoldStatistics(map, X, Y, num_folds), hyper);
}

std::vector<Hyperparameters> HyperparameterGrid(const Hyperparameters& base,
                                                const std::vector<double>& shape_values,
                                                const std::vector<double>& log_noise_values,
                                                int shape_index) {
  if (!shape_values.empty() && (shape_index < 0 || shape_index >= base.shape.size())) {
    throw std::invalid_argument("HyperparameterGrid: expected 0 <= shape_index < " +
                                std::to_string(base.shape.size()) + ", got " +
                                std::to_string(shape_index));
  }
  const std::vector<double> shapes = shape_values.empty() ? std::vector<double>{0.0} : shape_values;
  const std::vector<double> noises =
      log_noise_values.empty() ? std::vector<double>{base.log_noise_std} : log_noise_values;
  std::vector<Hyperparameters> grid;
  grid.reserve(shapes.size() * noises.size());
  for (double shape : shapes) {
    for (double log_noise : noises) {
      Hyperparameters h = base;
      if (!shape_values.empty()) h.shape[shape_index] = shape;
      h.log_noise_std = log_noise;
      grid.push_back(std::move(h));
    }
  }
  return grid;
}

Hyperparameters SelectByCrossValidation(const FeatureMap& map, const FoldStatistics& data,
                                        const std::vector<Hyperparameters>& candidates,
                                        std::vector<CrossValidationResult>* results,
                                        int* best_index) {
  if (candidates.empty()) {
    throw std::invalid_argument("SelectByCrossValidation: no candidates");
  }
  if (results != nullptr) results->clear();
  int best = -1;
  double best_score = kInfinity;
  for (size_t c = 0; c < candidates.size(); ++c) {
    CrossValidationResult result = BlockedCrossValidation(map, data, candidates[c]);
    if (result.mean_nmse < best_score) {
      best_score = result.mean_nmse;
      best = static_cast<int>(c);
    }
    if (results != nullptr) results->push_back(std::move(result));
  }
  if (best_index != nullptr) *best_index = best;
  return candidates[best < 0 ? 0 : static_cast<size_t>(best)];
}

TrainTestSplit TrainTestSplitPerTrajectory(const std::vector<int>& trajectory_ids,
                                           double train_fraction) {
  RequireFraction("TrainTestSplitPerTrajectory", train_fraction);
  std::map<int, std::vector<int>> rows_of;
  for (size_t i = 0; i < trajectory_ids.size(); ++i) {
    rows_of[trajectory_ids[i]].push_back(static_cast<int>(i));
  }
  TrainTestSplit split;
  for (const auto& entry : rows_of) SplitTrajectory(entry.second, train_fraction, &split);
  SortSplit(&split);
  return split;
}

TrainTestSplit TrainTestSplitPerSegment(const std::vector<std::pair<int, int>>& segments,
                                        double train_fraction) {
  RequireFraction("TrainTestSplitPerSegment", train_fraction);
  std::vector<std::pair<int, int>> sorted = segments;
  std::sort(sorted.begin(), sorted.end());
  for (size_t s = 0; s < sorted.size(); ++s) {
    const auto [begin, end] = sorted[s];
    if (begin < 0 || end < begin || (s > 0 && begin < sorted[s - 1].second)) {
      throw std::invalid_argument(
          "TrainTestSplitPerSegment: expected non-overlapping ranges [begin, end) with "
          "0 <= begin <= end, got [" +
          std::to_string(begin) + ", " + std::to_string(end) + ")" +
          (s > 0 ? " after [" + std::to_string(sorted[s - 1].first) + ", " +
                       std::to_string(sorted[s - 1].second) + ")"
                 : std::string()));
    }
  }
  TrainTestSplit split;
  std::vector<int> rows;
  for (const auto& [begin, end] : segments) {
    rows.clear();
    for (int i = begin; i < end; ++i) rows.push_back(i);
    SplitTrajectory(rows, train_fraction, &split);
  }
  SortSplit(&split);
  return split;
}

}  // namespace structgp
