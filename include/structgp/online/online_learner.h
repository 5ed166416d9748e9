#ifndef STRUCTGP_ONLINE_ONLINE_LEARNER_H_
#define STRUCTGP_ONLINE_ONLINE_LEARNER_H_

/// @file
/// Online learning of an inverse-dynamics model next to a hard real-time control loop: the
/// control thread predicts and submits samples, a learner thread updates the model, and the
/// two meet only through lock-free, wait-free structures.
///
///     control thread (e.g. 1 kHz)                 learner thread
///     ---------------------------                 --------------
///     Submit(x, tau) --> SPSC queue (fixed) -->   pop up to max_batch samples, their columns,
///                                                 WeightSpaceGP::UpdateBatch (forgetting;
///                                                 sliding window by removals)
///     Predict(x, mean [, variance]) <-- triple buffers <-- publish W (and S)
///
/// Two model forms, one learner. Feature form (feature_map): phi(x) (D) with one weight
/// vector per output, as WeightSpaceGP. Regressor form (regressor_map, the models rbd and lag):
/// tau = Psi(x) theta with Psi N x P, one theta for every joint, a prior mean mu and one noise
/// level sigma_j^2 per joint, as RegressorGP; a sample is N rank-one changes (the rows psi_j
/// weighted by sigma_n^2 / sigma_j^2) of one P x P factor. Both run the same queue, batching,
/// forgetting, window and publishing code (docs/online.md).
///
/// Control thread (one thread: the queue's producer and the buffers' reader). Submit and
/// Predict allocate nothing, take no lock, throw nothing, and run in bounded time:
/// - Submit validates the sample (sizes, NaN/Inf, the configured input and torque ranges);
///   a bad sample is counted by reason and never reaches the model. A good one is copied into
///   a boost::lockfree::spsc_queue of fixed capacity; when the queue is full the sample is
///   dropped and counted. O(input_dim + N).
/// - Predict evaluates phi(x) or Psi(x) (the map's cost, with the control thread's own
///   scratch) and returns the mean with the newest published weights, O(D P) or O(N P); with
///   the variance also the quadratic forms in the newest published factor S, O(D^2 / 2) or
///   O(N P^2 / 2) more.
///
/// What is published, and what it costs. W (D x P; theta, P x 1, in the regressor form) is
/// copied into a TripleBuffer after every publish_period-th update and whenever the queue runs
/// empty, so at control rates the mean uses every sample processed so far. The factor S (upper
/// triangle, D (D + 1) / 2 doubles: 1 MB at D = 512) goes through a second TripleBuffer every
/// covariance_publish_period-th update (0: never, no variance) and on WaitUntilIdle, so the
/// variance may lag the mean by that many updates. Memory: the model, three copies of W and,
/// with the variance, of S; with a window, the window's columns and one copy of the starting
/// model (for rebuilds).
///
/// Learner thread. Pops the samples waiting (at most max_batch), turns them into columns and
/// applies them, with the window's removals, in one WeightSpaceGP::UpdateBatch: one pass over
/// the factor for the whole burst instead of one per sample, so a learner that falls behind
/// catches up faster. Forgetting multiplies the precision by forgetting once per sample. With
/// window_length = L > 0 the model holds the newest L samples only: after adding sample n it
/// removes sample n - L, with the weight forgetting has left it (forgetting^L). A removal can
/// be refused (kNotPositiveDefinite: the rest of the window does not determine the posterior
/// well enough in the leaving sample's direction, typical with strong forgetting); the
/// WindowFailurePolicy decides then. The learner allocates nothing after construction and
/// sleeps for idle_sleep when the queue is empty (it is not a real-time thread).
///
/// Exactness. With max_batch = 1 the learner's model is bit for bit the model a
/// single-threaded WeightSpaceGP builds with the same Update and Downdate calls (in the
/// regressor form, one call per joint row), and Predict after WaitUntilIdle returns exactly
/// its Predict. With max_batch > 1 it equals that model to rounding (UpdateBatch), and either
/// way the batch posterior of the samples (WeightSpaceGP::Fit, RegressorGP::Fit) to the
/// rounding of the updates; the tests check all three.
///
/// Threads: Submit, Predict, PredictWithVariance and last_prediction_version are for the one
/// control thread. summary() may be called from any thread. WaitUntilIdle, Stop and the
/// destructor from the control thread or a supervisor (not concurrently with each other).
/// With start_thread = false there is no learner thread: the caller runs the learner's work
/// with ProcessPending (deterministic, e.g. for simulation and replays).

