#include "structgp/fit/fit_model.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <exception>
#include <functional>
#include <mutex>
#include <optional>
#include <thread>
#include <cmath>
#include <limits>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "structgp/core/row_subset.h"
#include "structgp/core/segments.h"
#include "structgp/core/validate.h"
#include "structgp/hyper/cross_validation.h"
#include "structgp/hyper/evidence.h"
#include "structgp/hyper/hyperparameter_layout.h"
#include "structgp/hyper/marginal_likelihood.h"
#include "structgp/rigid_body/physical_consistency.h"
#include "structgp/internal/text.h"
#include "structgp/model/sufficient_statistics.h"

namespace structgp {
namespace {

using internal::Format;
using internal::Table;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
// In the method description of a search with a prior (every form).
constexpr char kMapPhrase[] = " with a prior on the log hyper-parameters (MAP)";
constexpr char kFixedDescription[] = "fixed defaults (output scale = torque RMS, noise 10% of it)";

std::string Number(double value) { return Format("%.6g", value); }

// One fit in progress: the clock, the callback and the summary being filled.
class Fit {
 public:
  // origin: the time FitModel was called, from which progress counts its seconds (a joint's
  // search, FitOptions::per_joint, times its own summary from its own start).
  Fit(const FitOptions& options, RobotModel* model,
      std::chrono::steady_clock::time_point origin = std::chrono::steady_clock::now())
      : options_(options),
        model_(model),
        start_(std::chrono::steady_clock::now()),
        origin_(origin) {
    summary_.method = options.method;
    summary_.initial_negative_log_evidence = kNaN;
    summary_.final_negative_log_evidence = kNaN;
  }

  double seconds() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  }

  // Tells the callback; false when it asks to stop.
  bool Report(const std::string& message, int iteration = 0, double nle = kNaN) {
    if (!options_.callback) return true;
    FitProgress p;
    p.message = joint_ > 0 && !message.empty() ? Format("joint %d: ", joint_) + message : message;
    p.iteration = iteration;
    p.negative_log_evidence = nle;
    p.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - origin_).count();
    if (options_.callback(p) == FitCallbackReturn::kContinue) return true;
    aborted_ = true;
    return false;
  }

  // The evidence options with the fit's callback behind their iteration callback.
  MaximumLikelihoodOptions EvidenceOptions() {
    MaximumLikelihoodOptions o = options_.evidence;
    if (options_.callback) {
      auto user = o.iteration_callback;
      o.iteration_callback = [this, user](int iteration, double nle) {
        if (user && !user(iteration, nle)) return false;
        return Report("", iteration, nle);
      };
    }
    return o;
  }

  FitSummary Finish(FitTermination termination, std::string message) {
    summary_.termination = termination;
    summary_.message = std::move(message);
    summary_.total_seconds = seconds();
    return summary_;
  }
  FitSummary Aborted() { return Finish(FitTermination::kUserAbort, "the callback asked to stop"); }
  bool aborted() const { return aborted_; }
  // A stop asked by MaximumLikelihoodOptions::iteration_callback itself.
  void MarkAborted() { aborted_ = true; }

  // Records run `chosen` of an evidence search.
  void TakeEvidenceSummary(const MaximumLikelihoodSummary& s, int chosen) {
    const MaximumLikelihoodStart& run = s.starts.at(static_cast<size_t>(chosen));
    summary_.iterations = run.iterations;
    summary_.num_evaluations = s.num_evaluations;
    summary_.initial_negative_log_evidence = s.initial_negative_log_likelihood;
    summary_.final_negative_log_evidence = run.negative_log_likelihood;
    summary_.final_negative_log_prior = run.negative_log_prior;
    summary_.at_bounds = run.at_bounds;
    summary_.starts = s.starts;
    summary_.best_start = s.best_start;
    summary_.chosen_start = chosen;
    switch (run.termination) {
      case MaximumLikelihoodTermination::kMaxIterations:
        search_end_ = FitTermination::kMaxIterations;
        break;
      case MaximumLikelihoodTermination::kLineSearchFailed:
        search_end_ = FitTermination::kLineSearchFailed;
        break;
      default:
        search_end_ = FitTermination::kConverged;
        break;
    }
    search_message_ = chosen == s.best_start ? s.message : ToString(run.termination);
    const bool map = s.final_negative_log_prior != 0.0 || run.negative_log_prior != 0.0;
    std::string how = Format("type-II maximum likelihood%s (%s, %d iterations",
                             map ? kMapPhrase : "",
                             ToString(run.termination), run.iterations);
    if (s.starts.size() > 1) {
      how += Format("; start %d of %d", chosen + 1, static_cast<int>(s.starts.size()));
    }
    summary_.method_description = how + ")";
    if (s.starts.size() > 1) {
      std::string objectives;
      for (const MaximumLikelihoodStart& r : s.starts) {
        objectives += (objectives.empty() ? "" : ", ") +
                      (r.usable ? Format("%.6g", r.objective) : std::string("failed"));
      }
      summary_.notes.push_back("objective -log p(Y) - log p(x) of each start: " + objectives +
                               " nats");
    }
    if (!run.at_bounds.empty()) {
      std::string names;
      for (const auto& n : run.at_bounds) names += (names.empty() ? "" : ", ") + n;
      summary_.notes.push_back("at a bound of its search box (the optimum may lie beyond): " +
                               names);
    }
  }

  const FitOptions& options() const { return options_; }
  RobotModel* model() { return model_; }
  std::chrono::steady_clock::time_point origin() const { return origin_; }
  // The joint (1-based) whose own hyper-parameters are searched (FitOptions::per_joint), 0 for
  // a search of the shared set.
  int joint() const { return joint_; }
  void set_joint(int joint) { joint_ = joint; }
  FitSummary& summary() { return summary_; }
  FitTermination search_end() const { return search_end_; }
  void set_search_end(FitTermination end) { search_end_ = end; }
  const std::string& search_message() const { return search_message_; }
  void set_search_message(std::string m) { search_message_ = std::move(m); }

 private:
  const FitOptions& options_;
  RobotModel* model_;
  std::chrono::steady_clock::time_point start_;
  std::chrono::steady_clock::time_point origin_;
  FitSummary summary_;
  FitTermination search_end_ = FitTermination::kConverged;
  std::string search_message_;
  bool aborted_ = false;
  int joint_ = 0;
};

using Search =
    std::function<MaximumLikelihoodSummary(const MaximumLikelihoodOptions&, Hyperparameters*)>;

// One joint's set (one output scale) as a set shared by all num_joints joints, each with that
// joint's scale. The held-out check of that joint's candidates reads that joint alone, and a
// shared set fits every column with one factor, which the other columns' scales do not change.
Hyperparameters SharedFor(const Hyperparameters& own, int num_joints) {
  Hyperparameters shared = own;
  shared.log_output_scale = Vector::Constant(num_joints, own.log_output_scale[0]);
  return shared;
}

