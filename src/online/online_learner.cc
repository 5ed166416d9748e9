#include "structgp/online/online_learner.h"

#include <boost/lockfree/spsc_queue.hpp>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <thread>
#include <utility>

#include "model/factor_kernels.h"
#include "structgp/feature/feature_hyperparameters.h"
#include "structgp/model/model_spec.h"
#include "structgp/online/triple_buffer.h"

namespace structgp {
namespace {

// Smallest weight forgetting^window_length that a sample may have when it leaves the window.
// Below it the removal is a no-op to rounding (the sample has long been forgotten) and the
// window only costs memory: such options are refused.
constexpr double kMinWindowExitWeight = 1e-12;

// How often WaitUntilIdle looks at the learner's acknowledgement.
constexpr std::chrono::microseconds kWaitPollInterval{50};

// A counter written by one thread and read by others: no read-modify-write instruction needed.
inline void Bump(std::atomic<long>& counter) {
  counter.store(counter.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
}

struct WeightsSnapshot {
  Matrix weights;    // D x P
  long version = 0;  // updates behind these weights
};

struct FactorSnapshot {
  Matrix factor;  // D x D, upper triangle valid (strictly lower part zero)
  long version = 0;
};

bool Fail(std::string* error, const std::string& message) {
  if (error != nullptr) *error = "OnlineLearnerOptions: " + message;
  return false;
}

std::string Sizes(const char* what, Eigen::Index got, Eigen::Index expected) {
  std::ostringstream os;
  os << what << ": expected " << expected << " entries, got " << got;
  return os.str();
}

}  // namespace

const char* ToString(SubmitResult result) {
  switch (result) {
    case SubmitResult::kAccepted:
      return "accepted";
    case SubmitResult::kRejectedSize:
      return "rejected_size";
    case SubmitResult::kRejectedNonFinite:
      return "rejected_non_finite";
    case SubmitResult::kRejectedOutOfRange:
      return "rejected_out_of_range";
    case SubmitResult::kDroppedQueueFull:
      return "dropped_queue_full";
  }
  return "unknown";
}

bool OnlineLearnerOptions::IsValid(std::string* error) const {
  if (feature_map == nullptr) return Fail(error, "feature_map is null (a feature map is required)");
  const int D = feature_map->dim();
  const int n_in = feature_map->input_dim();
  if (num_outputs < 1) {
    return Fail(error, "num_outputs: expected at least 1, got " + std::to_string(num_outputs));
  }
  if (prior_variance.size() != 0) {
    if (prior_variance.size() != D) {
      return Fail(error,
                  Sizes("prior_variance (one per feature, or empty)", prior_variance.size(), D));
    }
    if (!prior_variance.allFinite() || (prior_variance.array() <= 0.0).any()) {
      return Fail(error, "prior_variance: every entry must be finite and > 0");
    }
  }
  if (!(noise_variance > 0.0 && std::isfinite(noise_variance))) {
    return Fail(error, "noise_variance: expected a finite value > 0, got " +
                           std::to_string(noise_variance));
  }
  if (output_scales.size() != 0) {
    if (output_scales.size() != num_outputs) {
      return Fail(error, Sizes("output_scales (one per output, or empty)", output_scales.size(),
                               num_outputs));
    }
    if (!output_scales.allFinite() || (output_scales.array() <= 0.0).any()) {
      return Fail(error, "output_scales: every entry must be finite and > 0");
    }
  }
  if (!(forgetting > 0.0 && forgetting <= 1.0)) {
    return Fail(error, "forgetting: expected a value in (0, 1], got " + std::to_string(forgetting));
  }
  if (window_length < 0) {
    return Fail(
        error, "window_length: expected >= 0 (0: no window), got " + std::to_string(window_length));
  }
  if (window_length > 0 && std::pow(forgetting, window_length) < kMinWindowExitWeight) {
    return Fail(
        error, "forgetting^window_length = " + std::to_string(std::pow(forgetting, window_length)) +
                   " is below 1e-12: samples are forgotten long before they leave the "
                   "window; use a shorter window or forgetting closer to 1");
  }
  if (input_lower.size() != 0 && input_lower.size() != n_in) {
    return Fail(error, Sizes("input_lower (one per input, or empty)", input_lower.size(), n_in));
  }
  if (input_upper.size() != 0 && input_upper.size() != n_in) {
    return Fail(error, Sizes("input_upper (one per input, or empty)", input_upper.size(), n_in));
  }
  if (input_lower.hasNaN() || input_upper.hasNaN()) {
    return Fail(error, "input_lower / input_upper contain NaN (use -inf / +inf for no bound)");
  }
  if (input_lower.size() != 0 && input_upper.size() != 0 &&
      (input_lower.array() > input_upper.array()).any()) {
    return Fail(error, "input_lower exceeds input_upper for some input");
  }
  if (target_limit.size() != 0) {
    if (target_limit.size() != num_outputs) {
      return Fail(error, Sizes("target_limit (one per output, or empty)", target_limit.size(),
                               num_outputs));
    }
    if (target_limit.hasNaN() || (target_limit.array() <= 0.0).any()) {
      return Fail(error, "target_limit: every entry must be > 0 (+inf for no bound)");
    }
  }
  if (queue_capacity < 1) {
    return Fail(
        error, "queue_capacity: expected at least 1 sample, got " + std::to_string(queue_capacity));
  }
  if (publish_period < 1) {
    return Fail(error,
                "publish_period: expected at least 1, got " + std::to_string(publish_period));
  }
  if (covariance_publish_period < 0) {
    return Fail(error, "covariance_publish_period: expected >= 0 (0: no variance), got " +
                           std::to_string(covariance_publish_period));
  }
  if (idle_sleep.count() < 0) return Fail(error, "idle_sleep must not be negative");
  return true;
}

std::string OnlineLearnerSummary::Report() const {
  std::ostringstream os;
  os << "submitted " << submitted << ": accepted " << accepted << ", rejected " << rejected()
     << " (size " << rejected_size << ", non-finite " << rejected_non_finite << ", out of range "
     << rejected_out_of_range << "), dropped (queue full) " << dropped_queue_full << "\n"
     << "learner: processed " << processed << ", updates " << updates << " (failed "
     << update_failures << "), downdates " << downdates << " (refused " << downdate_failures
     << ", rebuilds " << rebuilds << "), samples in model " << samples_in_model << "\n"
     << "published: weights " << weight_publishes << ", covariance " << covariance_publishes
     << "; predictions " << predictions << " (failed " << prediction_failures << ")"
     << (learner_failed ? "; LEARNER FAILED" : "") << "\n";
  return os.str();
}

// -------------------------------------------------------------------------------------------

struct OnlineLearner::Impl {
  explicit Impl(const OnlineLearnerOptions& opts);

