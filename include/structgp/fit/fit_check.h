#ifndef STRUCTGP_FIT_FIT_CHECK_H_
#define STRUCTGP_FIT_FIT_CHECK_H_

/// @file
/// A check of chosen hyper-parameters on held-out contiguous blocks of the training data: a
/// model with these hyper-parameters, fitted without one block, must not predict that block
/// far outside the range of the training torques while claiming to be sure of it.
///
/// A held-out prediction of joint j is *absurd* when its mean lies more than `range_margin`
/// spans outside [min tau_j, max tau_j] (span = max - min over all rows given), and
/// *confidently absurd* when that distance also exceeds `confidence_sigmas` predictive (noisy)
/// standard deviations. By default both count: on the UR10 log (docs/real_data.md) the fit
/// whose gravity scale ML-II inflated predicted held-out blocks 44 spans outside the torque
/// range with a standard deviation of the same size, because its prior variance was enormous
/// too; a model that does not know and says so falls back to its mean, which lies inside the
/// range. `count_only_confident` restricts the check to confidently absurd predictions.
///
/// The same predictions give each joint's held-out coverage: the fraction of the held-out
/// torques within 2 predictive (noisy) standard deviations of the held-out mean, about 95% for
/// a model whose bands are calibrated on motion it was not fitted on.
///
/// Cost: `folds` fits of the model on at most max_rows (1 - 1/folds) rows and predictions with
/// variance of the held-out rows; one more with fastest_rows_fold.

#include <string>

#include "structgp/core/hyperparameters.h"
#include "structgp/core/types.h"
#include "structgp/model/robot_model.h"

namespace structgp {

struct FitCheckOptions {
  /// Run the check at all (FitModel: after the evidence search).
  bool enabled = true;
  /// Contiguous held-out blocks (>= 2).
  int folds = 5;
  /// The check uses at most this many evenly spaced rows (core/row_subset.h), in time order,
  /// cut into `folds` blocks (>= 2 * folds). Function-space fits cost O(rows^3).
  int max_rows = 1000;
  /// How far outside the training torque range a prediction may lie, in spans of the range.
  double range_margin = 1.0;
  /// A prediction outside the widened range is confident when its distance to the range
  /// exceeds this many predictive standard deviations.
  double confidence_sigmas = 2.0;
  /// Count only confidently absurd predictions (see the file comment).
  bool count_only_confident = false;
  /// The check fails when more than this fraction of the held-out predictions of any joint
  /// are absurd (confidently absurd with count_only_confident).
  double max_fraction = 0.01;
  /// FitModel warns of every joint whose held-out coverage (FitCheck::coverage) is below this:
  /// its bands are too narrow on motion the model was not fitted on. In [0, 1].
  double min_coverage = 0.8;
  /// The held-out coverage FitCheck::latent_variance_scale is solved for, in (0, 1).
  double target_coverage = 0.95;
  /// Also hold out the fastest 1/folds of the rows (by |qd|) and predict them with the model
  /// fitted on the slower ones: motion faster than the model was fitted on, as a slow
  /// training log's model meets it. Its coverage is FitCheck::fastest_coverage, and the
  /// latent variance scale covers the target on these rows too. One more fit.
  bool fastest_rows_fold = true;

  /// True when the options are usable; otherwise false with the reason in *error (may be
  /// null).
  bool IsValid(std::string* error) const;
};

/// What the check found.
struct FitCheck {
  /// False when the check did not run (disabled, too few rows, not applicable).
  bool ran = false;
  /// True when no joint exceeds max_fraction (also when the check did not run).
  bool passed = true;
  /// Held-out rows predicted (each once).
  int rows = 0;
  /// The joint (1-based) with the largest fraction of counted (absurd, or confidently absurd
  /// with count_only_confident) predictions (0 when there is none), that fraction, the
  /// fraction of its held-out predictions that are confidently absurd, and its largest
  /// distance outside the training range in spans of the range.
  int worst_joint = 0;
  double worst_fraction = 0.0;
  double worst_confident_fraction = 0.0;
  double worst_excursion = 0.0;
  /// Per joint, the fraction of its held-out torques within 2 predictive (noisy) standard
  /// deviations of the held-out mean (size N when the check ran, else empty).
  Vector coverage;
  /// With FitCheckOptions::fastest_rows_fold: per joint, the coverage of the fastest rows'
  /// torques by the bands of the model fitted on the slower rows (size N when that fit
  /// succeeded, else empty; NaN for the joints the check did not count).
  Vector fastest_coverage;
  /// Per joint, the smallest factor kappa >= 1 on the latent (model) variance with which the
  /// band sqrt(kappa latent_var + noise_var) covers `FitCheckOptions::target_coverage` of the
  /// held-out torques, of the contiguous blocks and (fastest_rows_fold) of the fastest rows
  /// each: the larger of the two factors (1 when the bands already cover; at most
  /// kMaxLatentVarianceScale). Size N when the check ran, NaN for the joints it did not count.
  Vector latent_variance_scale;
  /// One line for a person.
  std::string message;
};

/// The largest FitCheck::latent_variance_scale.
inline constexpr double kMaxLatentVarianceScale = 1e6;

/// Per joint (column), the fraction of the measured torques within 2 standard deviations of the
/// noisy prediction, sqrt(latent_std^2 + noise_std_j^2), of the mean: about 95% when the bands
/// are calibrated. mean, latent_std and measured are m x N, noise_std N (RobotModel's
/// hyperparameters().noise_stds()). A row whose mean is not finite counts as outside; with no
/// rows every fraction is 0. Throws std::invalid_argument on mismatched sizes.
Vector BandCoverage(const ConstMatrixRef& mean, const ConstMatrixRef& latent_std,
                    const ConstVectorRef& noise_std, const ConstMatrixRef& measured);

/// Fits a fresh model of model's spec and options with hyper-parameters `hyper` on the rows
/// of X, Y outside each contiguous block (of the evenly spaced subset) and predicts the block.
/// X: the model's inputs (ModelInputs), Y: m x N torques. Throws std::invalid_argument on
/// invalid options or sizes. A fold whose fit fails numerically is skipped (said in the
/// message). only_joint (1-based): only that joint's predictions count (its verdict, its
/// coverage; the other entries of FitCheck::coverage are NaN), as when one joint's
/// hyper-parameters are chosen (FitOptions::per_joint); 0: every joint.
FitCheck CheckOnHeldOutBlocks(const RobotModel& model, const Hyperparameters& hyper,
                              const ConstMatrixRef& X, const ConstMatrixRef& Y,
                              const FitCheckOptions& options = FitCheckOptions(),
                              int only_joint = 0);

}  // namespace structgp

#endif  // STRUCTGP_FIT_FIT_CHECK_H_