#include <atomic>
#include <chrono>
#include <memory>
#include <string>

#include "structgp/core/status.h"
#include "structgp/core/types.h"
#include "structgp/feature/feature_map.h"
#include "structgp/feature/regressor_map.h"
#include "structgp/model/regressor_gp.h"
#include "structgp/model/robot_model.h"
#include "structgp/model/weight_space_gp.h"

namespace structgp {

/// Outcome of OnlineLearner::Submit.
enum class SubmitResult {
  kAccepted = 0,
  /// x or tau has the wrong number of entries.
  kRejectedSize,
  /// x or tau contains NaN or Inf.
  kRejectedNonFinite,
  /// x outside [input_lower, input_upper], or |tau_j| > target_limit_j.
  kRejectedOutOfRange,
  /// A valid sample that found the queue full; it is lost.
  kDroppedQueueFull,
};

/// Stable name ("accepted", "rejected_size", ...), for logs and files.
const char* ToString(SubmitResult result);

/// What the learner does when the sample leaving the sliding window cannot be removed
/// (WeightSpaceGP::Downdate returns kNotPositiveDefinite).
enum class WindowFailurePolicy {
  /// Rebuild the posterior from the samples now in the window: the prior model, then Update
  /// for each window sample in order (with the forgetting factor), O(L D^2) on the learner
  /// thread (at D = 138, L = 1000 roughly 5-10 ms). The result is the window posterior with the
  /// prior broadened by forgetting^-L only (a downdated model carries the broadening of every
  /// sample it has seen). Allocation-free.
  kRebuild,
  /// Keep the sample in the model for good (it is never removed; the model then holds more
  /// than L samples). Counted in downdate_failures. Cheapest, and harmless when it is rare.
  kKeepSample,
};

struct OnlineLearnerOptions {
  /// The model: exactly one of feature_map (feature form) and regressor_map (regressor form).
  /// Its Evaluate is called on both threads concurrently, each with its own scratch: it must
  /// be thread-safe and allocation-free (FeatureMap's and RegressorMap's contracts).
  std::shared_ptr<const FeatureMap> feature_map;
  std::shared_ptr<const RegressorMap> regressor_map;
  /// Number of outputs P (joint torques), >= 1; in the regressor form 0 or the map's N.
  int num_outputs = 0;
  /// Prior variances Lambda (D features or P parameters, all > 0). Empty: the feature map's
  /// PriorVariance at its default shape parameters, or the regressor map's prior_std()^2.
  Vector prior_variance;
  /// Regressor form: prior mean mu (P). Empty: the map's prior_mean(). Must be empty in the
  /// feature form.
  Vector prior_mean;
  /// Noise variance sigma_n^2 > 0, in units of s_j^2: output j's noise variance is
  /// sigma_n^2 s_j^2 (in both forms, as in GaussianProcess).
  double noise_variance = 0.01;
  /// Output scales s_j (size P, all > 0); empty: all 1.
  Vector output_scales;
  /// Factor kappa_j on output j's latent variance in PredictWithVariance (size P, all > 0;
  /// RobotModel::latent_variance_scale, the fit's band calibration); empty: all 1.
  Vector latent_variance_scale;
  /// Start from a posterior instead of the prior. Feature form: initial_model (D features,
  /// P outputs; its prior, noise and scales replace the three fields above). Regressor form:
  /// initial_regressor, fitted (its prior mean, prior variance and noise levels replace
  /// prior_mean, prior_variance, noise_variance and output_scales; the learner continues
  /// from its statistics). Null: start at the prior.
  std::shared_ptr<const WeightSpaceGP> initial_model;
  std::shared_ptr<const RegressorGP> initial_regressor;
  /// Forgetting factor lambda in (0, 1]: A <- lambda A + phi phi^T at each update. 1 keeps
  /// everything; 1 - 1/T gives a memory of about T samples.
  double forgetting = 1.0;
  /// Sliding window length L >= 0 (samples); 0: no window (samples stay until forgotten).
  int window_length = 0;
  WindowFailurePolicy window_failure_policy = WindowFailurePolicy::kRebuild;
  /// Accepted input range, per input entry (size input_dim each; -inf / +inf allowed), or
  /// empty for no bound. Samples outside are rejected (kRejectedOutOfRange). Predict does not
  /// check the range.
  Vector input_lower;
  Vector input_upper;
  /// Largest accepted |tau_j| (size P, > 0; +inf allowed), or empty for no bound.
  Vector target_limit;
  /// Queue capacity, in samples (>= 1). At 1 kHz, 1024 samples bridge a 1 s learner stall.
  int queue_capacity = 1024;
  /// Most samples the learner applies in one pass over the factor (>= 1). 1: one Update per
  /// sample (bit-identical to single calls); more: bursts go through UpdateBatch.
  int max_batch = 16;
  /// Publish W after every publish_period-th update (>= 1), and whenever the queue runs empty.
  int publish_period = 1;
  /// Publish S after every covariance_publish_period-th update; 0 disables the variance
  /// (PredictWithVariance then returns kInvalidInput) and saves the three copies of S.
  int covariance_publish_period = 0;
  /// Start the learner thread in the constructor. false: call ProcessPending yourself.
  bool start_thread = true;
  /// How long the learner thread sleeps when it finds the queue empty.
  std::chrono::microseconds idle_sleep{100};