  static Vector PriorVarianceOf(const OnlineLearnerOptions& opts);

  // Learner side.
  void Run();
  // Processes every queued sample (stops early when `stoppable` and Stop was called), then
  // publishes W if it changed. Returns the number of samples processed.
  int Drain(bool stoppable);
  void ProcessSample();
  void AddToWindow();
  void Rebuild();
  void PublishWeights();
  void PublishFactor();
  void ServiceFlush();
  void PublishAll();

  OnlineLearnerOptions options;
  int input_dim;
  int D;
  int P;
  int record;  // doubles per queued sample: input_dim + P

  WeightSpaceGP model;
  std::unique_ptr<WeightSpaceGP> prior_model;  // window rebuilds only

  boost::lockfree::spsc_queue<double> queue;
  TripleBuffer<WeightsSnapshot> weights_buffer;
  std::unique_ptr<TripleBuffer<FactorSnapshot>> factor_buffer;

  // Control thread: sigma_n^2 s_j^2 (P), copied so that the control thread never reads the
  // learner's model; scratch.
  Vector variance_scale;
  Vector control_phi;
  Vector control_f;
  long last_version = 0;

  // Learner scratch and state.
  Vector learner_record;
  Vector learner_phi;
  Matrix window_phi;  // D x L, ring buffer (column = sample)
  Matrix window_y;    // P x L
  int window_count = 0;
  int window_head = 0;  // oldest sample when full; next slot to write
  double window_exit_weight = 1.0;
  long learner_updates = 0;
  int since_weights = 0;
  int since_factor = 0;
  bool weights_dirty = false;
  bool factor_dirty = false;

  // Counters.
  std::atomic<long> submitted{0}, accepted{0}, rejected_size{0}, rejected_non_finite{0},
      rejected_out_of_range{0}, dropped{0}, predictions{0}, prediction_failures{0};
  std::atomic<long> processed{0}, updates{0}, update_failures{0}, downdates{0},
      downdate_failures{0}, rebuilds{0}, weight_publishes{0}, factor_publishes{0},
      samples_in_model{0};
  std::atomic<bool> learner_failed{false};

