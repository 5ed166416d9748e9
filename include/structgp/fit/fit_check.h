#ifndef STRUCTGP_FIT_FIT_CHECK_H_
#define STRUCTGP_FIT_FIT_CHECK_H_

/// @file
/// A check of chosen hyper-parameters on held-out contiguous blocks of the training data: a
/// model with these hyper-parameters, fitted without one block, must not predict that block
/// far outside the range of the training torques while claiming to be sure of it.
///
/// A held-out prediction of joint j is *confidently absurd* when its mean lies more than
/// `range_margin` spans outside [min tau_j, max tau_j] (span = max - min over all rows given),
/// by more than `confidence_sigmas` of its predictive (noisy) standard deviation. A model that
/// does not know (a large variance off the training path) passes; a model whose hyper-
/// parameters let a flexible block swing, with a small variance, far from any torque the robot
/// produced, fails. This is the failure of an over-large gravity scale on a real log
/// (docs/real_data.md, UR10).
///
/// Cost: `folds` fits of the model on at most max_rows (1 - 1/folds) rows and predictions with
/// variance of the held-out rows.

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
  /// The check fails when more than this fraction of the held-out predictions of any joint
  /// are confidently absurd.
  double max_fraction = 0.01;

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
  /// The joint (1-based) with the largest fraction of confidently absurd predictions (0 when
  /// there is none), that fraction, and its largest distance outside the training range in
  /// spans of the range.
  int worst_joint = 0;
  double worst_fraction = 0.0;
  double worst_excursion = 0.0;
  /// One line for a person.
  std::string message;
};

/// Fits a fresh model of model's spec and options with hyper-parameters `hyper` on the rows
/// of X, Y outside each contiguous block (of the evenly spaced subset) and predicts the block.
/// X: the model's inputs (ModelInputs), Y: m x N torques. Throws std::invalid_argument on
/// invalid options or sizes. A fold whose fit fails numerically is skipped (said in the
/// message).
FitCheck CheckOnHeldOutBlocks(const RobotModel& model, const Hyperparameters& hyper,
                              const ConstMatrixRef& X, const ConstMatrixRef& Y,
                              const FitCheckOptions& options = FitCheckOptions());

}  // namespace structgp

#endif  // STRUCTGP_FIT_FIT_CHECK_H_
