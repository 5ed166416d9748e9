#ifndef STRUCTGP_ONLINE_REPLAY_H_
#define STRUCTGP_ONLINE_REPLAY_H_

/// @file
/// Replaying a log through the online learner as a control loop would run it: for each sample
/// in time order, predict its torques from its state with the model learned so far (the
/// one-step-ahead prediction), then learn the sample. The workflow of `structgp replay`.
///
/// The learner starts from a fitted RobotModel (its weight-space or regressor posterior) or,
/// for an unfitted one, from its prior at the given hyper-parameters. It runs without a thread
/// (OnlineLearner::ProcessPending after each Submit), so a replay is deterministic; each
/// step's predict and update are timed (steady_clock). A log of several trajectories (time
/// starting again: core/segments.h) is replayed segment after segment in file order; the
/// segments are reported, the learner carries on across them.

#include <memory>
#include <string>
#include <vector>

#include "structgp/core/hyperparameters.h"
#include "structgp/core/types.h"
#include "structgp/model/robot_model.h"
#include "structgp/online/online_learner.h"

namespace structgp {

struct ReplayOptions {
  /// Forgetting factor in (0, 1] per sample (OnlineLearnerOptions::forgetting).
  double forgetting = 1.0;
  /// Sliding window length, samples (0: none).
  int window_length = 0;
  /// Unfitted models only: the prior's hyper-parameters. Empty (no output scales): the
  /// model's DefaultHyperparameters of the torques of the first default_rows samples (what a
  /// controller knows when it starts).
  Hyperparameters hyperparameters;
  int default_rows = 1000;
  /// Accepted torque magnitude per joint (OnlineLearnerOptions::target_limit), or empty.
  /// Samples above it are counted as bad and not learned (their error is still reported).
  Vector target_limit;

  /// True when usable; otherwise false with a message naming the field in *error.
  bool IsValid(std::string* error) const;
};

struct ReplaySummary {
  /// Samples replayed (each predicted, then submitted).
  long steps = 0;
  /// Samples the learner refused (OnlineLearner::Submit, any reason) or could not absorb
  /// (update failures).
  long bad_samples = 0;
  /// First row of each trajectory (SegmentStarts of t).
  std::vector<int> segment_starts;
  /// One-step-ahead error tau - prediction, steps x N (NaN where the prediction failed).
  Matrix errors;
  /// Per step: update latency (Submit + ProcessPending) and predict latency, microseconds.
  Vector update_us, predict_us;
  double update_us_p50 = 0.0, update_us_p99 = 0.0;
  double predict_us_p50 = 0.0, predict_us_p99 = 0.0;
  /// Per joint RMS of the one-step-ahead error over the first and the last fifth of the steps
  /// (at least one step each).
  Vector rms_first_fifth, rms_last_fifth;
  /// The learner's counters at the end.
  OnlineLearnerSummary learner;
  /// "weight_space" or "regressor".
  std::string form;
  /// Features D or parameters P of the learner.
  int num_features = 0;
  /// The learned model: a RobotModel in the learner's final posterior (weight-space or
  /// regressor form) with the starting hyper-parameters, ready for SaveModel.
  std::shared_ptr<const RobotModel> model;

  /// A few lines for the terminal.
  std::string Report() const;
};

/// Replays X (m x model.input_dim(): states, and time when the model uses it), Y (m x N) and
/// times t (m, or empty) through an OnlineLearner started from `model`, and returns the
/// summary (with the learned model).
/// Throws std::invalid_argument on mismatched sizes, bad options, or a model that cannot run
/// online (function-space models: rbf, rbfs, pol wider than its explicit limit).
ReplaySummary Replay(const RobotModel& model, const ConstMatrixRef& X, const ConstMatrixRef& Y,
                     const ConstVectorRef& t, const ReplayOptions& options);

}  // namespace structgp

#endif  // STRUCTGP_ONLINE_REPLAY_H_