  // WaitUntilIdle handshake: requests by the supervisor, acknowledgements by the learner.
  std::atomic<long> flush_requested{0};
  std::atomic<long> flush_done{0};

  std::atomic<bool> stop{false};
  std::thread thread;
};

Vector OnlineLearner::Impl::PriorVarianceOf(const OnlineLearnerOptions& opts) {
  if (opts.prior_variance.size() != 0) return opts.prior_variance;
  Vector lambda(opts.feature_map->dim());
  opts.feature_map->PriorVariance(opts.feature_map->default_shape_parameters(), lambda);
  return lambda;
}

OnlineLearner::Impl::Impl(const OnlineLearnerOptions& opts)
    : options(opts),
      input_dim(opts.feature_map->input_dim()),
      D(opts.feature_map->dim()),
      P(opts.num_outputs),
      record(input_dim + P),
      model(PriorVarianceOf(opts), opts.noise_variance, opts.num_outputs, opts.output_scales),
      queue(static_cast<std::size_t>(opts.queue_capacity) * static_cast<std::size_t>(record)),
      weights_buffer(WeightsSnapshot{model.weights(), 0}) {
  if (options.covariance_publish_period > 0) {
    factor_buffer = std::make_unique<TripleBuffer<FactorSnapshot>>(
        FactorSnapshot{model.covariance_factor(), 0});
  }
  if (options.window_length > 0) {
    prior_model = std::make_unique<WeightSpaceGP>(model);
    window_phi.setZero(D, options.window_length);
    window_y.setZero(P, options.window_length);
    window_exit_weight = std::pow(options.forgetting, options.window_length);
  }
  variance_scale = model.noise_variance() * model.output_scales().cwiseAbs2();
  control_phi.setZero(D);
  control_f.setZero(D);
  learner_record.setZero(record);
  learner_phi.setZero(D);
}

void OnlineLearner::Impl::PublishWeights() {
  WeightsSnapshot& slot = weights_buffer.write_buffer();
  slot.weights = model.weights();  // same size: no allocation
  slot.version = learner_updates;
  weights_buffer.Publish();
  Bump(weight_publishes);
  since_weights = 0;
  weights_dirty = false;
}

void OnlineLearner::Impl::PublishFactor() {
  FactorSnapshot& slot = factor_buffer->write_buffer();
  const Matrix& S = model.covariance_factor();
  // Upper triangle only (half the bytes); the slot's strictly lower part stays zero.
  for (int j = 0; j < D; ++j) slot.factor.col(j).head(j + 1) = S.col(j).head(j + 1);
  slot.version = learner_updates;
  factor_buffer->Publish();
  Bump(factor_publishes);
  since_factor = 0;
  factor_dirty = false;
}

void OnlineLearner::Impl::PublishAll() {
  if (weights_dirty) PublishWeights();
  if (factor_buffer != nullptr && factor_dirty) PublishFactor();
}

void OnlineLearner::Impl::Rebuild() {
  model = *prior_model;  // equal sizes: copy assignment does not allocate
  const int L = options.window_length;
  for (int k = 0; k < window_count; ++k) {
    const int slot = (window_head + k) % L;
    if (model.Update(window_phi.col(slot), window_y.col(slot), options.forgetting) != Status::kOk) {
      Bump(update_failures);
    }
  }
  Bump(rebuilds);
}

void OnlineLearner::Impl::AddToWindow() {
  const int L = options.window_length;
  const auto y = learner_record.tail(P);
  if (window_count < L) {
    const int slot = (window_head + window_count) % L;
    window_phi.col(slot) = learner_phi;
    window_y.col(slot) = y;
    ++window_count;
    return;
  }
  // Full: the sample at window_head leaves. It was added L updates ago, so forgetting has left
  // it the weight forgetting^L.
  const Status status =
      model.Downdate(window_phi.col(window_head), window_y.col(window_head), window_exit_weight);
  window_phi.col(window_head) = learner_phi;
  window_y.col(window_head) = y;
  window_head = (window_head + 1) % L;
  if (status == Status::kOk) {
    Bump(downdates);
    return;
  }
  Bump(downdate_failures);
  if (options.window_failure_policy == WindowFailurePolicy::kRebuild) Rebuild();
}

void OnlineLearner::Impl::ProcessSample() {
  Bump(processed);
  const auto x = learner_record.head(input_dim);
  const auto y = learner_record.tail(P);
  options.feature_map->Evaluate(x, learner_phi);
  if (model.Update(learner_phi, y, options.forgetting) != Status::kOk) {
    Bump(update_failures);
    return;
  }
  ++learner_updates;
  Bump(updates);
  if (options.window_length > 0) AddToWindow();
  samples_in_model.store(model.num_samples(), std::memory_order_relaxed);
  weights_dirty = true;
  factor_dirty = true;
  if (++since_weights >= options.publish_period) PublishWeights();
  if (factor_buffer != nullptr && ++since_factor >= options.covariance_publish_period) {
    PublishFactor();
  }
}

int OnlineLearner::Impl::Drain(bool stoppable) {
  int n = 0;
  while (queue.read_available() >= static_cast<std::size_t>(record)) {
    queue.pop(learner_record.data(), static_cast<std::size_t>(record));
    ProcessSample();
    ++n;
    if (stoppable && stop.load(std::memory_order_relaxed)) break;
  }
  // The queue ran empty: the control thread gets every sample processed so far.
  if (weights_dirty) PublishWeights();
  return n;
}

void OnlineLearner::Impl::ServiceFlush() {
  const long request = flush_requested.load(std::memory_order_acquire);
  if (request == flush_done.load(std::memory_order_relaxed)) return;
  // Every sample accepted before the request is visible in the queue now (the request was
  // stored after the push and loaded with acquire): acknowledge only once they are processed.
  if (queue.read_available() >= static_cast<std::size_t>(record)) return;
  PublishAll();
  flush_done.store(request, std::memory_order_release);
}

void OnlineLearner::Impl::Run() {
  try {
    while (!stop.load(std::memory_order_acquire)) {
      if (Drain(/*stoppable=*/true) == 0) {
        ServiceFlush();
        std::this_thread::sleep_for(options.idle_sleep);
      }
    }
  } catch (...) {
    // Nothing on the learner's path throws for validated samples; if something does, the
    // learner stops instead of terminating the process, and says so in the summary.
    learner_failed.store(true, std::memory_order_release);
  }
}

// -------------------------------------------------------------------------------------------

namespace {
const OnlineLearnerOptions& Validated(const OnlineLearnerOptions& options) {
  std::string error;
  if (!options.IsValid(&error)) throw std::invalid_argument(error);
  return options;
}
}  // namespace

OnlineLearnerOptions OnlineLearnerOptionsFor(const RobotModel& model) {
  if (!model.fitted() || model.feature_map() == nullptr) {
    throw std::invalid_argument(
        "OnlineLearnerOptionsFor: needs a fitted model with a feature map (pol up to 3 joints, "
        "motor); " + ModelLabel(model.spec()) + (model.fitted() ? " has none" : " is not fitted"));
  }
  const Hyperparameters& h = model.hyperparameters();
  OnlineLearnerOptions o;
  o.feature_map = model.feature_map();
  o.num_outputs = model.num_joints();
  o.prior_variance = PriorVariance(*model.feature_map(), h);
  o.noise_variance = h.noise_variance();
  o.output_scales = h.output_scales();
  return o;
}

OnlineLearner::OnlineLearner(const OnlineLearnerOptions& options)
    : impl_(std::make_unique<Impl>(Validated(options))) {
  if (options.start_thread) impl_->thread = std::thread([this]() { impl_->Run(); });
}

OnlineLearner::~OnlineLearner() { Stop(); }

const OnlineLearnerOptions& OnlineLearner::options() const { return impl_->options; }
int OnlineLearner::input_dim() const { return impl_->input_dim; }
int OnlineLearner::num_features() const { return impl_->D; }
int OnlineLearner::num_outputs() const { return impl_->P; }

SubmitResult OnlineLearner::Submit(const ConstVectorRef& x, const ConstVectorRef& tau) noexcept {
  Impl& s = *impl_;
  Bump(s.submitted);
  if (x.size() != s.input_dim || tau.size() != s.P) {
    Bump(s.rejected_size);
    return SubmitResult::kRejectedSize;
  }
  if (!x.allFinite() || !tau.allFinite()) {
    Bump(s.rejected_non_finite);
    return SubmitResult::kRejectedNonFinite;
  }
  const OnlineLearnerOptions& o = s.options;
  if ((o.input_lower.size() != 0 && (x.array() < o.input_lower.array()).any()) ||
      (o.input_upper.size() != 0 && (x.array() > o.input_upper.array()).any()) ||
      (o.target_limit.size() != 0 && (tau.array().abs() > o.target_limit.array()).any())) {
    Bump(s.rejected_out_of_range);
    return SubmitResult::kRejectedOutOfRange;
  }
  // Only this thread pushes, so the free space can only grow between the check and the pushes:
  // both pushes succeed, and the learner pops a sample only once all of it is in the queue.
  if (s.queue.write_available() < static_cast<std::size_t>(s.record)) {
    Bump(s.dropped);
    return SubmitResult::kDroppedQueueFull;
  }
  s.queue.push(x.data(), static_cast<std::size_t>(s.input_dim));
  s.queue.push(tau.data(), static_cast<std::size_t>(s.P));
  Bump(s.accepted);
  return SubmitResult::kAccepted;
}

Status OnlineLearner::Predict(const ConstVectorRef& x, VectorRef mean) noexcept {
  Impl& s = *impl_;
  if (x.size() != s.input_dim || mean.size() != s.P || !x.allFinite()) {
    Bump(s.prediction_failures);
    return Status::kInvalidInput;
  }
  s.weights_buffer.Acquire();
  const WeightsSnapshot& w = s.weights_buffer.read_buffer();
  s.options.feature_map->Evaluate(x, s.control_phi);
  mean.noalias() = w.weights.transpose() * s.control_phi;
  s.last_version = w.version;
  Bump(s.predictions);
  return Status::kOk;
}

Status OnlineLearner::PredictWithVariance(const ConstVectorRef& x, VectorRef mean,
                                          VectorRef latent_variance) noexcept {
  Impl& s = *impl_;
  if (s.factor_buffer == nullptr || latent_variance.size() != s.P) {
    Bump(s.prediction_failures);
    return Status::kInvalidInput;
  }
  const Status status = Predict(x, mean);
  if (status != Status::kOk) return status;
  s.factor_buffer->Acquire();
  const FactorSnapshot& f = s.factor_buffer->read_buffer();
  internal::UpperTransposeTimes(f.factor.data(), s.D, s.D, s.control_phi.data(), nullptr,
                                s.control_f.data(), nullptr);
  const double quad = s.control_f.squaredNorm();
  latent_variance = quad * s.variance_scale;
  return Status::kOk;
}

long OnlineLearner::last_prediction_version() const { return impl_->last_version; }

int OnlineLearner::ProcessPending() {
  if (impl_->thread.joinable()) {
    throw std::logic_error(
        "OnlineLearner::ProcessPending: a learner thread is running (start_thread = true); "
        "call Stop() first or construct with start_thread = false");
  }
  return impl_->Drain(/*stoppable=*/false);
}

bool OnlineLearner::WaitUntilIdle(std::chrono::milliseconds timeout) {
  Impl& s = *impl_;
  if (!s.thread.joinable()) {
    ProcessPending();
    s.PublishAll();
    return true;
  }
  const long request = s.flush_requested.fetch_add(1, std::memory_order_acq_rel) + 1;
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (s.flush_done.load(std::memory_order_acquire) < request) {
    if (s.learner_failed.load(std::memory_order_acquire) ||
        std::chrono::steady_clock::now() >= deadline) {
      return false;
    }
    std::this_thread::sleep_for(kWaitPollInterval);
  }
  return true;
}

void OnlineLearner::Stop() {
  impl_->stop.store(true, std::memory_order_release);
  if (impl_->thread.joinable()) impl_->thread.join();
}

OnlineLearnerSummary OnlineLearner::summary() const {
  const Impl& s = *impl_;
  const auto get = [](const std::atomic<long>& c) { return c.load(std::memory_order_relaxed); };
  OnlineLearnerSummary out;
  out.submitted = get(s.submitted);
  out.accepted = get(s.accepted);
  out.rejected_size = get(s.rejected_size);
  out.rejected_non_finite = get(s.rejected_non_finite);
  out.rejected_out_of_range = get(s.rejected_out_of_range);
  out.dropped_queue_full = get(s.dropped);
  out.predictions = get(s.predictions);
  out.prediction_failures = get(s.prediction_failures);
  out.processed = get(s.processed);
  out.updates = get(s.updates);
  out.update_failures = get(s.update_failures);
  out.downdates = get(s.downdates);
  out.downdate_failures = get(s.downdate_failures);
  out.rebuilds = get(s.rebuilds);
  out.weight_publishes = get(s.weight_publishes);
  out.covariance_publishes = get(s.factor_publishes);
  out.samples_in_model = get(s.samples_in_model);
  out.learner_failed = s.learner_failed.load(std::memory_order_relaxed);
  return out;
}

const WeightSpaceGP& OnlineLearner::model() const { return impl_->model; }

}  // namespace structgp
