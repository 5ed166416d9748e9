#include "structgp/online/online_learner.h"

#include <boost/lockfree/spsc_queue.hpp>
#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <thread>
#include <utility>
#include <vector>

#include <Eigen/Cholesky>

#include "model/factor_kernels.h"
#include "online/learner_form.h"
#include "structgp/feature/feature_hyperparameters.h"
#include "structgp/model/model_spec.h"
#include "structgp/online/triple_buffer.h"

namespace structgp {
namespace {

// Smallest weight forgetting^window_length that a sample may have when it leaves the window.
// Below it the removal is a no-op to rounding (the sample has long been forgotten) and the
// window only costs memory: such options are refused.
constexpr double kMinWindowExitWeight = 1e-12;

// Steps per UpdateBatch call, at most kFeaturesPerBatchStep per feature: the coupling of the
// steps within a call costs about 6 n D per step for n steps, the pass over the factor about
// 2 D^2, so beyond n ~ D / 3 a longer call costs more than it saves (the regressor form at
// P = 98 is there after a few samples; the feature form at D = 2048 never is).
constexpr double kFeaturesPerBatchStep = 4.0;

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
  if ((feature_map == nullptr) == (regressor_map == nullptr)) {
    return Fail(error, "exactly one of feature_map and regressor_map must be set (got " +
                           std::string(feature_map == nullptr ? "neither" : "both") + ")");
  }
  const bool regressor = regressor_map != nullptr;
  const int D = regressor ? regressor_map->dim() : feature_map->dim();
  const int n_in = regressor ? regressor_map->input_dim() : feature_map->input_dim();
  const int P = regressor ? regressor_map->num_outputs() : num_outputs;
  if (regressor) {
    if (num_outputs != 0 && num_outputs != P) {
      return Fail(error, "num_outputs: the regressor map has " + std::to_string(P) +
                             " outputs, got " + std::to_string(num_outputs) + " (or 0)");
    }
    if (initial_model != nullptr) {
      return Fail(error, "initial_model is for the feature form; use initial_regressor");
    }
  } else {
    if (num_outputs < 1) {
      return Fail(error, "num_outputs: expected at least 1, got " + std::to_string(num_outputs));
    }
    if (prior_mean.size() != 0) {
      return Fail(error, "prior_mean is for the regressor form (the feature form's mean is 0)");
    }
    if (initial_regressor != nullptr) {
      return Fail(error, "initial_regressor is for the regressor form; use initial_model");
    }
  }
  if (initial_model != nullptr && (initial_model->num_features() != D ||
                                   initial_model->num_outputs() != num_outputs)) {
    return Fail(error, "initial_model: expected " + std::to_string(D) + " features and " +
                           std::to_string(num_outputs) + " outputs, got " +
                           std::to_string(initial_model->num_features()) + " and " +
                           std::to_string(initial_model->num_outputs()));
  }
  if (initial_regressor != nullptr &&
      (!initial_regressor->fitted() || initial_regressor->dim() != D ||
       initial_regressor->num_outputs() != P)) {
    return Fail(error, "initial_regressor: expected a fitted model of " + std::to_string(D) +
                           " parameters and " + std::to_string(P) + " outputs");
  }
  if (prior_mean.size() != 0) {
    if (prior_mean.size() != D) {
      return Fail(error, Sizes("prior_mean (one per parameter, or empty)", prior_mean.size(), D));
    }
    if (!prior_mean.allFinite()) return Fail(error, "prior_mean: every entry must be finite");
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
    if (output_scales.size() != P) {
      return Fail(error,
                  Sizes("output_scales (one per output, or empty)", output_scales.size(), P));
    }
    if (!output_scales.allFinite() || (output_scales.array() <= 0.0).any()) {
      return Fail(error, "output_scales: every entry must be finite and > 0");
    }
  }
  if (latent_variance_scale.size() != 0) {
    if (latent_variance_scale.size() != P) {
      return Fail(error, Sizes("latent_variance_scale (one per output, or empty)",
                               latent_variance_scale.size(), P));
    }
    if (!latent_variance_scale.allFinite() || (latent_variance_scale.array() <= 0.0).any()) {
      return Fail(error, "latent_variance_scale: every entry must be finite and > 0");
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
    if (target_limit.size() != P) {
      return Fail(error, Sizes("target_limit (one per output, or empty)", target_limit.size(), P));
    }
    if (target_limit.hasNaN() || (target_limit.array() <= 0.0).any()) {
      return Fail(error, "target_limit: every entry must be > 0 (+inf for no bound)");
    }
  }
  if (queue_capacity < 1) {
    return Fail(
        error, "queue_capacity: expected at least 1 sample, got " + std::to_string(queue_capacity));
  }
  if (max_batch < 1) {
    return Fail(error, "max_batch: expected at least 1, got " + std::to_string(max_batch));
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
     << ", rebuilds " << rebuilds << "), passes " << batches << ", samples in model "
     << samples_in_model << "\n"
     << "published: weights " << weight_publishes << ", covariance " << covariance_publishes
     << "; predictions " << predictions << " (failed " << prediction_failures << ")"
     << (learner_failed ? "; LEARNER FAILED" : "") << "\n";
  return os.str();
}

// -------------------------------------------------------------------------------------------

struct OnlineLearner::Impl {
  explicit Impl(const OnlineLearnerOptions& opts);

  // Learner side.
  void Run();
  // Processes every queued sample, max_batch at a time (stops early when `stoppable` and Stop
  // was called), then publishes W if it changed. Returns the number of samples processed.
  int Drain(bool stoppable);
  // Applies the samples in batch_records columns [0, k).
  void ProcessBatch(int k);
  // Plans samples [first, k) of the batch as steps (their columns, then the leaving
  // sample's removal when the window is full), as if every step succeeds.
  void PlanSteps(int first, int k);
  // Runs steps [begin, end): UpdateBatch, or single Update/Downdate calls with max_batch = 1.
  // Returns the number applied; *status is that of the first refused step.
  int Execute(int begin, int end, Status* status);
  // The statistics of the regressor form follow steps [begin, end) (all applied).
  void AccountSteps(int begin, int end);
  // Writes the planned samples [first, last) into the window ring.
  void CommitWindow(int first, int last);
  void Rebuild();
  void PublishWeights();
  void PublishFactor();
  void ServiceFlush();
  void PublishAll();
  void AfterUpdates(int n);

  OnlineLearnerOptions options;
  WeightSpaceGP model;
  std::unique_ptr<online_detail::LearnerForm> form;
  online_detail::RegressorForm* regressor = nullptr;  // form, in the regressor form
  int input_dim;
  int D;       // model features
  int P;       // torques per sample
  int C;       // model columns per sample
  int record;  // doubles per queued sample: input_dim + P

  std::unique_ptr<WeightSpaceGP> prior_model;  // window rebuilds only

  boost::lockfree::spsc_queue<double> queue;
  TripleBuffer<WeightsSnapshot> weights_buffer;
  std::unique_ptr<TripleBuffer<FactorSnapshot>> factor_buffer;

  // Control thread scratch.
  online_detail::FormScratch control;
  long last_version = 0;

  // Learner scratch: the popped samples, the steps of a batch (columns, targets, forgetting,
  // weights; for each step its sample and column, and whether it removes), the planned
  // samples' first step and removal flag.
  online_detail::FormScratch learner;
  Matrix batch_records;  // record x max_batch
  Matrix step_phi;       // D x max_steps
  Matrix step_y;         // model outputs x max_steps
  Vector step_forgetting, step_weight;
  std::vector<int> step_sample, step_column;
  std::vector<int> sample_first_step, sample_removal_step;  // per planned sample (-1: none)
  int num_steps = 0;

  // Window: ring of L samples, C columns each; sample id i sits in slot i mod L.
  Matrix window_phi;  // D x (L C)
  Matrix window_y;    // model outputs x (L C)
  long window_next_id = 0;
  int window_count = 0;
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
      downdate_failures{0}, rebuilds{0}, batches{0}, weight_publishes{0}, factor_publishes{0},
      samples_in_model{0};
  std::atomic<bool> learner_failed{false};

  // WaitUntilIdle handshake: requests by the supervisor, acknowledgements by the learner.
  std::atomic<long> flush_requested{0};
  std::atomic<long> flush_done{0};

  std::atomic<bool> stop{false};
  std::thread thread;
};

namespace {

Vector ScalesOrOnes(const Vector& s, int n) { return s.size() == 0 ? Vector::Ones(n) : s; }

// The model the learner starts from, in the form's parametrisation.
WeightSpaceGP StartingModel(const OnlineLearnerOptions& o) {
  if (o.feature_map != nullptr) {
    if (o.initial_model != nullptr) return *o.initial_model;
    Vector lambda = o.prior_variance;
    if (lambda.size() == 0) {
      lambda.resize(o.feature_map->dim());
      o.feature_map->PriorVariance(o.feature_map->default_shape_parameters(), lambda);
    }
    return WeightSpaceGP(lambda, o.noise_variance, o.num_outputs, o.output_scales);
  }
  const RegressorMap& map = *o.regressor_map;
  if (o.initial_regressor == nullptr) {
    const Vector lambda =
        o.prior_variance.size() != 0 ? o.prior_variance : Vector(map.prior_std().cwiseAbs2());
    return WeightSpaceGP(lambda, o.noise_variance, 1);
  }
  // A fitted RegressorGP as the weight-space posterior of theta - mu with sigma_ref^2 the
  // largest joint noise: A_ws = sigma_ref^2 A, S = L^{-T} / sigma_ref for A = L L^T.
  const RegressorGP& gp = *o.initial_regressor;
  const double ref = gp.noise_variance().maxCoeff();
  const RegressorStatistics& st = gp.statistics();
  Matrix A = gp.prior_variance().cwiseInverse().asDiagonal();
  for (int j = 0; j < gp.num_outputs(); ++j) A += st.gram[static_cast<size_t>(j)] / gp.noise_variance()[j];
  const Eigen::LLT<Matrix> llt(A);
  if (llt.info() != Eigen::Success) {
    throw std::invalid_argument(
        "OnlineLearner: initial_regressor's posterior precision cannot be factorised");
  }
  Matrix l_inv = Matrix::Identity(gp.dim(), gp.dim());
  llt.matrixL().solveInPlace(l_inv);
  WeightSpaceGPState state;
  state.prior_variance = gp.prior_variance();
  state.noise_variance = ref;
  state.output_scales = Vector::Ones(1);
  state.covariance_factor = l_inv.transpose() / std::sqrt(ref);
  state.covariance_factor.triangularView<Eigen::StrictlyLower>().setZero();
  state.weights = gp.parameters() - gp.prior_mean();
  // Evidence counters of the residual targets y - psi mu, rows weighted sigma_ref^2 / sigma_j^2.
  state.y_squared.setZero(1);
  for (int j = 0; j < gp.num_outputs(); ++j) {
    const Matrix& G = st.gram[static_cast<size_t>(j)];
    const Vector& mu = gp.prior_mean();
    state.y_squared[0] += ref / gp.noise_variance()[j] *
                          (st.y_squared[j] - 2.0 * st.cross.col(j).dot(mu) + mu.dot(G * mu));
  }
  state.weight_sum = st.count * gp.num_outputs();
  state.sample_count = st.count * gp.num_outputs();
  state.num_samples = static_cast<long>(st.count) * gp.num_outputs();
  return WeightSpaceGP::FromState(state);
}

std::unique_ptr<online_detail::LearnerForm> MakeForm(const OnlineLearnerOptions& o,
                                                     const WeightSpaceGP& model) {
  if (o.feature_map != nullptr) {
    return std::make_unique<online_detail::FeatureForm>(
        o.feature_map, o.num_outputs,
        model.noise_variance() * model.output_scales().cwiseAbs2());
  }
  const RegressorMap& map = *o.regressor_map;
  if (o.initial_regressor != nullptr) {
    const RegressorGP& gp = *o.initial_regressor;
    return std::make_unique<online_detail::RegressorForm>(o.regressor_map, gp.prior_mean(),
                                                          gp.noise_variance(),
                                                          model.noise_variance(),
                                                          &gp.statistics());
  }
  const Vector mu = o.prior_mean.size() != 0 ? o.prior_mean : map.prior_mean();
  const Vector scales = ScalesOrOnes(o.output_scales, map.num_outputs());
  return std::make_unique<online_detail::RegressorForm>(
      o.regressor_map, mu, o.noise_variance * scales.cwiseAbs2(), o.noise_variance, nullptr);
}

}  // namespace

Matrix PublishedWeights(const online_detail::LearnerForm& form, const WeightSpaceGP& model) {
  Matrix published(form.published_rows(), form.published_cols());
  form.Publish(model.weights(), published);
  return published;
}

OnlineLearner::Impl::Impl(const OnlineLearnerOptions& opts)
    : options(opts),
      model(StartingModel(opts)),
      form(MakeForm(opts, model)),
      regressor(dynamic_cast<online_detail::RegressorForm*>(form.get())),
      input_dim(form->input_dim()),
      D(form->features()),
      P(form->num_outputs()),
      C(form->columns()),
      record(input_dim + P),
      queue(static_cast<std::size_t>(opts.queue_capacity) * static_cast<std::size_t>(record)),
      weights_buffer(WeightsSnapshot{PublishedWeights(*form, model), 0}) {
  options.num_outputs = P;
  // Steps of one batch: each sample's columns and, with a window, the leaving sample's.
  const int max_steps = options.max_batch * C * (options.window_length > 0 ? 2 : 1);
  if (options.max_batch > 1) model.ReserveBatch(max_steps);
  if (options.covariance_publish_period > 0) {
    factor_buffer = std::make_unique<TripleBuffer<FactorSnapshot>>(
        FactorSnapshot{model.covariance_factor(), 0});
  }
  if (options.window_length > 0) {
    prior_model = std::make_unique<WeightSpaceGP>(model);
    window_phi.setZero(D, static_cast<Eigen::Index>(options.window_length) * C);
    window_y.setZero(form->model_outputs(), static_cast<Eigen::Index>(options.window_length) * C);
    window_exit_weight = std::pow(options.forgetting, options.window_length);
  }
  control = form->MakeScratch();
  learner = form->MakeScratch();
  batch_records.setZero(record, options.max_batch);
  step_phi.setZero(D, max_steps);
  step_y.setZero(form->model_outputs(), max_steps);
  step_forgetting.setZero(max_steps);
  step_weight.setZero(max_steps);
  step_sample.assign(static_cast<size_t>(max_steps), 0);
  step_column.assign(static_cast<size_t>(max_steps), 0);
  sample_first_step.assign(static_cast<size_t>(options.max_batch), 0);
  sample_removal_step.assign(static_cast<size_t>(options.max_batch), -1);
}

void OnlineLearner::Impl::PublishWeights() {
  WeightsSnapshot& slot = weights_buffer.write_buffer();
  form->Publish(model.weights(), slot.weights);  // same size: no allocation
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

void OnlineLearner::Impl::PlanSteps(int first, int k) {
  const int L = options.window_length;
  const Vector& v = form->column_weights();
  num_steps = 0;
  long next_id = window_next_id;
  int count = window_count;
  for (int p = first; p < k; ++p) {
    const auto rec = batch_records.col(p);
    const int begin = num_steps;
    form->Encode(rec.head(input_dim), rec.tail(P), learner, step_phi.middleCols(begin, C),
                 step_y.middleCols(begin, C));
    for (int c = 0; c < C; ++c) {
      step_forgetting[begin + c] = c == 0 ? options.forgetting : 1.0;
      step_weight[begin + c] = v[c];
      step_sample[static_cast<size_t>(begin + c)] = p;
      step_column[static_cast<size_t>(begin + c)] = c;
    }
    num_steps += C;
    sample_first_step[static_cast<size_t>(p)] = begin;
    sample_removal_step[static_cast<size_t>(p)] = -1;
    if (L == 0) continue;
    const long id = next_id++;
    if (count < L) {
      ++count;
      continue;
    }
    // The sample added L samples ago leaves: from the ring, or from this batch's own steps.
    const long leaving = id - L;
    const int r = num_steps;
    if (leaving >= window_next_id) {
      const int q = first + static_cast<int>(leaving - window_next_id);
      const int s0 = sample_first_step[static_cast<size_t>(q)];
      step_phi.middleCols(r, C) = step_phi.middleCols(s0, C);
      step_y.middleCols(r, C) = step_y.middleCols(s0, C);
    } else {
      const Eigen::Index slot = (leaving % L) * C;
      step_phi.middleCols(r, C) = window_phi.middleCols(slot, C);
      step_y.middleCols(r, C) = window_y.middleCols(slot, C);
    }
    for (int c = 0; c < C; ++c) {
      step_forgetting[r + c] = 1.0;
      step_weight[r + c] = -v[c] * window_exit_weight;
      step_sample[static_cast<size_t>(r + c)] = p;
      step_column[static_cast<size_t>(r + c)] = c;
    }
    sample_removal_step[static_cast<size_t>(p)] = r;
    num_steps += C;
  }
}

int OnlineLearner::Impl::Execute(int begin, int end, Status* status) {
  *status = Status::kOk;
  if (end <= begin) return 0;
  Bump(batches);
  if (options.max_batch == 1) {
    for (int i = begin; i < end; ++i) {
      const double w = step_weight[i];
      *status = w > 0.0 ? model.Update(step_phi.col(i), step_y.col(i), step_forgetting[i], w)
                        : model.Downdate(step_phi.col(i), step_y.col(i), -w);
      if (*status != Status::kOk) return i - begin;
    }
    return end - begin;
  }
  const int chunk = std::max(C, static_cast<int>(D / kFeaturesPerBatchStep));
  int applied = 0;
  for (int i = begin; i < end; i += chunk) {
    const int n = std::min(chunk, end - i);
    if (i > begin) Bump(batches);
    const int done = model.UpdateBatch(step_phi.middleCols(i, n), step_y.middleCols(i, n),
                                       step_forgetting.segment(i, n), step_weight.segment(i, n),
                                       status);
    applied += done;
    if (done < n) break;
  }
  return applied;
}

void OnlineLearner::Impl::AccountSteps(int begin, int end) {
  if (regressor == nullptr) return;
  for (int i = begin; i < end; ++i) {
    regressor->Account(step_phi.col(i), step_y(0, i), step_column[static_cast<size_t>(i)],
                       step_forgetting[i], step_weight[i]);
  }
}

void OnlineLearner::Impl::CommitWindow(int first, int last) {
  const int L = options.window_length;
  if (L == 0) return;
  for (int p = first; p < last; ++p) {
    const Eigen::Index slot = (window_next_id % L) * C;
    const int s0 = sample_first_step[static_cast<size_t>(p)];
    window_phi.middleCols(slot, C) = step_phi.middleCols(s0, C);
    window_y.middleCols(slot, C) = step_y.middleCols(s0, C);
    ++window_next_id;
    if (window_count < L) ++window_count;
  }
}

void OnlineLearner::Impl::Rebuild() {
  model = *prior_model;  // equal sizes: copy assignment does not allocate
  if (regressor != nullptr) regressor->ResetStatistics();
  const int L = options.window_length;
  const Vector& v = form->column_weights();
  // The window's samples in order, as steps, max_batch samples per pass.
  num_steps = 0;
  const auto flush = [&]() {
    Status status = Status::kOk;
    int begin = 0;
    while (begin < num_steps) {
      const int applied = Execute(begin, num_steps, &status);
      AccountSteps(begin, begin + applied);
      begin += applied;
      if (status != Status::kOk) {
        Bump(update_failures);
        ++begin;  // skip the refused step
      }
    }
    num_steps = 0;
  };
  for (long id = window_next_id - window_count; id < window_next_id; ++id) {
    const Eigen::Index slot = (id % L) * C;
    step_phi.middleCols(num_steps, C) = window_phi.middleCols(slot, C);
    step_y.middleCols(num_steps, C) = window_y.middleCols(slot, C);
    for (int c = 0; c < C; ++c) {
      step_forgetting[num_steps + c] = c == 0 ? options.forgetting : 1.0;
      step_weight[num_steps + c] = v[c];
      step_column[static_cast<size_t>(num_steps + c)] = c;
    }
    num_steps += C;
    if (num_steps + C > step_phi.cols()) flush();
  }
  flush();
  Bump(rebuilds);
}

void OnlineLearner::Impl::AfterUpdates(int n) {
  if (n == 0) return;
  learner_updates += n;
  for (int i = 0; i < n; ++i) Bump(updates);
  samples_in_model.store(model.num_samples() / C, std::memory_order_relaxed);
  weights_dirty = true;
  factor_dirty = true;
  since_weights += n;
  since_factor += n;
}

void OnlineLearner::Impl::ProcessBatch(int k) {
  int first = 0;
  while (first < k) {
    PlanSteps(first, k);
    Status status = Status::kOk;
    const int applied = Execute(0, num_steps, &status);
    AccountSteps(0, applied);
    if (status == Status::kOk) {
      CommitWindow(first, k);
      for (int p = first; p < k; ++p) {
        if (sample_removal_step[static_cast<size_t>(p)] >= 0) Bump(downdates);
      }
      AfterUpdates(k - first);
      return;
    }
    // Step `applied` was refused: the samples before its sample are in the model as planned.
    const int failed = applied;
    const int p = step_sample[static_cast<size_t>(failed)];
    for (int q = first; q < p; ++q) {
      if (sample_removal_step[static_cast<size_t>(q)] >= 0) Bump(downdates);
    }
    const int removal = sample_removal_step[static_cast<size_t>(p)];
    if (removal < 0 || failed < removal) {
      // Its addition failed: take out the rows of it already added (regressor form; the
      // forgetting step stays), and it never enters the window.
      Status undo = Status::kOk;
      for (int i = sample_first_step[static_cast<size_t>(p)]; i < failed; ++i) {
        undo = model.Downdate(step_phi.col(i), step_y.col(i), step_weight[i]);
        if (regressor != nullptr) {
          regressor->Account(step_phi.col(i), step_y(0, i), step_column[static_cast<size_t>(i)],
                             1.0, undo == Status::kOk ? -step_weight[i] : 0.0);
        }
      }
      CommitWindow(first, p);
      AfterUpdates(p - first);
      Bump(update_failures);
    } else {
      // The leaving sample's removal was refused: the new sample is in the model and the
      // window; the leaving one leaves the ring.
      CommitWindow(first, p + 1);
      AfterUpdates(p + 1 - first);
      Bump(downdate_failures);
      if (options.window_failure_policy == WindowFailurePolicy::kRebuild) {
        Rebuild();
      } else {
        // Keep it: put back the rows of it already removed.
        for (int i = removal; i < failed; ++i) {
          if (model.Update(step_phi.col(i), step_y.col(i), 1.0, -step_weight[i]) == Status::kOk) {
            if (regressor != nullptr) {
              regressor->Account(step_phi.col(i), step_y(0, i),
                                 step_column[static_cast<size_t>(i)], 1.0, -step_weight[i]);
            }
          }
        }
      }
      samples_in_model.store(model.num_samples() / C, std::memory_order_relaxed);
    }
    first = p + 1;
  }
}

int OnlineLearner::Impl::Drain(bool stoppable) {
  int n = 0;
  while (queue.read_available() >= static_cast<std::size_t>(record)) {
    int k = 0;
    while (k < options.max_batch && queue.read_available() >= static_cast<std::size_t>(record)) {
      queue.pop(batch_records.col(k).data(), static_cast<std::size_t>(record));
      Bump(processed);
      ++k;
    }
    ProcessBatch(k);
    n += k;
    if (since_weights >= options.publish_period) PublishWeights();
    if (factor_buffer != nullptr && since_factor >= options.covariance_publish_period) {
      PublishFactor();
    }
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
  if (model.prior_mean()) {
    throw std::invalid_argument("OnlineLearnerOptionsFor: " + ModelLabel(model.spec()) +
                                " has a prior mean (the URDF's torques), which the learner does "
                                "not add; Replay (online/replay.h) handles it");
  }
  if (model.per_joint()) {
    throw std::invalid_argument("OnlineLearnerOptionsFor: " + ModelLabel(model.spec()) +
                                " has per-joint hyper-parameters; the learner updates one "
                                "posterior shared by the joints: fit without per-joint sets");
  }
  const Hyperparameters& h = model.hyperparameters();
  OnlineLearnerOptions o;
  o.feature_map = model.feature_map();
  o.num_outputs = model.num_joints();
  o.prior_variance = PriorVariance(*model.feature_map(), h);
  o.noise_variance = h.noise_variance();
  o.output_scales = h.output_scales();
  if (model.bands_calibrated()) o.latent_variance_scale = model.latent_variance_scale();
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
  s.form->Predict(x, w.weights, nullptr, s.control, mean, mean);
  s.last_version = w.version;
  Bump(s.predictions);
  return Status::kOk;
}

Status OnlineLearner::PredictWithVariance(const ConstVectorRef& x, VectorRef mean,
                                          VectorRef latent_variance) noexcept {
  Impl& s = *impl_;
  if (s.factor_buffer == nullptr || latent_variance.size() != s.P || x.size() != s.input_dim ||
      mean.size() != s.P || !x.allFinite()) {
    Bump(s.prediction_failures);
    return Status::kInvalidInput;
  }
  s.weights_buffer.Acquire();
  s.factor_buffer->Acquire();
  const WeightsSnapshot& w = s.weights_buffer.read_buffer();
  const FactorSnapshot& f = s.factor_buffer->read_buffer();
  s.form->Predict(x, w.weights, &f.factor, s.control, mean, latent_variance);
  if (s.options.latent_variance_scale.size() != 0) {
    latent_variance.array() *= s.options.latent_variance_scale.array();
  }
  s.last_version = w.version;
  Bump(s.predictions);
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
  out.batches = get(s.batches);
  out.weight_publishes = get(s.weight_publishes);
  out.covariance_publishes = get(s.factor_publishes);
  out.samples_in_model = get(s.samples_in_model);
  out.learner_failed = s.learner_failed.load(std::memory_order_relaxed);
  return out;
}

const WeightSpaceGP& OnlineLearner::model() const { return impl_->model; }

RegressorGP OnlineLearner::regressor_model() const {
  const Impl& s = *impl_;
  if (s.regressor == nullptr) {
    throw std::logic_error("OnlineLearner::regressor_model: the learner runs a feature map");
  }
  RegressorGP gp(s.regressor->prior_mean(), s.model.effective_prior_variance(),
                 s.regressor->noise_variance());
  if (gp.Fit(s.regressor->Statistics()) != Status::kOk) {
    throw std::logic_error(
        "OnlineLearner::regressor_model: the posterior of the statistics cannot be factorised");
  }
  return gp;
}

}  // namespace structgp