  /// True when the options can be used; otherwise false with a message in *error (which may be
  /// null) naming the field, what was expected and what was found.
  bool IsValid(std::string* error) const;
};

/// Options of a learner that starts from the prior of a fitted RobotModel: its feature map,
/// with the prior variances, noise level and output scales of the model's hyper-parameters
/// and its latent variance scale,
/// learning from no data (the model's form, learned again online). Every other option at its
/// default. Throws std::invalid_argument when the model is not fitted or has no feature map
/// (rbf, rbfs, rbd, lag, pol beyond its explicit map).
OnlineLearnerOptions OnlineLearnerOptionsFor(const RobotModel& model);

/// Counters of an OnlineLearner. Each field is exact; fields written by different threads are
/// read one by one, so a summary taken while the learner runs is a near-simultaneous sample.
struct OnlineLearnerSummary {
  // Control thread.
  long submitted = 0;              ///< calls to Submit
  long accepted = 0;               ///< pushed into the queue
  long rejected_size = 0;          ///< SubmitResult::kRejectedSize
  long rejected_non_finite = 0;    ///< SubmitResult::kRejectedNonFinite
  long rejected_out_of_range = 0;  ///< SubmitResult::kRejectedOutOfRange
  long dropped_queue_full = 0;     ///< SubmitResult::kDroppedQueueFull
  long predictions = 0;            ///< successful Predict / PredictWithVariance calls
  long prediction_failures = 0;    ///< Predict calls that returned a status other than kOk
  // Learner.
  long processed = 0;             ///< samples popped from the queue
  long updates = 0;               ///< successful WeightSpaceGP::Update calls
  long update_failures = 0;       ///< Update calls that failed (sample not absorbed)
  long downdates = 0;             ///< samples removed from the window
  long downdate_failures = 0;     ///< removals refused (then the WindowFailurePolicy)
  long rebuilds = 0;              ///< window rebuilds (WindowFailurePolicy::kRebuild)
  long batches = 0;               ///< passes over the factor (UpdateBatch calls or single steps)
  long weight_publishes = 0;      ///< W published
  long covariance_publishes = 0;  ///< S published
  long samples_in_model = 0;      ///< samples in the model after the last update
  bool learner_failed = false;    ///< the learner thread stopped on an unexpected exception