// The evidence search from *h (the data-derived start, also the prior's centre), then the
// held-out check of its runs, best objective first; when none passes, the search again from
// *h with a tighter prior (FitOptions::max_prior_tightenings). *h receives the run taken.
// False when the fit ends here (aborted: fit->aborted(); failed: *failure).
bool SearchAndCheck(const Matrix& X, const Matrix& Y, Fit* fit, Hyperparameters* h,
                    std::string* failure, const Search& search) {
  const FitOptions& options = fit->options();
  const Hyperparameters centre = *h;
  MaximumLikelihoodOptions o = fit->EvidenceOptions();
  // The search with the prior as given, kept for when no tighter prior passes either.
  MaximumLikelihoodSummary first;
  FitCheck first_check;
  for (int round = 0;; ++round) {
    Hyperparameters trial = centre;
    const MaximumLikelihoodSummary s = search(o, &trial);
    if (s.termination == MaximumLikelihoodTermination::kUserAbort || fit->aborted()) {
      fit->MarkAborted();
      return false;
    }
    if (!s.usable()) {
      *failure = "type-II maximum likelihood: " + s.message;
      return false;
    }
    if (!fit->Report(s.BriefReport())) return false;
    if (!options.check.enabled) {
      *h = s.starts[static_cast<size_t>(s.best_start)].hyperparameters;
      fit->TakeEvidenceSummary(s, s.best_start);
      return true;
    }
    FitCheck best_check;
    const std::vector<int> order = s.StartsByObjective();
    for (size_t i = 0; i < order.size(); ++i) {
      const int k = order[i];
      const Hyperparameters& candidate = s.starts[static_cast<size_t>(k)].hyperparameters;
      const FitCheck c =
          fit->joint() > 0
              ? CheckOnHeldOutBlocks(*fit->model(),
                                     SharedFor(candidate, static_cast<int>(Y.cols())), X, Y,
                                     options.check, fit->joint())
              : CheckOnHeldOutBlocks(*fit->model(), candidate, X, Y, options.check);
      if (i == 0) best_check = c;
      if (!fit->Report(Format("start %d: %s", k + 1, c.message.c_str()))) return false;
      if (!c.ran || c.passed) {
        *h = s.starts[static_cast<size_t>(k)].hyperparameters;
        fit->summary().check = c;
        fit->summary().prior_tightenings = round;
        fit->TakeEvidenceSummary(s, k);
        if (k != s.best_start) {
          fit->summary().notes.push_back(
              Format("start %d (the lowest objective) failed the held-out check (%s); start %d "
                     "passed and was taken",
                     s.best_start + 1, best_check.message.c_str(), k + 1));
        }
        if (round > 0) {
          fit->summary().notes.push_back(Format(
              "no start passed the held-out check with the prior as given (%s); with its "
              "widths divided by %g the check passed",
              first_check.message.c_str(), std::pow(options.prior_tightening_factor, round)));
        }
        return true;
      }
    }
    if (round == 0) {
      first = s;
      first_check = best_check;
    }
    if (round >= options.max_prior_tightenings || o.prior.family == HyperpriorFamily::kNone) {
      // Nothing passed: the best objective of the search with the prior as given, and a
      // warning. A tighter prior is kept only when it passes.
      *h = first.starts[static_cast<size_t>(first.best_start)].hyperparameters;
      fit->summary().check = first_check;
      fit->summary().prior_tightenings = round;
      fit->TakeEvidenceSummary(first, first.best_start);
      fit->summary().warnings.push_back(
          first_check.message +
          (o.prior.family == HyperpriorFamily::kNone
               ? "; no start passed (plain type-II maximum likelihood: no prior to tighten)"
               : Format("; no start passed, nor with the prior's widths divided by up to %g",
                        std::pow(options.prior_tightening_factor, round))) +
          ". Predictions away from the training path may be far off.");
      return true;
    }
    if (!fit->Report(Format("no start passed the held-out check; searching again from the "
                            "data-derived start with the prior's widths divided by %g",
                            std::pow(options.prior_tightening_factor, round + 1)))) {
      return false;
    }
    o.prior = o.prior.Tightened(options.prior_tightening_factor);
    o.num_starts = 1;
  }
}

// Feature-map models by evidence: noise and output scales profiled, then LBFGS on cached
// Phi^T Phi. False when the fit ends here (summary finished by the caller's check).
bool FeatureMapByEvidence(const Matrix& X, const Matrix& Y, const Matrix& Yr, Fit* fit,
                          Hyperparameters* h, std::string* failure) {
  const auto& map = fit->model()->feature_map();
  if (!fit->Report(Format("accumulating Phi^T Phi over %d rows (D = %d)",
                          static_cast<int>(X.rows()), map->dim()))) {
    return false;
  }
  AccumulateOptions accumulate;
  accumulate.num_threads = fit->options().num_threads;
  SufficientStatistics stats = AccumulateStatistics(*map, X, Yr, accumulate);
  const WeightSpaceEvidence evidence(map, std::move(stats));
  if (fit->options().profile_noise_and_scales &&
      fit->options().output_scaling == OutputScaling::kPerJointRms) {
    if (!fit->Report("profiling the noise level and output scales by evidence")) return false;
    try {
      // The profile's own range, within the noise bounds of the search that follows.
      const LogBounds& noise = fit->options().evidence.noise_bounds;
      *h = ProfileNoiseAndScales(evidence, *h, std::max(-9.0, noise.lower),
                                 std::min(1.0, noise.upper));
    } catch (const std::runtime_error& e) {
      *failure = std::string("hyper-parameters by evidence: ") + e.what();
      return false;
    }
  }
  if (!fit->Report("maximising the evidence over the shape, block scales and noise (Ceres "
                   "LBFGS)")) {
    return false;
  }
  fit->summary().hyperparameter_rows = static_cast<int>(X.rows());
  return SearchAndCheck(
      X, Y, fit, h, failure,
      [&evidence](const MaximumLikelihoodOptions& o, Hyperparameters* hyper) {
        return FitHyperparameters(evidence, o, hyper);
      });
}

bool FeatureMapByCrossValidation(const Matrix& X, const Matrix& Yr, const ConstVectorRef& t,
                                 Fit* fit, Hyperparameters* h, std::string* failure) {
  const FeatureMap& map = *fit->model()->feature_map();
  const FitOptions& o = fit->options();
  if (o.cv_folds > X.rows()) {
    throw std::invalid_argument(Format(
        "cross-validation: need 2 <= folds <= %d (the number of rows), got %d folds",
        static_cast<int>(X.rows()), o.cv_folds));
  }
  if (!fit->Report(Format("blocked %d-fold cross-validation statistics over %d rows (D = %d)",
                          o.cv_folds, static_cast<int>(X.rows()), map.dim()))) {
    return false;
  }
  // Whole trajectories per fold when the log holds enough of them (t restarts).
  const FoldStatistics folds(map, X, Yr, o.cv_folds, SegmentStarts(t));
  const Hyperparameters base = *h;
  std::vector<double> shape_values;
  if (map.num_shape_parameters() > 0) {
    for (double offset : o.cv_shape_offsets) shape_values.push_back(base.shape[0] + offset);
  }
  std::vector<double> noise_values;
  for (double level : o.cv_noise_levels) noise_values.push_back(std::log(level));
  const std::vector<Hyperparameters> candidates =
      HyperparameterGrid(base, shape_values, noise_values, 0);
  if (!fit->Report(Format("scoring %d candidates", static_cast<int>(candidates.size())))) {
    return false;
  }
  std::vector<CrossValidationResult> results;
  int best = -1;
  *h = SelectByCrossValidation(map, folds, candidates, &results, &best);
  if (best < 0) {
    *failure = "cross-validation: every candidate failed to factorise";
    return false;
  }
  std::string chosen = Format("noise std %.3g", std::exp(h->log_noise_std));
  if (!shape_values.empty()) {
    chosen = map.shape_parameter_names()[0] + Format(" %.3g, ", h->shape[0]) + chosen;
  }
  const auto at_edge = [](double value, const std::vector<double>& grid) {
    return value == *std::min_element(grid.begin(), grid.end()) ||
           value == *std::max_element(grid.begin(), grid.end());
  };
  if ((!shape_values.empty() && at_edge(h->shape[0], shape_values)) ||
      at_edge(h->log_noise_std, noise_values)) {
    fit->summary().notes.push_back(
        "the best candidate lies on the edge of the grid; type-II maximum likelihood searches "
        "without a grid");
  }
  FitSummary& summary = fit->summary();
  summary.cv_candidates = static_cast<int>(candidates.size());
  summary.cv_mean_nmse = results[static_cast<size_t>(best)].mean_nmse;
  summary.hyperparameter_rows = static_cast<int>(X.rows());
  summary.method_description =
      Format("blocked %d-fold cross-validation over %d candidates (%s; held-out nMSE %.4g)",
             o.cv_folds, static_cast<int>(candidates.size()), chosen.c_str(),
             summary.cv_mean_nmse);
  fit->set_search_message("scored " + std::to_string(candidates.size()) + " candidates");
  return true;
}

