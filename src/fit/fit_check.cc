#include "structgp/fit/fit_check.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

#include "structgp/core/row_subset.h"
#include "structgp/core/validate.h"
#include "structgp/hyper/cross_validation.h"
#include "structgp/internal/text.h"

namespace structgp {

using internal::Format;

bool FitCheckOptions::IsValid(std::string* error) const {
  auto fail = [error](const std::string& message) {
    if (error != nullptr) *error = message;
    return false;
  };
  if (folds < 2) return fail("FitCheckOptions::folds: expected >= 2, got " + std::to_string(folds));
  if (max_rows < 2 * folds) {
    return fail(Format("FitCheckOptions::max_rows: expected >= 2 * folds = %d, got %d", 2 * folds,
                       max_rows));
  }
  if (!(std::isfinite(range_margin) && range_margin >= 0.0)) {
    return fail(Format("FitCheckOptions::range_margin: expected a finite value >= 0, got %g",
                       range_margin));
  }
  if (!(std::isfinite(confidence_sigmas) && confidence_sigmas >= 0.0)) {
    return fail(Format("FitCheckOptions::confidence_sigmas: expected a finite value >= 0, got %g",
                       confidence_sigmas));
  }
  if (!(std::isfinite(max_fraction) && max_fraction >= 0.0 && max_fraction < 1.0)) {
    return fail(Format("FitCheckOptions::max_fraction: expected a value in [0, 1), got %g",
                       max_fraction));
  }
  if (!(target_coverage > 0.0 && target_coverage < 1.0)) {
    return fail(Format("FitCheckOptions::target_coverage: expected a value in (0, 1), got %g",
                       target_coverage));
  }
  if (!(min_coverage >= 0.0 && min_coverage <= 1.0)) {
    return fail(Format("FitCheckOptions::min_coverage: expected a value in [0, 1], got %g",
                       min_coverage));
  }
  return true;
}

Vector BandCoverage(const ConstMatrixRef& mean, const ConstMatrixRef& latent_std,
                    const ConstVectorRef& noise_std, const ConstMatrixRef& measured) {
  const Eigen::Index N = noise_std.size();
  RequireSize("BandCoverage mean", mean.cols(), N, "columns (joints, as noise_std)");
  RequireSize("BandCoverage latent_std", latent_std.cols(), N, "columns (joints, as noise_std)");
  RequireSize("BandCoverage measured", measured.cols(), N, "columns (joints, as noise_std)");
  RequireSize("BandCoverage latent_std", latent_std.rows(), mean.rows(), "rows (as mean)");
  RequireSize("BandCoverage measured", measured.rows(), mean.rows(), "rows (as mean)");
  Vector coverage = Vector::Zero(N);
  if (mean.rows() == 0) return coverage;
  for (Eigen::Index j = 0; j < N; ++j) {
    Eigen::Index inside = 0;
    for (Eigen::Index i = 0; i < mean.rows(); ++i) {
      const double std = std::hypot(latent_std(i, j), noise_std[j]);
      // false for a NaN mean: outside.
      if (std::abs(measured(i, j) - mean(i, j)) <= 2.0 * std) ++inside;
    }
    coverage[j] = static_cast<double>(inside) / static_cast<double>(mean.rows());
  }
  return coverage;
}

namespace {

// The smallest kappa in [1, kMaxLatentVarianceScale] with which at least `target` of the rows
// (squared error e, latent variance v) satisfy e <= 4 (kappa v + noise_var): each row is
// covered from kappa_i = (e / 4 - noise_var) / v on, so kappa is the target quantile of the
// kappa_i. A row that no kappa covers (v = 0 and e beyond the noise band) counts as never.
double LatentVarianceScale(const std::vector<std::pair<double, double>>& rows,
                           double noise_var, double target) {
  if (rows.empty()) return 1.0;
  std::vector<double> needed;
  needed.reserve(rows.size());
  for (const auto& [e, v] : rows) {
    const double excess = e / 4.0 - noise_var;
    if (excess <= 0.0) {
      needed.push_back(0.0);
    } else if (v > 0.0 && std::isfinite(excess / v)) {
      needed.push_back(excess / v);
    } else {
      needed.push_back(std::numeric_limits<double>::infinity());
    }
  }
  const size_t k = static_cast<size_t>(
      std::min<double>(static_cast<double>(needed.size()) - 1.0,
                       std::ceil(target * static_cast<double>(needed.size())) - 1.0));
  std::nth_element(needed.begin(), needed.begin() + static_cast<std::ptrdiff_t>(k),
                   needed.end());
  return std::clamp(needed[k], 1.0, kMaxLatentVarianceScale);
}

// One held-out fold: a fresh model of model's spec and options with hyper-parameters `hyper`,
// fitted on the rows `train` of X, Y (in the order given), predicts the rows `test`: the mean
// and latent std (rows of test x N) and the measured torques of those rows. False when the fit
// fails numerically.
struct HeldOutFold {
  Matrix mean, latent_std, measured;
};
bool FitAndPredict(const RobotModel& model, const Hyperparameters& hyper, const Matrix& X,
                   const Matrix& Y, const std::vector<int>& train, const std::vector<int>& test,
                   HeldOutFold* fold) {
  RobotModel fitted(model.spec(), model.num_joints(), model.options());
  if (fitted.Fit(SelectRows(X, train), SelectRows(Y, train), hyper) != Status::kOk) return false;
  fitted.PredictRows(SelectRows(X, test), &fold->mean, &fold->latent_std);
  fold->measured = SelectRows(Y, test);
  return true;
}

// Appends each counted joint's (squared error, latent variance) of the fold's rows with a
// finite mean to errors[j].
template <typename Counts>
void AppendErrors(const HeldOutFold& fold, const Counts& counts,
                  std::vector<std::vector<std::pair<double, double>>>* errors) {
  for (Eigen::Index i = 0; i < fold.mean.rows(); ++i) {
    for (Eigen::Index j = 0; j < fold.mean.cols(); ++j) {
      const double mu = fold.mean(i, j);
      if (!counts(static_cast<int>(j)) || !std::isfinite(mu)) continue;
      const double residual = fold.measured(i, j) - mu;
      const double std = fold.latent_std(i, j);
      (*errors)[static_cast<size_t>(j)].emplace_back(residual * residual, std * std);
    }
  }
}

}  // namespace

FitCheck CheckOnHeldOutBlocks(const RobotModel& model, const Hyperparameters& hyper,
                              const ConstMatrixRef& X, const ConstMatrixRef& Y,
                              const FitCheckOptions& options, int only_joint) {
  std::string error;
  if (!options.IsValid(&error)) throw std::invalid_argument(error);
  const int N = model.num_joints();
  if (only_joint < 0 || only_joint > N) {
    throw std::invalid_argument("CheckOnHeldOutBlocks: only_joint: expected 0..." +
                                std::to_string(N) + ", got " + std::to_string(only_joint));
  }
  const auto counts = [only_joint](int j) { return only_joint == 0 || j + 1 == only_joint; };
  RequireSize("CheckOnHeldOutBlocks X", X.cols(), model.input_dim(), "columns");
  RequireSize("CheckOnHeldOutBlocks Y", Y.cols(), N, "columns (joints)");
  RequireSize("CheckOnHeldOutBlocks Y", Y.rows(), X.rows(), "rows (as in X)");
  FitCheck check;
  const std::vector<int> subset = EvenlySpacedRows(X.rows(), options.max_rows);
  const int m = static_cast<int>(subset.size());
  if (m < 2 * options.folds) {
    check.message = Format("held-out check not run: %d rows, fewer than 2 per block", m);
    return check;
  }
  const Matrix Xs = SelectRows(X, subset);
  const Matrix Ys = SelectRows(Y, subset);
  // The training torque range of every joint, over all rows given.
  const Vector lo = Y.colwise().minCoeff().transpose();
  const Vector hi = Y.colwise().maxCoeff().transpose();
  const Vector span = (hi - lo).cwiseMax(1e-12);
  const Vector noise_std = hyper.noise_stds();

  std::vector<int> absurd(static_cast<size_t>(N), 0);
  std::vector<int> confident(static_cast<size_t>(N), 0);
  std::vector<double> excursion(static_cast<size_t>(N), 0.0);
  std::vector<int> covered(static_cast<size_t>(N), 0);
  // Per joint and held-out row: the squared error and the latent variance, for the latent
  // variance scale.
  std::vector<std::vector<std::pair<double, double>>> errors(static_cast<size_t>(N));
  int skipped = 0;
  for (const auto& [begin, end] : ContiguousFolds(m, options.folds)) {
    const int held = end - begin;
    std::vector<int> train, test;
    for (int i = 0; i < m; ++i) (i >= begin && i < end ? test : train).push_back(i);
    HeldOutFold fold;
    if (!FitAndPredict(model, hyper, Xs, Ys, train, test, &fold)) {
      ++skipped;
      continue;
    }
    const Matrix& mean = fold.mean;
    const Matrix& latent_std = fold.latent_std;
    const Vector fold_coverage = BandCoverage(mean, latent_std, noise_std, fold.measured);
    for (int j = 0; j < N; ++j) {
      covered[static_cast<size_t>(j)] += static_cast<int>(std::lround(fold_coverage[j] * held));
    }
    AppendErrors(fold, counts, &errors);
    for (int i = 0; i < held; ++i) {
      for (int j = 0; j < N; ++j) {
        if (!counts(j)) continue;
        const double mu = mean(i, j);
        const double margin = options.range_margin * span[j];
        const double outside =
            std::max({0.0, mu - (hi[j] + margin), (lo[j] - margin) - mu});
        if (!std::isfinite(mu)) {
          ++absurd[static_cast<size_t>(j)];
          ++confident[static_cast<size_t>(j)];
          continue;
        }
        const double std = std::hypot(latent_std(i, j), noise_std[j]);
        if (outside > 0.0) {
          const bool sure = outside > options.confidence_sigmas * std;
          if (sure) ++confident[static_cast<size_t>(j)];
          if (sure || !options.count_only_confident) ++absurd[static_cast<size_t>(j)];
        }
        const double beyond = std::max({0.0, mu - hi[j], lo[j] - mu}) / span[j];
        excursion[static_cast<size_t>(j)] = std::max(excursion[static_cast<size_t>(j)], beyond);
      }
    }
    check.rows += held;
  }
  if (check.rows == 0) {
    check.message = "held-out check not run: no fold could be fitted";
    return check;
  }
  check.ran = true;
  // The fastest rows (by |qd|), predicted by the model fitted on the others.
  std::vector<std::vector<std::pair<double, double>>> fastest(static_cast<size_t>(N));
  if (options.fastest_rows_fold) {
    std::vector<int> order(static_cast<size_t>(m));
    for (int i = 0; i < m; ++i) order[static_cast<size_t>(i)] = i;
    std::stable_sort(order.begin(), order.end(), [&Xs, N](int a, int b) {
      return Xs.row(a).segment(N, N).squaredNorm() < Xs.row(b).segment(N, N).squaredNorm();
    });
    const int held = (m + options.folds - 1) / options.folds;
    std::vector<int> train(order.begin(), order.end() - held);
    std::vector<int> test(order.end() - held, order.end());
    std::sort(train.begin(), train.end());  // in time order
    std::sort(test.begin(), test.end());
    HeldOutFold fold;
    if (FitAndPredict(model, hyper, Xs, Ys, train, test, &fold)) {
      check.fastest_coverage = BandCoverage(fold.mean, fold.latent_std, noise_std, fold.measured);
      AppendErrors(fold, counts, &fastest);
      for (int j = 0; j < N; ++j) {
        if (!counts(j)) check.fastest_coverage[j] = std::numeric_limits<double>::quiet_NaN();
      }
    }
  }
  check.coverage.resize(N);
  check.latent_variance_scale.resize(N);
  for (int j = 0; j < N; ++j) {
    if (!counts(j)) {
      check.coverage[j] = std::numeric_limits<double>::quiet_NaN();
      check.latent_variance_scale[j] = std::numeric_limits<double>::quiet_NaN();
      continue;
    }
    const double noise_var = noise_std[j] * noise_std[j];
    check.latent_variance_scale[j] = std::max(
        LatentVarianceScale(errors[static_cast<size_t>(j)], noise_var, options.target_coverage),
        LatentVarianceScale(fastest[static_cast<size_t>(j)], noise_var, options.target_coverage));
    check.coverage[j] = static_cast<double>(covered[static_cast<size_t>(j)]) / check.rows;
    const double fraction = static_cast<double>(absurd[static_cast<size_t>(j)]) / check.rows;
    if (fraction > check.worst_fraction) {
      check.worst_joint = j + 1;
      check.worst_fraction = fraction;
      check.worst_confident_fraction =
          static_cast<double>(confident[static_cast<size_t>(j)]) / check.rows;
    }
  }
  double largest = 0.0;
  int largest_joint = only_joint > 0 ? only_joint : 1;
  for (int j = 0; j < N; ++j) {
    if (excursion[static_cast<size_t>(j)] > largest) {
      largest = excursion[static_cast<size_t>(j)];
      largest_joint = j + 1;
    }
  }
  check.worst_excursion =
      check.worst_joint > 0 ? excursion[static_cast<size_t>(check.worst_joint - 1)] : largest;
  check.passed = check.worst_fraction <= options.max_fraction;
  const std::string folds_text =
      Format("%d contiguous blocks of %d evenly spaced rows%s", options.folds, m,
             skipped > 0 ? Format(", %d not fitted", skipped).c_str() : "");
  // "89% 98% 72%": the counted joints' coverages.
  const auto percents = [&counts, N](const Vector& coverage) {
    std::string text;
    for (int j = 0; j < N; ++j) {
      if (counts(j)) text += Format("%s%.0f%%", text.empty() ? "" : " ", 100.0 * coverage[j]);
    }
    return text;
  };
  const std::string coverage_text = percents(check.coverage);
  if (check.passed) {
    check.message = Format(
        "held-out check passed (%s): largest excursion %.3g spans of the training torque range "
        "(joint %d)",
        folds_text.c_str(), largest, largest_joint);
  } else {
    check.message = Format(
        "held-out check failed (%s): %.1f%% of joint %d's held-out predictions lie more than "
        "%.3g spans outside its training torque range (up to %.3g spans; %.1f%% by more than "
        "%.3g predictive std)",
        folds_text.c_str(), 100.0 * check.worst_fraction, check.worst_joint,
        options.range_margin, check.worst_excursion, 100.0 * check.worst_confident_fraction,
        options.confidence_sigmas);
  }
  check.message += "; 2 sigma band covers " + coverage_text +
                   (only_joint > 0 ? Format(" of joint %d's held-out torques", only_joint)
                                   : std::string(" of the held-out torques per joint"));
  if (check.fastest_coverage.size() == N) {
    check.message += ", " + percents(check.fastest_coverage) +
                     " of the fastest rows' (fitted on the slower ones)";
  }
  return check;
}

}  // namespace structgp