  /// Samples rejected for any reason.
  long rejected() const { return rejected_size + rejected_non_finite + rejected_out_of_range; }
  /// update_failures + downdate_failures.
  long status_failures() const { return update_failures + downdate_failures; }
  /// A few lines for logs.
  std::string Report() const;
};

class OnlineLearner {
 public:
  /// Validates the options (std::invalid_argument with IsValid's message otherwise), builds
  /// the model at its prior, allocates every buffer, publishes the prior, and starts the
  /// learner thread when options.start_thread.
  explicit OnlineLearner(const OnlineLearnerOptions& options);
  /// Stops the learner thread (samples still queued are not processed).
  ~OnlineLearner();

  OnlineLearner(const OnlineLearner&) = delete;
  OnlineLearner& operator=(const OnlineLearner&) = delete;

  const OnlineLearnerOptions& options() const;
  int input_dim() const;
  /// D features (feature form) or P parameters (regressor form).
  int num_features() const;
  /// Torques per sample.
  int num_outputs() const;
  bool regressor_form() const { return options().regressor_map != nullptr; }
  bool has_variance() const { return options().covariance_publish_period > 0; }

  // ---- control thread: real-time ------------------------------------------------------------

  /// Validates (x, tau) (x: input_dim entries, tau: num_outputs) and queues it for the
  /// learner. Allocation-free, lock-free, never throws, O(input_dim + num_outputs).
  SubmitResult Submit(const ConstVectorRef& x, const ConstVectorRef& tau) noexcept;

  /// Predictive mean (num_outputs) at x with the newest published weights. kInvalidInput
  /// (nothing written) on a wrong size or NaN/Inf in x. Allocation-free, lock-free, never
  /// throws; cost: one map evaluation + O(D P) (regressor: O(N P)).
  Status Predict(const ConstVectorRef& x, VectorRef mean) noexcept;
  /// Mean and latent variance (each num_outputs): s_j^2 sigma_n^2 phi^T A^{-1} phi, or
  /// psi_j Cov(theta) psi_j^T in the regressor form, with the newest published factor (which
  /// may be older than the weights by up to covariance_publish_period - 1 updates). Add the
  /// output's noise variance for that of a noisy observation. kInvalidInput without variance
  /// (covariance_publish_period = 0) or on bad input. Cost: one map evaluation +
  /// O(D P + D^2 / 2) (regressor: O(N P^2 / 2)).
  Status PredictWithVariance(const ConstVectorRef& x, VectorRef mean,
                             VectorRef latent_variance) noexcept;

  /// Number of updates behind the weights used by the last Predict (0 before any update).
  long last_prediction_version() const;

  // ---- learner side and supervision (not real-time) --------------------------------------------

  /// Without a learner thread (start_thread = false): processes every queued sample on the
  /// calling thread, then publishes W (and S when publish-worthy as with the thread). Returns
  /// the number of samples processed. Throws std::logic_error when a learner thread runs.
  int ProcessPending();

  /// Waits until every sample accepted before the call has been processed and W and S (with
  /// variance) of the result are published, or until timeout. Returns true when idle. Without
  /// a learner thread it runs ProcessPending and publishes itself.
  bool WaitUntilIdle(std::chrono::milliseconds timeout = std::chrono::milliseconds(10000));

  /// Stops the learner thread (idempotent). Queued samples stay queued.
  void Stop();

  /// Counters (any thread).
  OnlineLearnerSummary summary() const;

  /// The learner's model. Only valid while the learner is not working: with start_thread =
  /// false, after Stop(), or after WaitUntilIdle returned true and no Submit since. In the
  /// regressor form it is the posterior of theta - mu: P features, one output, the joint rows
  /// as samples weighted sigma_n^2 / sigma_j^2.
  const WeightSpaceGP& model() const;

  /// Regressor form: the posterior as a fitted RegressorGP, from the statistics of the samples
  /// in the model (forgotten and removed as the model's) with the prior broadened by
  /// forgetting (model().effective_prior_variance()); the same posterior to rounding.
  /// Allocates, O(N P^2 + P^3). Valid when model() is; throws std::logic_error in the feature
  /// form or when the fit fails.
  RegressorGP regressor_model() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace structgp

#endif  // STRUCTGP_ONLINE_ONLINE_LEARNER_H_