// Kernel models by evidence on an evenly spaced subset. *h holds the kernel's default
// parameters in shape (RobotModel::DefaultHyperparameters); the fitted ones replace them, and
// RobotModel::Fit(X, Y, *h) then builds the kernel from them.
bool KernelByEvidence(const Matrix& X, const Matrix& Y, const Matrix& Yr, Fit* fit,
                      Hyperparameters* h, std::string* failure) {
  RobotModel* model = fit->model();
  const Kernel& kernel = *model->kernel();
  const int limit = fit->options().max_evidence_rows;
  const std::vector<int> rows = EvenlySpacedRows(X.rows(), limit);
  const Matrix Xs = SelectRows(X, rows);
  const Matrix Ys = SelectRows(Yr, rows);
  const int used = static_cast<int>(rows.size());
  if (!fit->Report(Format("maximising the evidence of the kernel on %d of %d rows (Ceres LBFGS, "
                          "O(m^3) per evaluation)",
                          used, static_cast<int>(X.rows())))) {
    return false;
  }
  fit->summary().hyperparameter_rows = used;
  if (used < X.rows()) {
    fit->summary().notes.push_back(
        Format("kernel hyper-parameters fitted on %d evenly spaced rows of %d", used,
               static_cast<int>(X.rows())));
  }
  return SearchAndCheck(
      X, Y, fit, h, failure,
      [&kernel, &Xs, &Ys](const MaximumLikelihoodOptions& o, Hyperparameters* hyper) {
        return FitKernelHyperparameters(kernel, Xs, Ys, o, hyper);
      });
}

// rbd and lag models by evidence: the per-joint statistics of the regressor over every row, then LBFGS
// over the block scales and the noise level of each joint.
bool RegressorByEvidence(const Matrix& X, const Matrix& Y, const Matrix& Yr, Fit* fit,
                         Hyperparameters* h, std::string* failure) {
  const SemiParametricRegressorMap& map = *fit->model()->regressor_map();
  if (!fit->Report(Format("accumulating the regressor's statistics over %d rows "
                          "(P = %d parameters)",
                          static_cast<int>(X.rows()), map.dim()))) {
    return false;
  }
  RegressorStatistics stats(map.dim(), map.num_outputs());
  stats.Accumulate(map, X, Yr);
  if (!fit->Report("maximising the evidence over the prior widths and each joint's noise (Ceres "
                   "LBFGS)")) {
    return false;
  }
  fit->summary().hyperparameter_rows = static_cast<int>(X.rows());
  return SearchAndCheck(
      X, Y, fit, h, failure,
      [&map, &stats](const MaximumLikelihoodOptions& o, Hyperparameters* hyper) {
        return FitRegressorHyperparameters(map, stats, o, hyper);
      });
}

// The Euler-Lagrange search's options for this model: friction and its Coulomb width from the
// model, the evidence rows capped at max_euler_lagrange_evidence_values / N.
EulerLagrangeGPOptions EulerLagrangeOptions(const FitOptions& options, const RobotModel& model) {
  EulerLagrangeGPOptions o = options.euler_lagrange;
  o.prior = options.evidence.prior;
  o.friction = model.spec().friction;
  o.coulomb_width = model.options().friction_width;
  o.effects = model.effect_map();
  o.effect_prior_variance = model.effect_prior_variance();
  o.inducing_states = 0;
  o.num_threads = options.num_threads;
  const int cap = std::max(1, options.max_euler_lagrange_evidence_values / model.num_joints());
  o.hyperparameter_rows = o.hyperparameter_rows > 0 ? std::min(o.hyperparameter_rows, cap) : cap;
  return o;
}

// lagk by evidence: FitEulerLagrangeGP's search (hyper/euler_lagrange_fit.h) on evenly spaced
// rows, the best sigma of its grid winning; *h receives the result (ToHyperparameters).
bool EulerLagrangeByEvidence(const Matrix& X, const Matrix& Yr, Fit* fit, Hyperparameters* h,
                             std::string* failure) {
  const RobotModel& model = *fit->model();
  const int N = model.num_joints();
  const EulerLagrangeGPOptions o = EulerLagrangeOptions(fit->options(), model);
  const int used = static_cast<int>(EvenlySpacedRows(X.rows(), o.hyperparameter_rows).size());
  std::string grid;
  for (double sigma : o.start ? std::vector<double>{o.start->sigma} : o.sigmas) {
    grid += (grid.empty() ? "" : ", ") + Number(sigma);
  }
  if (!fit->Report(Format("maximising the evidence of the Euler-Lagrange kernel over %d part "
                          "weights and %d noise levels at sigma in {%s}%s on %d of %d rows (Ceres "
                          "LBFGS, O((m N)^3) per evaluation)",
                          o.per_link ? 2 * N : 2, N, grid.c_str(),
                          o.start ? " from the given hyper-parameters" : "", used,
                          static_cast<int>(X.rows())))) {
    return false;
  }
  const EulerLagrangeGPSummary s = FitEulerLagrangeGP(X, Yr, o, nullptr);
  FitSummary& summary = fit->summary();
  summary.hyperparameter_rows = s.hyperparameter_rows;
  summary.warnings.insert(summary.warnings.end(), s.warnings.begin(), s.warnings.end());
  if (s.status != Status::kOk) {
    *failure = "type-II maximum likelihood of the Euler-Lagrange kernel failed: " + s.message;
    return false;
  }
  *h = ToHyperparameters(s.hyperparameters);
  summary.final_negative_log_evidence = -s.log_evidence;
  summary.final_negative_log_prior = -s.log_prior;
  summary.initial_negative_log_evidence = -s.initial_log_evidence;
  summary.iterations = 0;
  summary.num_evaluations = 0;
  for (size_t k = 0; k < s.sigmas.size(); ++k) {
    summary.iterations += s.iterations_per_sigma[k];
    summary.num_evaluations += s.evaluations_per_sigma[k];
  }
  const bool with_prior = o.prior.family != HyperpriorFamily::kNone;
  const char* map = with_prior ? kMapPhrase : "";
  summary.method_description =
      o.start ? Format("type-II maximum likelihood%s over the part weights and each joint's noise "
                       "from the given hyper-parameters, at their sigma = %s",
                       map, Number(s.hyperparameters.sigma).c_str())
              : Format("type-II maximum likelihood%s over the part weights and each joint's "
                       "noise, best of %d sigmas (sigma = %s)",
                       map, static_cast<int>(s.sigmas.size()),
                       Number(s.hyperparameters.sigma).c_str());
  std::string per_sigma;
  for (size_t k = 0; k < s.sigmas.size(); ++k) {
    per_sigma += (per_sigma.empty() ? "" : ", ") + Number(s.sigmas[k]) + ": " +
                 (std::isfinite(s.log_evidence_per_sigma[k])
                      ? Number(s.log_evidence_per_sigma[k]) + " nats" +
                            (with_prior ? ", log prior " + Number(s.log_prior_per_sigma[k])
                                        : std::string())
                      : std::string("failed")) +
                 Format(" (%d iterations%s)", s.iterations_per_sigma[k],
                        s.warm_start_per_sigma[k] ? ", from the previous sigma's optimum" : "");
  }
  summary.notes.push_back("log evidence at each sigma: " + per_sigma);
  if (used < X.rows()) {
    summary.notes.push_back(Format("hyper-parameters fitted on %d evenly spaced rows of %d", used,
                                   static_cast<int>(X.rows())));
  }
  const double best = s.hyperparameters.sigma;
  // s.sigmas: the grid searched, sorted (one sigma from a given start: no edge).
  if (s.sigmas.size() > 1 && (best == s.sigmas.front() || best == s.sigmas.back())) {
    summary.at_bounds.push_back("log_sigma");
    summary.notes.push_back("sigma at the edge of its grid (the optimum may lie beyond): " +
                            Number(best));
  }
  return true;
}

// One joint's own search (FitOptions::per_joint) on its torque alone (Yr's column; Y, all
// torques, for the held-out check of its candidates, which reads that joint).
struct JointSearch {
  bool ok = false;
  bool aborted = false;
  std::string failure;
  FitSummary summary;
  Hyperparameters set;
  std::exception_ptr error;  // thrown on a worker thread, rethrown on the caller's
};

