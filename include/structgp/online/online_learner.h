#ifndef STRUCTGP_ONLINE_ONLINE_LEARNER_H_
#define STRUCTGP_ONLINE_ONLINE_LEARNER_H_

/// @file
/// Online learning of an inverse-dynamics model next to a hard real-time control loop: the
/// control thread predicts and submits samples, a learner thread updates the model, and the
/// two meet only through lock-free, wait-free structures.
///
///     control thread (e.g. 1 kHz)                 learner thread
///     ---------------------------                 --------------
///     Submit(x, tau) --> SPSC queue (fixed) -->   pop, phi(x), WeightSpaceGP::Update
///                                                 (forgetting; sliding window by Downdate)
///     Predict(x, mean [, variance]) <-- triple buffers <-- publish W (and S)
///
/// Control thread (one thread: the queue's producer and the buffers' reader). Submit and
/// Predict allocate nothing, take no lock, throw nothing, and run in bounded time:
/// - Submit validates the sample (sizes, NaN/Inf, the configured input and torque ranges);
///   a bad sample is counted by reason and never reaches the model. A good one is copied into
///   a boost::lockfree::spsc_queue of fixed capacity; when the queue is full the sample is
///   dropped and counted. O(input_dim + P).
/// - Predict evaluates phi(x) (the feature map's cost) and returns W^T phi with the newest
///   published weights W, O(D P); with the variance also s_j^2 sigma_n^2 ||S^T phi||^2 with the
///   newest published factor S, O(D^2 / 2) more.
///
/// What is published, and what it costs. The learner owns the model; the control thread reads
/// copies. W (D x P) is copied into a TripleBuffer after every publish_period-th update and
/// whenever the queue runs empty, so at control rates the mean always uses every sample
/// processed so far: the copy is D P doubles (57 KB at D = 1024, P = 7), a few microseconds.
/// The factor S (upper triangle of D x D) is needed only for the variance and is large
/// (D (D + 1) / 2 doubles: 1 MB at D = 512, 4 MB at D = 1024), so it goes through a second
/// TripleBuffer every covariance_publish_period-th update (0: never, no variance) and on
/// WaitUntilIdle. The variance therefore lags the mean by up to that many updates; it is a
/// confidence measure, and at one publish per 10-100 updates the copy adds only a few percent
/// to the learner's work. Memory: the model's S and W, three copies of W, and, with the
/// variance, three copies of S; with a window, the window's features and targets (W_len x D
/// and W_len x P) and one copy of the prior model (for rebuilds).
///
/// Learner thread. Pops samples, evaluates phi, and calls WeightSpaceGP::Update with the
/// configured forgetting factor. With window_length = L > 0 the model holds the newest L
/// samples only: after adding sample n it removes sample n - L by Downdate, with the weight
/// forgetting has left it (forgetting^L). A removal can be refused (kNotPositiveDefinite: the
/// rest of the window does not determine the posterior well enough in the leaving sample's
/// direction — typical with strong forgetting, whose prior precision decays too); the
/// WindowFailurePolicy decides what happens then. The learner allocates nothing either after
/// construction. It sleeps for idle_sleep when the queue is empty (it is not a real-time
/// thread and should run at a lower priority than the control thread).
///
/// Exactness. For the same samples in the same order, the learner's model is bit-for-bit the
/// model a single-threaded WeightSpaceGP builds with the same Update calls, and Predict after
/// WaitUntilIdle returns exactly its Predict (the tests check this).
///
/// Threads: Submit, Predict, PredictWithVariance and last_prediction_version are for the one
/// control thread. summary() may be called from any thread. WaitUntilIdle, Stop and the
/// destructor from the control thread or a supervisor (not concurrently with each other).
/// With start_thread = false there is no learner thread: the caller runs the learner's work
/// with ProcessPending (deterministic, e.g. for simulation).

#include <atomic>
#include <chrono>
#include <memory>
#include <string>

#include "structgp/core/status.h"
#include "structgp/core/types.h"
#include "structgp/feature/feature_map.h"
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
  /// The feature map phi (required). Its Evaluate is called on both threads concurrently: it
  /// must be thread-safe and allocation-free (FeatureMap's contract).
  std::shared_ptr<const FeatureMap> feature_map;
  /// Number of outputs P (joint torques), >= 1.
  int num_outputs = 0;
  /// Prior variances Lambda (size D, all > 0). Empty: the map's PriorVariance at its default
  /// shape parameters.
  Vector prior_variance;
  /// Noise variance sigma_n^2 > 0, in units of s_j^2 (see WeightSpaceGP).
  double noise_variance = 0.01;
  /// Output scales s_j (size P, all > 0); empty: all 1.
  Vector output_scales;
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
/// with the prior variances, noise level and output scales of the model's hyper-parameters,
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
  long weight_publishes = 0;      ///< W published
  long covariance_publishes = 0;  ///< S published
  long samples_in_model = 0;      ///< WeightSpaceGP::num_samples() after the last update
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
  int num_features() const;
  int num_outputs() const;
  bool has_variance() const { return options().covariance_publish_period > 0; }

  // ---- control thread: real-time ------------------------------------------------------------

  /// Validates (x, tau) (x: input_dim entries, tau: P) and queues it for the learner.
  /// Allocation-free, lock-free, never throws, O(input_dim + P).
  SubmitResult Submit(const ConstVectorRef& x, const ConstVectorRef& tau) noexcept;

  /// Predictive mean (size P) at x with the newest published weights. kInvalidInput (nothing
  /// written) on a wrong size or NaN/Inf in x. Allocation-free, lock-free, never throws;
  /// cost: one feature evaluation + O(D P).
  Status Predict(const ConstVectorRef& x, VectorRef mean) noexcept;
  /// Mean and latent variance s_j^2 sigma_n^2 phi^T A^{-1} phi (each size P), the variance with
  /// the newest published factor (which may be older than the weights by up to
  /// covariance_publish_period - 1 updates). Add s_j^2 sigma_n^2 for the variance of a noisy
  /// observation. kInvalidInput without variance (covariance_publish_period = 0) or on bad
  /// input. Cost: one feature evaluation + O(D P + D^2 / 2).
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
  /// false, after Stop(), or after WaitUntilIdle returned true and no Submit since.
  const WeightSpaceGP& model() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace structgp

#endif  // STRUCTGP_ONLINE_ONLINE_LEARNER_H_