JointSearch SearchJoint(const FitOptions& options, RobotModel* model,
                        std::chrono::steady_clock::time_point origin, const Matrix& X,
                        const Matrix& Y, const Matrix& Yr, const ConstVectorRef& t,
                        bool kernel_model, const Hyperparameters& start, int j) {
  JointSearch out;
  Fit joint(options, model, origin);
  joint.set_joint(j + 1);
  out.set = start.Output(j);
  const Matrix Yr_j = Yr.col(j);
  bool go_on = true;
  switch (options.method) {
    case HyperparameterMethod::kEvidence:
      go_on = kernel_model ? KernelByEvidence(X, Y, Yr_j, &joint, &out.set, &out.failure)
                           : FeatureMapByEvidence(X, Y, Yr_j, &joint, &out.set, &out.failure);
      break;
    case HyperparameterMethod::kCrossValidation:
      go_on = FeatureMapByCrossValidation(X, Yr_j, t, &joint, &out.set, &out.failure);
      break;
    case HyperparameterMethod::kFixed:
      joint.summary().method_description = kFixedDescription;
      joint.set_search_message("fixed hyper-parameters: nothing to search");
      break;
  }
  out.aborted = joint.aborted();
  out.ok = go_on && !out.aborted;
  if (out.ok) {
    out.summary = joint.Finish(joint.search_end(), joint.search_message());
    out.summary.hyperparameter_seconds = out.summary.total_seconds;
  }
  return out;
}

// Every joint's search: one after the other, or with FitOptions::num_threads > 1 up to that
// many joints at once (each then accumulates on num_threads / workers threads; without a
// MaximumLikelihoodOptions::iteration_callback, which the caller may expect on its thread).
// FitOptions::callback is called on the calling thread either way: the workers queue their
// progress, and a kAbort stops them all.
std::vector<JointSearch> SearchJoints(Fit* fit, const Matrix& X, const Matrix& Y,
                                      const Matrix& Yr, const ConstVectorRef& t,
                                      bool kernel_model, const Hyperparameters& start) {
  const FitOptions& options = fit->options();
  const int N = static_cast<int>(Y.cols());
  const int workers = options.evidence.iteration_callback ? 1 : std::min(options.num_threads, N);
  std::vector<JointSearch> results(static_cast<size_t>(N));
  if (workers <= 1) {
    for (int j = 0; j < N; ++j) {
      results[static_cast<size_t>(j)] =
          SearchJoint(options, fit->model(), fit->origin(), X, Y, Yr, t, kernel_model, start, j);
      if (!results[static_cast<size_t>(j)].ok) break;
    }
    return results;
  }
  std::mutex mutex;
  std::condition_variable wake;
  std::deque<FitProgress> queue;
  std::atomic<bool> stop{false};        // a joint failed, or the caller asked to stop
  std::atomic<bool> user_abort{false};  // the caller asked to stop
  std::atomic<int> next{0};
  int running = workers;
  FitOptions worker_options = options;
  worker_options.num_threads = std::max(1, options.num_threads / workers);
  if (options.callback) {
    worker_options.callback = [&](const FitProgress& p) {
      {
        const std::lock_guard<std::mutex> lock(mutex);
        queue.push_back(p);
      }
      wake.notify_one();
      return stop ? FitCallbackReturn::kAbort : FitCallbackReturn::kContinue;
    };
  }
  std::vector<std::thread> threads;
  for (int w = 0; w < workers; ++w) {
    threads.emplace_back([&]() {
      for (int j = next++; j < N && !stop; j = next++) {
        JointSearch& r = results[static_cast<size_t>(j)];
        try {
          r = SearchJoint(worker_options, fit->model(), fit->origin(), X, Y, Yr, t,
                          kernel_model, start, j);
        } catch (...) {
          r.error = std::current_exception();
        }
        if (!r.ok) stop = true;
      }
      {
        const std::lock_guard<std::mutex> lock(mutex);
        --running;
      }
      wake.notify_one();
    });
  }
  {
    std::unique_lock<std::mutex> lock(mutex);
    while (running > 0 || !queue.empty()) {
      wake.wait(lock, [&] { return running == 0 || !queue.empty(); });
      while (!queue.empty()) {
        const FitProgress p = std::move(queue.front());
        queue.pop_front();
        lock.unlock();
        if (!stop && options.callback(p) == FitCallbackReturn::kAbort) {
          user_abort = true;
          stop = true;
        }
        lock.lock();
      }
    }
  }
  for (std::thread& thread : threads) thread.join();
  for (const JointSearch& r : results) {
    if (r.error) std::rethrow_exception(r.error);
  }
  // A stop asked by the caller's callback is an abort of every joint not yet finished.
  if (user_abort) {
    for (JointSearch& r : results) {
      if (!r.ok && r.failure.empty()) r.aborted = true;
    }
  }
  return results;
}

// FitOptions::per_joint: each joint's own search (SearchJoints), each joint's summary kept in
// the fit's summary and merged into it. *h holds the data-derived shared start on entry; on
// success its per_output holds the joints' sets.
bool PerJointSearch(const Matrix& X, const Matrix& Y, const Matrix& Yr, const ConstVectorRef& t,
                    bool kernel_model, Fit* fit, Hyperparameters* h, std::string* failure) {
  const FitOptions& options = fit->options();
  FitSummary& summary = fit->summary();
  const int N = static_cast<int>(Y.cols());
  std::vector<JointSearch> results = SearchJoints(fit, X, Y, Yr, t, kernel_model, *h);
  // A joint that failed names the failure (the joints stopped because of it are not aborts).
  for (int j = 0; j < N; ++j) {
    const JointSearch& r = results[static_cast<size_t>(j)];
    if (!r.ok && !r.aborted && !r.failure.empty()) {
      *failure = Format("joint %d: ", j + 1) + r.failure;
      return false;
    }
  }
  for (const JointSearch& r : results) {
    if (r.aborted) {
      fit->MarkAborted();
      return false;
    }
  }
  std::vector<Hyperparameters> sets;
  double initial = 0.0, final_evidence = 0.0, final_prior = 0.0, cv_nmse = 0.0;
  std::string messages;
  bool map = false;
  for (int j = 0; j < N; ++j) {
    JointSearch& r = results[static_cast<size_t>(j)];
    if (!r.ok) {
      *failure = Format("joint %d: its search did not run", j + 1);
      return false;
    }
    FitSummary js = std::move(r.summary);
    const std::string name = Format("joint %d: ", j + 1);
    summary.notes.push_back(name + js.method_description);
    for (const std::string& note : js.notes) summary.notes.push_back(name + note);
    for (const std::string& warning : js.warnings) summary.warnings.push_back(name + warning);
    for (const std::string& bound : js.at_bounds) {
      summary.at_bounds.push_back(bound + Format("@%d", j + 1));
    }
    summary.iterations += js.iterations;
    summary.num_evaluations += js.num_evaluations;
    summary.prior_tightenings = std::max(summary.prior_tightenings, js.prior_tightenings);
    summary.hyperparameter_rows = js.hyperparameter_rows;
    summary.cv_candidates = js.cv_candidates;
    initial += js.initial_negative_log_evidence;
    final_evidence += js.final_negative_log_evidence;
    final_prior += js.final_negative_log_prior;
    cv_nmse += js.cv_mean_nmse / N;
    map = map || js.final_negative_log_prior != 0.0;
    if (js.termination != FitTermination::kConverged &&
        fit->search_end() == FitTermination::kConverged) {
      fit->set_search_end(js.termination);
    }
    messages += (messages.empty() ? "" : "; ") + name + js.message;
    summary.joints.push_back(std::move(js));
    sets.push_back(std::move(r.set));
  }
  h->per_output = std::move(sets);
  fit->set_search_message(messages);
  switch (options.method) {
    case HyperparameterMethod::kEvidence:
      summary.initial_negative_log_evidence = initial;
      summary.final_negative_log_evidence = final_evidence;
      summary.final_negative_log_prior = final_prior;
      summary.method_description =
          std::string("type-II maximum likelihood") + (map ? kMapPhrase : "") +
          ", one set of hyper-parameters per joint";
      break;
    case HyperparameterMethod::kCrossValidation:
      summary.cv_mean_nmse = cv_nmse;
      summary.method_description = Format(
          "blocked %d-fold cross-validation, one set of hyper-parameters per joint (mean "
          "held-out nMSE %.4g)",
          options.cv_folds, cv_nmse);
      break;
    case HyperparameterMethod::kFixed:
      summary.method_description = std::string(kFixedDescription) + ", one set per joint";
      break;
  }
  return true;
}

void CheckData(const RobotModel& model, const ConstMatrixRef& states, const ConstMatrixRef& torques,
               const ConstVectorRef& t) {
  const int N = model.num_joints();
  RequireSize("FitModel states", states.cols(), 3 * N, "columns (q, qd, qdd of each joint)");
  RequireSize("FitModel torques", torques.cols(), N, "columns (joints)");
  RequireSize("FitModel torques", torques.rows(), states.rows(), "rows (as in the states)");
  if (t.size() != 0) RequireSize("FitModel t", t.size(), states.rows(), "times (one per row)");
  if (states.rows() < 1) throw std::invalid_argument("FitModel: expected at least 1 row, got 0");
  RequireFinite("FitModel states", states);
  RequireFinite("FitModel torques", torques);
  RequireFinite("FitModel t", t);
}

// A joint whose velocity (or acceleration) RMS over the log is at most this, in rad/s (rad/s^2;
// m/s, m/s^2 for a prismatic joint), stands still (does not accelerate) as far as any model can
// tell: a log of static poses, or rows that all fall on via points.
constexpr double kStillJointRms = 1e-6;

// The warning for joints whose 2 sigma band covered less than min_coverage of their held-out
// torques in the held-out check, of its blocks or of the fastest rows (none when it did not
// run or every band covered enough); with calibrated, the same finding as a note on the bands
// before their calibration.
std::vector<std::string> NarrowBandWarnings(const FitCheck& check, double min_coverage,
                                            bool calibrated) {
  if (!check.ran) return {};
  // "joints 5 and 6 covered only 71%, 79% of <what>", or empty.
  auto narrow_text = [min_coverage](const Vector& coverage, const char* what) {
    std::vector<int> narrow;
    std::string percents;
    for (int j = 0; j < static_cast<int>(coverage.size()); ++j) {
      if (coverage[j] < min_coverage) {
        percents += Format("%s%.0f%%", narrow.empty() ? "" : ", ", 100.0 * coverage[j]);
        narrow.push_back(j + 1);
      }
    }
    if (narrow.empty()) return std::string();
    return Format("%s covered only %s of %s", internal::JointsText(narrow).c_str(), percents.c_str(),
                  what);
  };
  const std::string blocks = narrow_text(check.coverage, "the held-out torques");
  const std::string fastest =
      narrow_text(check.fastest_coverage, "the fastest rows' torques (fitted on the slower rows)");
  if (blocks.empty() && fastest.empty()) return {};
  const std::string finding =
      "the 2 sigma band of " + (blocks.empty() ? fastest : blocks) +
      (!blocks.empty() && !fastest.empty() ? ", and of " + fastest : std::string());
  if (calibrated) return {"before their calibration, " + finding};
  return {finding +
          " (held-out check; about 95% when calibrated): the model claims more certainty than "
          "it has on motion it was not fitted on"};
}

// Sets the model's latent variance scale from the held-out check (FitOptions::calibrate_bands;
// a joint the check did not count keeps 1) and says which joints' bands it widened.
std::string CalibrateBands(const FitCheck& check, double target, RobotModel* model) {
  Vector scale = Vector::Ones(model->num_joints());
  for (int j = 0; j < model->num_joints() && j < check.latent_variance_scale.size(); ++j) {
    const double kappa = check.latent_variance_scale[j];
    if (std::isfinite(kappa) && kappa > 1.0) scale[j] = kappa;
  }
  model->SetLatentVarianceScale(scale);
  const std::string text = CalibratedBandsText(*model);
  if (text.empty()) return {};
  return Format("2 sigma bands calibrated on the held-out blocks: %s (each band then covers at "
                "least %.0f%% of its held-out torques)",
                text.c_str(), 100.0 * target);
}

// Warnings for joints the log never moves or never accelerates (kStillJointRms): the torques
// that act only with motion (friction, Coriolis and centrifugal; inertia) are not in its data,
// so whatever the model predicts of them on other motion rests on its prior alone.
std::vector<std::string> StillJointWarnings(const ConstMatrixRef& states) {
  const int N = static_cast<int>(states.cols() / 3);
  const int rows = static_cast<int>(states.rows());
  const auto rms = [&states, rows](int column) {
    return std::sqrt(states.col(column).squaredNorm() / rows);
  };
  std::vector<int> still;         // velocity at rounding level
  std::vector<int> unaccelerated;  // acceleration at rounding level, velocity not
  double largest_velocity = 0.0;
  double largest_acceleration = 0.0;
  for (int j = 0; j < N; ++j) {
    const double velocity = rms(N + j);
    const double acceleration = rms(2 * N + j);
    if (velocity <= kStillJointRms) {
      still.push_back(j + 1);
      largest_velocity = std::max(largest_velocity, velocity);
    } else if (acceleration <= kStillJointRms) {
      unaccelerated.push_back(j + 1);
      largest_acceleration = std::max(largest_acceleration, acceleration);
    }
  }
  const auto size_text = [](const char* what, double largest, const char* unit) {
    return largest == 0.0 ? Format("%s zero on every row", what)
                          : Format("%s RMS at most %.2g %s", what, largest, unit);
  };
  std::vector<std::string> warnings;
  if (!still.empty()) {
    warnings.push_back(Format(
        "%s never move%s in the %d rows (%s): the fit sees none of the friction, inertial or "
        "velocity (Coriolis, centrifugal) torques of %s, and the model's predictions of them on "
        "motion rest on its prior alone",
        internal::JointsText(still).c_str(), still.size() == 1 ? "s" : "", rows,
        size_text("velocity", largest_velocity, "rad/s").c_str(),
        still.size() == 1 ? "its motion" : "their motion"));
  }
  if (!unaccelerated.empty()) {
    warnings.push_back(Format(
        "%s never accelerate%s in the %d rows (%s): the fit sees no inertial torque of %s, and "
        "the model's predictions of it on accelerating motion rest on its prior alone",
        internal::JointsText(unaccelerated).c_str(), unaccelerated.size() == 1 ? "s" : "", rows,
        size_text("acceleration", largest_acceleration, "rad/s^2").c_str(),
        unaccelerated.size() == 1 ? "its acceleration" : "their accelerations"));
  }
  return warnings;
}


}  // namespace

const char* ToString(HyperparameterMethod method) {
  switch (method) {
    case HyperparameterMethod::kEvidence:
      return "ml";
    case HyperparameterMethod::kCrossValidation:
      return "cv";
    case HyperparameterMethod::kFixed:
      return "fixed";
  }
  return "unknown";
}

bool FromString(const std::string& text, HyperparameterMethod* method) {
  for (HyperparameterMethod m : {HyperparameterMethod::kEvidence,
                                 HyperparameterMethod::kCrossValidation,
                                 HyperparameterMethod::kFixed}) {
    if (text == ToString(m)) {
      *method = m;
      return true;
    }
  }
  return false;
}

const char* ToString(FitTermination termination) {
  switch (termination) {
    case FitTermination::kConverged:
      return "converged";
    case FitTermination::kMaxIterations:
      return "max_iterations";
    case FitTermination::kLineSearchFailed:
      return "line_search_failed";
    case FitTermination::kUserAbort:
      return "user_abort";
    case FitTermination::kFailure:
      return "failure";
  }
  return "unknown";
}

bool FitOptions::IsValid(std::string* error) const {
  auto fail = [error](const std::string& message) {
    if (error != nullptr) *error = message;
    return false;
  };
  std::string reason;
  if (method == HyperparameterMethod::kEvidence && !evidence.IsValid(&reason)) {
    return fail("FitOptions::evidence: " + reason);
  }
  if (!check.IsValid(&reason)) return fail("FitOptions::check: " + reason);
  if (max_prior_tightenings < 0) {
    return fail("FitOptions::max_prior_tightenings: expected >= 0, got " +
                std::to_string(max_prior_tightenings));
  }
  if (!(std::isfinite(prior_tightening_factor) && prior_tightening_factor > 1.0)) {
    return fail(Format("FitOptions::prior_tightening_factor: expected a finite value > 1, got %g",
                       prior_tightening_factor));
  }
  if (max_evidence_rows < 0) {
    return fail("FitOptions::max_evidence_rows: expected >= 0 (0: every row), got " +
                std::to_string(max_evidence_rows));
  }
  if (cv_folds < 2) {
    return fail("FitOptions::cv_folds: expected >= 2, got " + std::to_string(cv_folds));
  }
  if (method == HyperparameterMethod::kCrossValidation && cv_noise_levels.empty()) {
    return fail("FitOptions::cv_noise_levels: expected at least one level, got none");
  }
  for (double level : cv_noise_levels) {
    if (!(level > 0.0) || !std::isfinite(level)) {
      return fail("FitOptions::cv_noise_levels: expected finite levels > 0, got " +
                  Format("%g", level));
    }
  }
  for (double offset : cv_shape_offsets) {
    if (!std::isfinite(offset)) {
      return fail("FitOptions::cv_shape_offsets: expected finite offsets, got " +
                  Format("%g", offset));
    }
  }
  if (num_threads < 1) {
    return fail("FitOptions::num_threads: expected >= 1, got " + std::to_string(num_threads));
  }
  return true;
}

bool FitSummary::IsUsable() const {
  return termination == FitTermination::kConverged ||
         termination == FitTermination::kMaxIterations ||
         termination == FitTermination::kLineSearchFailed;
}

std::string FitSummary::BriefReport() const {
  std::string text = Format("fit (%s): %s", ToString(method), ToString(termination));
  if (method == HyperparameterMethod::kEvidence && std::isfinite(final_negative_log_evidence)) {
    text += Format(", %d iterations, %d evaluations, -log p(Y) %.6g -> %.6g", iterations,
                   num_evaluations, initial_negative_log_evidence, final_negative_log_evidence);
  }
  if (method == HyperparameterMethod::kCrossValidation && cv_candidates > 0) {
    text += Format(", %d candidates, held-out nMSE %.4g", cv_candidates, cv_mean_nmse);
  }
  text += Format(", %d of %d rows in the model, %.2f s", model_rows, rows, total_seconds);
  if (!warnings.empty()) text += Format(" (%d warnings)", static_cast<int>(warnings.size()));
  if (!IsUsable()) text += ": " + message;
  return text;
}

Matrix ModelInputs(const RobotModel& model, const ConstMatrixRef& states, const ConstVectorRef& t) {
  RequireSize("ModelInputs states", states.cols(), 3 * model.num_joints(),
              "columns (q, qd, qdd of each joint)");
  if (!model.uses_time()) return states;
  if (t.size() == 0) {
    throw std::invalid_argument("the model uses the time (effects '" +
                                ToString(model.spec().effects) + "'), but no times were given");
  }
  RequireSize("ModelInputs t", t.size(), states.rows(), "times (one per row)");
  Matrix X(states.rows(), states.cols() + 1);
  X << states, t;
  return X;
}

FitSummary FitModel(const FitOptions& options, const ConstMatrixRef& states,
                    const ConstMatrixRef& torques, const ConstVectorRef& t, RobotModel* model) {
  std::string error;
  if (!options.IsValid(&error)) throw std::invalid_argument(error);
  if (model == nullptr) throw std::invalid_argument("FitModel: model is null");
  CheckData(*model, states, torques, t);
  const bool euler_model = model->spec().base == BaseModel::kLagk;
  const bool regressor_model = model->regressor_map() != nullptr;
  const bool kernel_model = model->feature_map() == nullptr && !regressor_model && !euler_model;
  if (options.method == HyperparameterMethod::kCrossValidation && (regressor_model || euler_model)) {
    throw std::invalid_argument(
        "cross-validation is not available for '" + ToString(model->spec()) +
        "' (use type-II maximum likelihood, the default, or fixed hyper-parameters)");
  }
  if (options.method == HyperparameterMethod::kCrossValidation && kernel_model) {
    throw std::invalid_argument(
        "cross-validation needs a model with an explicit feature map (motor, or pol up to 3 "
        "joints); '" +
        ToString(model->spec()) + "' for " + std::to_string(model->num_joints()) +
        " joints runs in function space (use type-II maximum likelihood or fixed "
        "hyper-parameters)");
  }
  if (options.per_joint && (regressor_model || euler_model)) {
    throw std::invalid_argument("per-joint hyper-parameters: model '" + ToString(model->spec()) +
                                "' shares its parameters across joints (pol, motor, rbf and "
                                "rbfs have one set per joint)");
  }
  const Matrix X = ModelInputs(*model, states, t);
  // Y: the torques, which RobotModel::Fit and the held-out check take; Yr: what the model's
  // GP learns, the torques less the prior mean of rbd+<base>, the targets of the search.
  const Matrix Y = torques;
  const Matrix Yr = model->prior_mean() ? Matrix(Y - model->PriorMeanRows(X)) : Y;

  Fit fit(options, model);
  FitSummary& summary = fit.summary();
  summary.rows = static_cast<int>(X.rows());
  for (std::string& warning : StillJointWarnings(states)) {
    summary.warnings.push_back(std::move(warning));
  }
  Hyperparameters h = model->DefaultHyperparameters(Yr);
  if (options.output_scaling == OutputScaling::kUnit) h.log_output_scale.setZero();
  std::string failure;
  bool go_on = true;
  if (options.per_joint) {
    go_on = PerJointSearch(X, Y, Yr, t, kernel_model, &fit, &h, &failure);
  } else switch (options.method) {
    case HyperparameterMethod::kEvidence:
      go_on = euler_model       ? EulerLagrangeByEvidence(X, Yr, &fit, &h, &failure)
              : regressor_model ? RegressorByEvidence(X, Y, Yr, &fit, &h, &failure)
              : kernel_model    ? KernelByEvidence(X, Y, Yr, &fit, &h, &failure)
                                : FeatureMapByEvidence(X, Y, Yr, &fit, &h, &failure);
      break;
    case HyperparameterMethod::kCrossValidation:
      go_on = FeatureMapByCrossValidation(X, Yr, t, &fit, &h, &failure);
      break;
    case HyperparameterMethod::kFixed:
      if (euler_model) {
        const EulerLagrangeGPOptions o = EulerLagrangeOptions(options, *model);
        std::vector<double> sigmas = o.sigmas;
        std::sort(sigmas.begin(), sigmas.end());
        const double sigma = sigmas[sigmas.size() / 2];
        h = ToHyperparameters(EulerLagrangeStart(X, Yr, o, sigma));
        summary.method_description =
            "fixed defaults (sigma " + Number(sigma) +
            ", the torques' mean square shared by the parts, noise 10% of each joint's RMS)";
      } else {
        summary.method_description = kFixedDescription;
      }
      fit.set_search_message("fixed hyper-parameters: nothing to search");
      break;
  }
  // Each joint's search checked its own candidates; the check of all joints with their sets
  // gives the coverage of the model as fitted.
  if (go_on && !fit.aborted() &&
      (options.method != HyperparameterMethod::kEvidence || euler_model || options.per_joint) &&
      options.check.enabled) {
    summary.check = CheckOnHeldOutBlocks(*model, h, X, Y, options.check);
    if (summary.check.ran && !summary.check.passed) {
      summary.warnings.push_back(summary.check.message +
                                 ". Predictions away from the training path may be far off.");
    }
  }
  const bool calibrate = options.calibrate_bands && summary.check.ran;
  for (std::string& line : NarrowBandWarnings(summary.check, options.check.min_coverage,
                                              calibrate)) {
    (calibrate ? summary.notes : summary.warnings).push_back(std::move(line));
  }
  summary.hyperparameter_seconds = fit.seconds();
  if (fit.aborted()) return fit.Aborted();
  if (!go_on) return fit.Finish(FitTermination::kFailure, failure);

  if (!fit.Report(Format("fitting the model to %d rows", static_cast<int>(X.rows())))) {
    return fit.Aborted();
  }
  const Status status = model->Fit(X, Y, h);
  if (status != Status::kOk) {
    return fit.Finish(
        FitTermination::kFailure,
        std::string("fitting the model failed: ") + ToString(status) +
            " (the posterior precision is not numerically positive definite; try fixed "
            "hyper-parameters, or check the data for duplicated rows)");
  }
  summary.model_rows = static_cast<int>(model->gp().fit_rows());
  if (calibrate) {
    const std::string note = CalibrateBands(summary.check, options.check.target_coverage, model);
    if (!note.empty()) {
      summary.notes.push_back(note);
      if (!fit.Report(note)) return fit.Aborted();
    }
  }
  if (model->gp().subsampled()) {
    const std::string note = Format(
        "the function-space form was fitted on %d evenly spaced rows of %d (its row limit: the "
        "fit costs O(m^3) time and O(m^2) memory); a model with an explicit feature map (motor, "
        "pol up to 3 joints) learns from every row",
        static_cast<int>(model->gp().fit_rows()), static_cast<int>(model->gp().data_rows()));
    summary.notes.push_back(note);
    if (!fit.Report(note)) return fit.Aborted();
  }
  return fit.Finish(fit.search_end(), fit.search_message());
}

std::string CalibratedBandsText(const RobotModel& model) {
  const Vector& scale = model.latent_variance_scale();
  std::vector<int> widened;
  std::string factors;
  for (int j = 0; j < static_cast<int>(scale.size()); ++j) {
    if (scale[j] == 1.0) continue;
    factors += Format("%s%.3g", widened.empty() ? "" : ", ", scale[j]);
    widened.push_back(j + 1);
  }
  if (widened.empty()) return {};
  return "the latent variance of " + internal::JointsText(widened) + " scaled by " + factors;
}

FittedModel FitModel(const ModelSpec& spec, const ConstMatrixRef& states,
                     const ConstMatrixRef& torques, const ConstVectorRef& t,
                     const FitOptions& options) {
  FittedModel out{RobotModel(spec, static_cast<int>(torques.cols()), options.model), {}};
  out.summary = FitModel(options, states, torques, t, &out.model);
  return out;
}

namespace {

// FitReport's lines on the search, the same for every model: how the hyper-parameters were
// chosen, the notes, the held-out check and the warnings.
void ReportSearch(const FitSummary& summary, std::ostream& os) {
  os << "hyper        " << summary.method_description
     << Format(", %.2f s", summary.total_seconds) << "\n";
  for (const auto& note : summary.notes) os << "             " << note << "\n";
  if (summary.check.ran) os << "check        " << summary.check.message << "\n";
  for (const auto& warning : summary.warnings) os << "warning      " << warning << "\n";
}

// FitReport of an rbd model: the prior widths, each joint's noise, the friction and effect
// coefficients, how many rigid-body directions the data identified, and whether the identified
// inertial parameters are physically consistent.
void ReportRegressor(const RobotModel& model, const FitSummary& summary, std::ostream& os) {
  const SemiParametricRegressorMap& map = *model.regressor_map();
  const auto* rigid = dynamic_cast<const RigidBodyRegressorMap*>(&map.base());
  const RegressorGP& gp = *model.gp().regressor();
  const Hyperparameters& h = model.hyperparameters();
  const int N = model.num_joints();
  const int P = map.base().dim();
  os << "parameters   P = " << map.dim() << " (" << P
     << (rigid ? " rigid-body of the chain " + rigid->chain().root() + " -> " +
                     rigid->chain().tip()
               : std::string(" of the Lagrangian, shared by all joints"))
     << ", regressor form)\n";
  ReportSearch(summary, os);
  std::vector<std::vector<std::string>> rows = {{"parameter", "value"}};
  const auto blocks = map.blocks();
  for (size_t b = 0; b < blocks.size(); ++b) {
    rows.push_back({"log_block_scale_" + blocks[b].name,
                    Number(h.log_block_scale[static_cast<Eigen::Index>(b)])});
  }
  os << Table(rows, 4);
  os << "noise std   ";
  const Vector noise_std = h.noise_stds();
  for (int j = 0; j < N; ++j) os << Format(" tau%d %.4g", j + 1, noise_std[j]);
  os << "  (one per joint)\n";
  os << "log marginal likelihood " << Format("%.6g", gp.LogMarginalLikelihood()) << " nats\n";
  os << "identified   " << gp.IdentifiedDirections() << " of " << map.dim()
     << " parameter directions are determined by the data better than by the prior"
     << (rigid ? " (the rest, e.g. inertial combinations the motion does not excite, stay at "
                 "the URDF's values)\n"
               : "\n");
  const Vector theta = gp.parameters();
  const Vector std_dev = gp.ParameterStd();
  if (rigid) {
    const PhysicalConsistency consistency =
        CheckPhysicalConsistency(rigid->chain(), theta.head(P), 200, 1);
    os << "consistency  " << consistency.Summary() << "\n";
  }
  const auto names = model.ParametricFeatureNames();
  if (!names.empty()) {
    os << "coefficients (posterior mean +- std):\n";
    std::vector<std::vector<std::string>> coef = {{"feature", "value"}};
    const std::vector<std::string> all = map.parameter_names();
    for (int k = P; k < map.dim(); ++k) {
      coef.push_back({all[static_cast<size_t>(k)],
                      Format("%.4g +- %.2g", theta[k], std_dev[k])});
    }
    os << Table(coef, 4);
  }
}

}  // namespace

bool StartFromModel(const RobotModel& model, FitOptions* options) {
  if (!model.fitted() || model.gp().euler_lagrange() == nullptr) return false;
  options->euler_lagrange.start = model.gp().euler_lagrange()->hyperparameters();
  return true;
}

std::string FitReport(const RobotModel& model, const FitSummary& summary) {
  std::ostringstream os;
  const int N = model.num_joints();
  if (!summary.IsUsable() || !model.fitted()) {
    os << "not fitted: " << ToString(summary.termination) << ": " << summary.message << "\n";
    return os.str();
  }
  const GaussianProcess& gp = model.gp();
  if (model.regressor_map()) {
    ReportRegressor(model, summary, os);
    return os.str();
  }
  if (model.feature_map()) {
    os << "features     D = " << model.feature_map()->dim() << " (" << ToString(gp.form())
       << " form)\n";
  } else if (const EulerLagrangeGP* euler = gp.euler_lagrange()) {
    os << "features     none: one GP of all joints on the Euler-Lagrange kernel ("
       << ToString(gp.form()) << " form, " << euler->inputs().rows() << " rows, "
       << (euler->dtc() ? Format("through %d inducing states",
                                 static_cast<int>(euler->states().rows()))
                        : std::string("exact"))
       << ")\n";
  } else {
    os << "features     none: kernel model (" << ToString(gp.form()) << " form, "
       << gp.fit_rows() << " stored points)\n";
  }
  ReportSearch(summary, os);
  std::vector<std::vector<std::string>> rows = {{"parameter", "value"}};
  const Hyperparameters& h = model.hyperparameters();
  if (model.per_joint()) {
    // One column per joint, each its own set (one output scale).
    rows[0].resize(1);
    for (int j = 1; j <= N; ++j) rows[0].push_back(Format("tau%d", j));
    // The names of one joint's set: a feature map's single-output layout, or the kernel's
    // parameters, then the noise and the output scale.
    FreeHyperparameters all;
    all.output_scales = true;
    std::optional<HyperparameterLayout> layout;
    std::vector<std::string> names;
    if (model.feature_map()) {
      layout.emplace(*model.feature_map(), 1, all);
      names = layout->names();
      for (std::string& name : names) {
        if (name.rfind("log_output_scale", 0) == 0) name = "log_output_scale";
      }
    } else {
      names = model.kernel()->parameter_names();
      names.push_back("log_noise_std");
      names.push_back("log_output_scale");
    }
    std::vector<Vector> values;
    for (const Hyperparameters& own : h.per_output) {
      if (layout) {
        values.push_back(layout->Flatten(own));
      } else {
        Vector v(own.shape.size() + 2);
        v << own.shape, own.log_noise_std, own.log_output_scale[0];
        values.push_back(v);
      }
    }
    for (size_t i = 0; i < names.size(); ++i) {
      std::vector<std::string> row = {names[i]};
      for (const Vector& v : values) row.push_back(Number(v[static_cast<Eigen::Index>(i)]));
      rows.push_back(std::move(row));
    }
  } else if (model.feature_map()) {
    FreeHyperparameters all;
    all.output_scales = true;
    const HyperparameterLayout layout(*model.feature_map(), N, all);
    const Vector values = layout.Flatten(h);
    for (int i = 0; i < layout.size(); ++i) {
      rows.push_back({layout.names()[static_cast<size_t>(i)], Number(values[i])});
    }
  } else if (gp.euler_lagrange() != nullptr) {
    const auto names =
        EulerLagrangeParameterNames(N, model.spec().friction, model.effect_map() != nullptr);
    for (Eigen::Index i = 0; i < h.shape.size(); ++i) {
      rows.push_back({names[static_cast<size_t>(i)], Number(h.shape[i])});
    }
    for (int j = 0; j < N; ++j) {
      rows.push_back({Format("log_noise_std_%d", j + 1), Number(h.log_output_scale[j])});
    }
  } else {
    const Vector theta = model.kernel()->parameters();
    const auto names = model.kernel()->parameter_names();
    for (Eigen::Index i = 0; i < theta.size(); ++i) {
      rows.push_back({names[static_cast<size_t>(i)], Number(theta[i])});
    }
    rows.push_back({"log_noise_std", Number(h.log_noise_std)});
    for (int j = 0; j < N; ++j) {
      rows.push_back({Format("log_output_scale_%d", j + 1), Number(h.log_output_scale[j])});
    }
  }
  os << Table(rows, 4);
  os << "noise std   ";
  const Vector noise_std = h.noise_stds();
  for (int j = 0; j < N; ++j) os << Format(" tau%d %.4g", j + 1, noise_std[j]);
  os << "  (sigma_n times the output scale)\n";
  os << "log marginal likelihood " << Format("%.6g", gp.LogMarginalLikelihood()) << " nats\n";
  const auto names = model.ParametricFeatureNames();
  if (model.has_components() && !names.empty()) {
    os << "coefficients (posterior mean +- std, per joint torque):\n";
    std::vector<std::vector<std::string>> coef = {{"feature"}};
    for (int j = 1; j <= N; ++j) coef[0].push_back(Format("tau%d", j));
    for (const auto& name : names) {
      std::vector<std::string> row = {name};
      for (int j = 1; j <= N; ++j) {
        const auto [value, std] = model.Coefficient(name, j);
        row.push_back(Format("%.4g +- %.2g", value, std));
      }
      coef.push_back(row);
    }
    os << Table(coef, 4);
  }
  return os.str();
}

namespace {

using Json = nlohmann::ordered_json;

// JSON has no NaN or infinity: such a number is written as null.
Json JsonNumber(double v) { return std::isfinite(v) ? Json(v) : Json(nullptr); }

// Every field of a FitSummary, with each joint's own summary under "joints" (per_joint).
Json SummaryJson(const FitSummary& summary) {
  auto number = [](double v) { return JsonNumber(v); };
  auto numbers = [](const Vector& v) {
    Json list = Json::array();
    for (Eigen::Index k = 0; k < v.size(); ++k) list.push_back(JsonNumber(v[k]));
    return list;
  };
  Json s;
  s["termination"] = ToString(summary.termination);
  s["usable"] = summary.IsUsable();
  s["message"] = summary.message;
  s["method"] = ToString(summary.method);
  s["method_description"] = summary.method_description;
  s["notes"] = summary.notes;
  s["warnings"] = summary.warnings;
  s["iterations"] = summary.iterations;
  s["num_evaluations"] = summary.num_evaluations;
  s["initial_negative_log_evidence"] = number(summary.initial_negative_log_evidence);
  s["final_negative_log_evidence"] = number(summary.final_negative_log_evidence);
  s["final_negative_log_prior"] = number(summary.final_negative_log_prior);
  s["at_bounds"] = summary.at_bounds;
  s["starts"] = Json::array();
  for (const MaximumLikelihoodStart& start : summary.starts) {
    s["starts"].push_back({{"usable", start.usable},
                           {"termination", ToString(start.termination)},
                           {"iterations", start.iterations},
                           {"num_evaluations", start.num_evaluations},
                           {"negative_log_likelihood", number(start.negative_log_likelihood)},
                           {"negative_log_prior", number(start.negative_log_prior)},
                           {"objective", number(start.objective)}});
  }
  s["best_start"] = summary.best_start;
  s["chosen_start"] = summary.chosen_start;
  s["prior_tightenings"] = summary.prior_tightenings;
  s["check"] = {{"ran", summary.check.ran},
                {"passed", summary.check.passed},
                {"rows", summary.check.rows},
                {"worst_joint", summary.check.worst_joint},
                {"worst_fraction", number(summary.check.worst_fraction)},
                {"worst_confident_fraction", number(summary.check.worst_confident_fraction)},
                {"worst_excursion", number(summary.check.worst_excursion)},
                {"coverage", numbers(summary.check.coverage)},
                {"fastest_coverage", numbers(summary.check.fastest_coverage)},
                {"latent_variance_scale", numbers(summary.check.latent_variance_scale)},
                {"message", summary.check.message}};
  s["cv_mean_nmse"] = number(summary.cv_mean_nmse);
  s["cv_candidates"] = summary.cv_candidates;
  s["rows"] = summary.rows;
  s["hyperparameter_rows"] = summary.hyperparameter_rows;
  s["model_rows"] = summary.model_rows;
  s["hyperparameter_seconds"] = number(summary.hyperparameter_seconds);
  s["total_seconds"] = number(summary.total_seconds);
  s["joints"] = Json::array();
  for (const FitSummary& joint : summary.joints) s["joints"].push_back(SummaryJson(joint));
  return s;
}

}  // namespace

std::string ToJson(const RobotModel& model, const FitSummary& summary) {
  auto number = [](double v) { return JsonNumber(v); };
  Json j;
  j["model"] = ModelLabel(model.spec());
  j["num_joints"] = model.num_joints();
  j["form"] = model.fitted() ? Json(ToString(model.gp().form())) : Json(nullptr);
  if (model.regressor_map()) {
    j["size"] = {{"parameters", model.regressor_map()->dim()}};
  } else if (model.feature_map()) {
    j["size"] = {{"features", model.feature_map()->dim()}};
  } else if (model.fitted() && model.gp().euler_lagrange() != nullptr) {
    const EulerLagrangeGP& euler = *model.gp().euler_lagrange();
    j["size"] = {{"rows", euler.inputs().rows()},
                 {"inducing_states", euler.dtc() ? euler.states().rows() : 0}};
  } else {
    j["size"] = Json::object();
  }
  j["per_joint"] = model.fitted() && model.per_joint();
  j["summary"] = SummaryJson(summary);
  if (summary.IsUsable() && model.fitted()) {
    j["log_marginal_likelihood"] = number(model.gp().LogMarginalLikelihood());
    const Hyperparameters& h = model.hyperparameters();
    Json noise = Json::array();
    for (double value : h.noise_stds()) noise.push_back(number(value));
    j["noise_std"] = noise;
    j["coefficients"] = Json::array();
    if (model.has_components()) {
      for (const FeatureCoefficient& c : model.Coefficients()) {
        j["coefficients"].push_back(
            {{"name", c.name}, {"joint", c.joint}, {"value", number(c.value)}, {"std", number(c.std)}});
      }
    }
  }
  return j.dump(2) + "\n";
}

}  // namespace structgp
