#include "structgp/hyper/marginal_likelihood.h"

#include <ceres/first_order_function.h>
#include <ceres/gradient_problem.h>
#include <ceres/gradient_problem_solver.h>
#include <ceres/iteration_callback.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <sstream>
#include <stdexcept>

#include "structgp/core/validate.h"
#include "structgp/model/kernel_gp.h"

namespace structgp {
namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();
// A perturbed start moves each entry at most this fraction of the way to its bound, so that
// it starts strictly inside the box.
constexpr double kStartBoundFraction = 0.9;
// Hyperparameters::Validate accepts log sigma_n in the open interval (-50, 50).
constexpr double kNoiseLimit = 50.0;

bool BoundsValid(const char* name, const LogBounds& bounds, double limit, std::string* error) {
  if (std::isfinite(bounds.lower) && std::isfinite(bounds.upper) && bounds.lower < bounds.upper &&
      bounds.lower > -limit && bounds.upper < limit) {
    return true;
  }
  if (error != nullptr) {
    std::ostringstream os;
    os << "MaximumLikelihoodOptions::" << name << ": expected finite lower < upper";
    if (std::isfinite(limit)) os << " inside (" << -limit << ", " << limit << ")";
    os << ", got [" << bounds.lower << ", " << bounds.upper << "]";
    *error = os.str();
  }
  return false;
}

bool ToleranceValid(const char* name, double value, std::string* error) {
  if (std::isfinite(value) && value >= 0.0) return true;
  if (error != nullptr) {
    std::ostringstream os;
    os << "MaximumLikelihoodOptions::" << name << ": expected a finite value >= 0, got " << value;
    *error = os.str();
  }
  return false;
}

const char* BoundsName(HyperparameterGroup group) {
  switch (group) {
    case HyperparameterGroup::kShape:
      return "shape_bounds";
    case HyperparameterGroup::kBlockScale:
      return "block_scale_bounds";
    case HyperparameterGroup::kNoise:
      return "noise_bounds";
    case HyperparameterGroup::kOutputScale:
      return "output_scale_bounds";
  }
  return "";
}

const LogBounds& BoundsOf(const MaximumLikelihoodOptions& options, HyperparameterGroup group) {
  switch (group) {
    case HyperparameterGroup::kShape:
      return options.shape_bounds;
    case HyperparameterGroup::kBlockScale:
      return options.block_scale_bounds;
    case HyperparameterGroup::kNoise:
      return options.noise_bounds;
    case HyperparameterGroup::kOutputScale:
      return options.output_scale_bounds;
  }
  return options.shape_bounds;
}

// True when x is finite and inside [lower, upper] entry by entry.
bool InsideBox(const Eigen::Map<const Vector>& x, const Vector& lower, const Vector& upper) {
  return x.allFinite() && (x.array() >= lower.array()).all() && (x.array() <= upper.array()).all();
}

// Throws std::invalid_argument naming the first free starting value outside its bounds.
void RequireStartInside(const char* who, const Vector& x, const Vector& lower, const Vector& upper,
                        const std::vector<std::string>& names,
                        const std::vector<std::string>& bounds_names) {
  for (Eigen::Index i = 0; i < x.size(); ++i) {
    if (x[i] >= lower[i] && x[i] <= upper[i]) continue;
    std::ostringstream os;
    os << who << ": the starting value of " << names[static_cast<size_t>(i)] << " is " << x[i]
       << ", outside its bounds [" << lower[i] << ", " << upper[i]
       << "]; start inside them or widen MaximumLikelihoodOptions::"
       << bounds_names[static_cast<size_t>(i)];
    throw std::invalid_argument(os.str());
  }
}

// The Ceres view of an objective. Remembers the best point it has seen, so that the result
// never depends on which iterate Ceres reports back.
template <typename Objective>
class CeresFunction final : public ceres::FirstOrderFunction {
 public:
  explicit CeresFunction(const Objective* objective)
      : objective_(objective), best_x_(objective->num_parameters()) {}

  bool Evaluate(const double* x, double* cost, double* gradient) const override {
    if (!objective_->Evaluate(x, cost, gradient)) return false;
    if (*cost < best_cost_) {
      best_cost_ = *cost;
      best_x_ = Eigen::Map<const Vector>(x, NumParameters());
    }
    return true;
  }
  int NumParameters() const override { return objective_->num_parameters(); }

  bool has_best() const { return std::isfinite(best_cost_); }
  const Vector& best_x() const { return best_x_; }

 private:
  const Objective* objective_;
  mutable Vector best_x_;
  mutable double best_cost_ = kInfinity;
};

class ProgressPrinter final : public ceres::IterationCallback {
 public:
  explicit ProgressPrinter(double num_observations) : n_(num_observations) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& s) override {
    std::fprintf(stderr,
                 "ML-II iteration %4d  -log p(Y) %.10g  max|d/dx| %.3e  |step| %.3e  "
                 "line search evaluations %d\n",
                 s.iteration, s.cost * n_, s.gradient_max_norm * n_, s.step_norm,
                 s.line_search_function_evaluations);
    return ceres::SOLVER_CONTINUE;
  }

 private:
  double n_;
};

// MaximumLikelihoodOptions::iteration_callback as a Ceres callback (SOLVER_ABORT on false).
class UserCallback final : public ceres::IterationCallback {
 public:
  UserCallback(const std::function<bool(int, double)>* callback, double num_observations)
      : callback_(callback), n_(num_observations) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& s) override {
    return (*callback_)(s.iteration, s.cost * n_) ? ceres::SOLVER_CONTINUE : ceres::SOLVER_ABORT;
  }

 private:
  const std::function<bool(int, double)>* callback_;
  double n_;
};

// The outcome of one LBFGS run.
struct Run {
  MaximumLikelihoodTermination termination = MaximumLikelihoodTermination::kInitialPointFailed;
  std::string message;
  int iterations = 0;
  Vector x;          // best point evaluated
  double cost = 0.0;  // objective (divided by n) at x
  Vector gradient;   // of the objective at x (divided by n)
  bool aborted = false;
};

// LBFGS on the objective from x0, which lies inside the bounds. Returns kInitialPointFailed
// (x = x0) when the objective cannot be evaluated at x0.
template <typename Objective>
Run RunLbfgs(const Objective& objective, const MaximumLikelihoodOptions& options,
             const Vector& x0, double seconds_left) {
  Run run;
  run.x = x0;
  const int num_parameters = objective.num_parameters();
  run.gradient = Vector::Zero(num_parameters);
  if (!objective.Evaluate(x0.data(), &run.cost, run.gradient.data())) {
    run.cost = kInfinity;
    run.message = "the evidence could not be evaluated at the starting point";
    return run;
  }
  if (num_parameters == 0) {
    run.termination = MaximumLikelihoodTermination::kNoFreeParameters;
    run.message = "no hyper-parameter is free";
    return run;
  }
  const double n = objective.num_observations();
  ceres::GradientProblemSolver::Options solver_options;
  solver_options.line_search_direction_type = ceres::LBFGS;
  solver_options.max_lbfgs_rank = options.lbfgs_rank;
  // Scales the initial inverse Hessian of each LBFGS step by s^T y / y^T y, so that the first
  // trial step of the line search has the right length in every direction.
  solver_options.use_approximate_eigenvalue_bfgs_scaling = true;
  solver_options.max_num_iterations = options.max_iterations;
  solver_options.max_solver_time_in_seconds = std::max(1e-3, seconds_left);
  solver_options.gradient_tolerance = options.gradient_tolerance;
  solver_options.function_tolerance = options.function_tolerance;
  solver_options.parameter_tolerance = options.parameter_tolerance;
  solver_options.logging_type = ceres::SILENT;
  ProgressPrinter printer(n);
  if (options.verbose) solver_options.callbacks.push_back(&printer);
  UserCallback user(&options.iteration_callback, n);
  if (options.iteration_callback) solver_options.callbacks.push_back(&user);

  auto* function = new CeresFunction<Objective>(&objective);
  ceres::GradientProblem problem(function);  // owns function
  Vector solver_x = x0;
  ceres::GradientProblemSolver::Summary solver_summary;
  ceres::Solve(solver_options, problem, solver_x.data(), &solver_summary);

  switch (solver_summary.termination_type) {
    case ceres::CONVERGENCE:
      run.termination = MaximumLikelihoodTermination::kConverged;
      break;
    case ceres::NO_CONVERGENCE:
      run.termination = MaximumLikelihoodTermination::kMaxIterations;
      break;
    case ceres::USER_SUCCESS:
    case ceres::USER_FAILURE:
      run.termination = MaximumLikelihoodTermination::kUserAbort;
      run.aborted = true;
      break;
    default:
      run.termination = MaximumLikelihoodTermination::kLineSearchFailed;
      break;
  }
  run.message = solver_summary.message;
  run.iterations = std::max(0, static_cast<int>(solver_summary.iterations.size()) - 1);

  // The best point seen; re-evaluated with its gradient (evaluations are deterministic).
  Vector best = function->has_best() ? function->best_x() : x0;
  if (!objective.Evaluate(best.data(), &run.cost, run.gradient.data())) {
    best = x0;
    objective.Evaluate(best.data(), &run.cost, run.gradient.data());
  }
  run.x = best;
  return run;
}

// The k-th perturbed start: x0 moved by N(0, perturbation^2) per entry, each entry kept at
// least a tenth of the way from its bounds.
Vector PerturbedStart(const Vector& x0, const Vector& lower, const Vector& upper,
                      double perturbation, std::mt19937_64* rng) {
  std::normal_distribution<double> normal(0.0, 1.0);
  Vector x = x0;
  for (Eigen::Index i = 0; i < x.size(); ++i) {
    const double step = perturbation * normal(*rng);
    const double target = x0[i] + step;
    const double lo = x0[i] - kStartBoundFraction * (x0[i] - lower[i]);
    const double hi = x0[i] + kStartBoundFraction * (upper[i] - x0[i]);
    x[i] = std::min(hi, std::max(lo, target));
  }
  return x;
}

// LBFGS from *x and from options.num_starts - 1 perturbed starts; *x receives the best point
// of the winning run. The caller has checked that *x lies inside the bounds.
template <typename Objective>
MaximumLikelihoodSummary Minimize(const Objective& objective,
                                  const MaximumLikelihoodOptions& options,
                                  const std::vector<std::string>& names, Vector* x) {
  const auto start_time = std::chrono::steady_clock::now();
  const auto elapsed = [&]() {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_time).count();
  };
  MaximumLikelihoodSummary summary;
  summary.parameter_names = names;
  const double n = objective.num_observations();
  summary.num_observations = n;
  const int num_parameters = objective.num_parameters();
  const LogHyperprior& prior = objective.prior();
  auto finish = [&]() {
    summary.num_evaluations = objective.num_evaluations();
    summary.num_failed_evaluations = objective.num_failed_evaluations();
    summary.num_out_of_bounds_evaluations = objective.num_out_of_bounds_evaluations();
    summary.elapsed_seconds = elapsed();
    if (options.verbose) std::fprintf(stderr, "%s\n", summary.BriefReport().c_str());
    return summary;
  };

  const Vector x0 = *x;
  std::mt19937_64 rng(options.seed);
  std::vector<Run> runs;
  const int num_starts = num_parameters == 0 ? 1 : options.num_starts;
  for (int k = 0; k < num_starts; ++k) {
    const Vector start = k == 0 ? x0
                                : PerturbedStart(x0, objective.lower_bounds(),
                                                 objective.upper_bounds(),
                                                 options.start_perturbation, &rng);
    if (k > 0 && options.verbose) std::fprintf(stderr, "ML-II start %d of %d\n", k + 1, num_starts);
    const int evaluations_before = objective.num_evaluations();
    runs.push_back(RunLbfgs(objective, options, start, options.max_seconds - elapsed()));
    const Run& run = runs.back();
    MaximumLikelihoodStart record;
    record.usable = run.termination != MaximumLikelihoodTermination::kInitialPointFailed;
    record.termination = run.termination;
    record.iterations = run.iterations;
    record.num_evaluations = objective.num_evaluations() - evaluations_before;
    record.initial_x = start;
    record.final_x = run.x;
    for (int i = 0; i < num_parameters; ++i) {
      if (run.x[i] - objective.lower_bounds()[i] <= kAtBoundDistance ||
          objective.upper_bounds()[i] - run.x[i] <= kAtBoundDistance) {
        record.at_bounds.push_back(names[static_cast<size_t>(i)]);
      }
    }
    if (record.usable) {
      record.objective = run.cost * n;
      record.negative_log_prior = prior.NegativeLogDensity(run.x);
      record.negative_log_likelihood = record.objective - record.negative_log_prior;
    } else {
      record.objective = record.negative_log_likelihood = record.negative_log_prior = kInfinity;
    }
    summary.starts.push_back(record);
    if (k == 0) {
      if (!record.usable) {
        summary.termination = MaximumLikelihoodTermination::kInitialPointFailed;
        summary.message = run.message;
        summary.initial_negative_log_likelihood = kInfinity;
        summary.final_negative_log_likelihood = kInfinity;
        summary.final_negative_log_prior = kInfinity;
        summary.final_gradient = Vector::Zero(num_parameters);
        return finish();
      }
      // x0 is the prior's centre: its prior term is 0.
      double cost0 = 0.0;
      objective.Evaluate(x0.data(), &cost0, nullptr);
      summary.initial_negative_log_likelihood = cost0 * n - prior.NegativeLogDensity(x0);
    }
    if (run.aborted || elapsed() >= options.max_seconds) break;
  }

  int best = 0;
  for (int k = 1; k < static_cast<int>(runs.size()); ++k) {
    const auto& r = summary.starts[static_cast<size_t>(k)];
    if (r.usable && r.objective < summary.starts[static_cast<size_t>(best)].objective) best = k;
  }
  summary.best_start = best;
  const Run& winner = runs[static_cast<size_t>(best)];
  const MaximumLikelihoodStart& record = summary.starts[static_cast<size_t>(best)];
  bool aborted = false;
  for (const Run& r : runs) aborted = aborted || r.aborted;
  summary.termination = aborted ? MaximumLikelihoodTermination::kUserAbort : winner.termination;
  summary.message = aborted ? "the iteration callback asked to stop" : winner.message;
  summary.iterations = winner.iterations;
  *x = winner.x;
  summary.final_negative_log_likelihood = record.negative_log_likelihood;
  summary.final_negative_log_prior = record.negative_log_prior;
  summary.final_gradient = winner.gradient * n;
  summary.at_bounds = record.at_bounds;
  return finish();
}

// The prior of an objective: centre x0, the width of each entry's group.
LogHyperprior MakePrior(const HyperpriorOptions& options, const Vector& x0, const Vector& width) {
  if (options.family == HyperpriorFamily::kNone) return LogHyperprior();
  return LogHyperprior(options.family, x0, width, options.degrees_of_freedom);
}

}  // namespace

const char* ToString(MaximumLikelihoodTermination termination) {
  switch (termination) {
    case MaximumLikelihoodTermination::kConverged:
      return "converged";
    case MaximumLikelihoodTermination::kMaxIterations:
      return "max_iterations";
    case MaximumLikelihoodTermination::kLineSearchFailed:
      return "line_search_failed";
    case MaximumLikelihoodTermination::kInitialPointFailed:
      return "initial_point_failed";
    case MaximumLikelihoodTermination::kNoFreeParameters:
      return "no_free_parameters";
    case MaximumLikelihoodTermination::kUserAbort:
      return "user_abort";
  }
  return "unknown";
}

bool MaximumLikelihoodOptions::IsValid(std::string* error) const {
  if (max_iterations < 1) {
    if (error != nullptr) {
      *error = "MaximumLikelihoodOptions::max_iterations: expected >= 1, got " +
               std::to_string(max_iterations);
    }
    return false;
  }
  if (lbfgs_rank < 1) {
    if (error != nullptr) {
      *error =
          "MaximumLikelihoodOptions::lbfgs_rank: expected >= 1, got " + std::to_string(lbfgs_rank);
    }
    return false;
  }
  if (!(std::isfinite(max_seconds) && max_seconds > 0.0)) {
    if (error != nullptr) {
      *error = "MaximumLikelihoodOptions::max_seconds: expected a finite value > 0, got " +
               std::to_string(max_seconds);
    }
    return false;
  }
  if (num_starts < 1) {
    if (error != nullptr) {
      *error = "MaximumLikelihoodOptions::num_starts: expected >= 1, got " +
               std::to_string(num_starts);
    }
    return false;
  }
  if (!(std::isfinite(start_perturbation) && start_perturbation >= 0.0)) {
    if (error != nullptr) {
      *error = "MaximumLikelihoodOptions::start_perturbation: expected a finite value >= 0 (log "
               "units), got " +
               std::to_string(start_perturbation);
    }
    return false;
  }
  std::string prior_error;
  if (!prior.IsValid(&prior_error)) {
    if (error != nullptr) *error = "MaximumLikelihoodOptions::prior: " + prior_error;
    return false;
  }
  return ToleranceValid("gradient_tolerance", gradient_tolerance, error) &&
         ToleranceValid("function_tolerance", function_tolerance, error) &&
         ToleranceValid("parameter_tolerance", parameter_tolerance, error) &&
         BoundsValid("shape_bounds", shape_bounds, kInfinity, error) &&
         BoundsValid("block_scale_bounds", block_scale_bounds, kInfinity, error) &&
         BoundsValid("noise_bounds", noise_bounds, kNoiseLimit, error) &&
         BoundsValid("output_scale_bounds", output_scale_bounds, kInfinity, error) &&
         BoundsValid("kernel_parameter_bounds", kernel_parameter_bounds, kInfinity, error);
}

void MaximumLikelihoodOptions::Validate() const {
  std::string error;
  if (!IsValid(&error)) throw std::invalid_argument(error);
}

FreeHyperparameters MaximumLikelihoodOptions::free_hyperparameters() const {
  FreeHyperparameters free;
  free.shape = optimize_shape;
  free.block_scales = optimize_block_scales;
  free.noise = optimize_noise;
  free.output_scales = optimize_output_scales;
  return free;
}

std::string MaximumLikelihoodSummary::BriefReport() const {
  std::ostringstream os;
  os << "ML-II: " << ToString(termination) << " after " << iterations << " iterations ("
     << num_evaluations << " evaluations, " << num_failed_evaluations << " failed, "
     << num_out_of_bounds_evaluations << " out of bounds), -log p(Y) "
     << initial_negative_log_likelihood << " -> " << final_negative_log_likelihood;
  if (final_negative_log_prior != 0.0) os << ", -log p(prior) " << final_negative_log_prior;
  if (starts.size() > 1) {
    os << ", start " << best_start + 1 << " of " << starts.size() << " won (objective";
    for (const MaximumLikelihoodStart& start : starts) os << " " << start.objective;
    os << ")";
  }
  if (final_gradient.size() > 0) {
    os << ", max|gradient| " << final_gradient.lpNorm<Eigen::Infinity>();
  }
  if (!at_bounds.empty()) {
    os << ", at bounds:";
    for (const std::string& name : at_bounds) os << " " << name;
  }
  os << ", " << elapsed_seconds << " s";
  return os.str();
}

std::vector<int> MaximumLikelihoodSummary::StartsByObjective() const {
  std::vector<int> order;
  for (int k = 0; k < static_cast<int>(starts.size()); ++k) {
    if (starts[static_cast<size_t>(k)].usable) order.push_back(k);
  }
  std::stable_sort(order.begin(), order.end(), [this](int a, int b) {
    return starts[static_cast<size_t>(a)].objective < starts[static_cast<size_t>(b)].objective;
  });
  return order;
}

// ---- weight space -----------------------------------------------------------------------------

EvidenceObjective::EvidenceObjective(const WeightSpaceEvidence& evidence,
                                     const MaximumLikelihoodOptions& options,
                                     const Hyperparameters& start)
    : evidence_(&evidence),
      layout_(evidence.map(), evidence.statistics().num_outputs(), options.free_hyperparameters()),
      base_(start) {
  options.Validate();
  const int num_outputs = evidence.statistics().num_outputs();
  ValidateHyperparameters(start, evidence.map(), num_outputs);
  lower_.resize(layout_.size());
  upper_.resize(layout_.size());
  for (int i = 0; i < layout_.size(); ++i) {
    const LogBounds& bounds = BoundsOf(options, layout_.group(i));
    lower_[i] = bounds.lower;
    upper_[i] = bounds.upper;
  }
  Vector width(layout_.size());
  for (int i = 0; i < layout_.size(); ++i) {
    switch (layout_.group(i)) {
      case HyperparameterGroup::kShape:
        width[i] = options.prior.shape_width;
        break;
      case HyperparameterGroup::kBlockScale:
        width[i] = options.prior.block_scale_width;
        break;
      case HyperparameterGroup::kNoise:
        width[i] = options.prior.noise_width;
        break;
      case HyperparameterGroup::kOutputScale:
        width[i] = options.prior.output_scale_width;
        break;
    }
  }
  prior_ = MakePrior(options.prior, layout_.Flatten(start), width);
  num_observations_ = std::max(1.0, evidence.statistics().count) * num_outputs;
  work_ = base_;
  gradient_ = base_;
}

Hyperparameters EvidenceObjective::ToHyperparameters(const ConstVectorRef& x) const {
  Hyperparameters hyper = base_;
  layout_.Unflatten(x, &hyper);
  return hyper;
}

bool EvidenceObjective::Evaluate(const double* x, double* cost, double* gradient) const {
  ++num_evaluations_;
  const Eigen::Map<const Vector> xv(x, layout_.size());
  if (!InsideBox(xv, lower_, upper_)) {
    ++num_out_of_bounds_;
    return false;
  }
  layout_.Unflatten(xv, &work_);
  // A shape value far from its default can underflow a prior variance to 0 (or overflow it);
  // the model rejects such a prior, so the point is declined here instead.
  const Vector lambda = PriorVariance(evidence_->map(), work_);
  if (!lambda.allFinite() || (lambda.array() <= 0.0).any()) {
    ++num_failed_;
    return false;
  }
  double lml = 0.0;
  const Status status = evidence_->Evaluate(work_, &lml, gradient ? &gradient_ : nullptr);
  if (status != Status::kOk || !std::isfinite(lml)) {
    ++num_failed_;
    return false;
  }
  Vector g;
  if (gradient != nullptr) {
    g = -layout_.Flatten(gradient_);
    if (!g.allFinite()) {
      ++num_failed_;
      return false;
    }
  }
  const double penalty = prior_.NegativeLogDensity(xv, gradient != nullptr ? g.data() : nullptr);
  if (gradient != nullptr) Eigen::Map<Vector>(gradient, layout_.size()) = g / num_observations_;
  *cost = (-lml + penalty) / num_observations_;
  return true;
}

MaximumLikelihoodSummary FitHyperparameters(const WeightSpaceEvidence& evidence,
                                            const MaximumLikelihoodOptions& options,
                                            Hyperparameters* hyper) {
  if (hyper == nullptr) throw std::invalid_argument("FitHyperparameters: null hyper");
  const EvidenceObjective objective(evidence, options, *hyper);
  const HyperparameterLayout& layout = objective.layout();
  Vector x = layout.Flatten(*hyper);
  std::vector<std::string> bounds_names;
  for (int i = 0; i < layout.size(); ++i) bounds_names.push_back(BoundsName(layout.group(i)));
  RequireStartInside("FitHyperparameters", x, objective.lower_bounds(), objective.upper_bounds(),
                     layout.names(), bounds_names);
  MaximumLikelihoodSummary summary = Minimize(objective, options, layout.names(), &x);
  for (MaximumLikelihoodStart& start : summary.starts) {
    start.hyperparameters = objective.ToHyperparameters(start.final_x);
  }
  if (summary.usable()) *hyper = objective.ToHyperparameters(x);
  return summary;
}

// ---- function space ---------------------------------------------------------------------------

KernelEvidenceObjective::KernelEvidenceObjective(const Kernel& kernel, const ConstMatrixRef& X,
                                                 const ConstMatrixRef& Y,
                                                 const MaximumLikelihoodOptions& options,
                                                 const Hyperparameters& start)
    : kernel_(kernel.Clone()),
      X_(X),
      Y_(Y),
      free_kernel_(options.optimize_kernel_parameters),
      free_noise_(options.optimize_noise),
      free_scales_(options.optimize_output_scales),
      base_(start) {
  options.Validate();
  RequireSize("KernelEvidenceObjective X", X.cols(), kernel.input_dim(), "columns");
  RequireSize("KernelEvidenceObjective Y", Y.rows(), X.rows(), "rows (as in X)");
  if (X.rows() < 1 || Y.cols() < 1) {
    throw std::invalid_argument(
        "KernelEvidenceObjective: expected at least one sample and "
        "one output, got " +
        std::to_string(X.rows()) + " x " + std::to_string(Y.cols()));
  }
  RequireFinite("KernelEvidenceObjective X", X);
  RequireFinite("KernelEvidenceObjective Y", Y);
  const int num_outputs = static_cast<int>(Y.cols());
  ValidateHyperparameters(start, kernel, num_outputs);
  std::vector<double> lower, upper, width;
  auto add = [&](const std::string& name, const LogBounds& bounds, double prior_width) {
    names_.push_back(name);
    lower.push_back(bounds.lower);
    upper.push_back(bounds.upper);
    width.push_back(prior_width);
  };
  if (free_kernel_) {
    const std::vector<std::string> names = kernel.parameter_names();
    for (int i = 0; i < kernel.num_parameters(); ++i) {
      add(names.at(static_cast<size_t>(i)), options.kernel_parameter_bounds,
          options.prior.kernel_parameter_width);
    }
  }
  if (free_noise_) add("log_noise_std", options.noise_bounds, options.prior.noise_width);
  if (free_scales_) {
    for (int j = 0; j < num_outputs; ++j) {
      add("log_output_scale_" + std::to_string(j + 1), options.output_scale_bounds,
          options.prior.output_scale_width);
    }
  }
  lower_ = Eigen::Map<const Vector>(lower.data(), static_cast<Eigen::Index>(lower.size()));
  upper_ = Eigen::Map<const Vector>(upper.data(), static_cast<Eigen::Index>(upper.size()));
  prior_ = MakePrior(options.prior, Flatten(start),
                     Eigen::Map<const Vector>(width.data(), static_cast<Eigen::Index>(width.size())));
  num_observations_ = static_cast<double>(X.rows()) * num_outputs;
}

Vector KernelEvidenceObjective::Flatten(const Hyperparameters& hyper) const {
  ValidateHyperparameters(hyper, *kernel_, static_cast<int>(Y_.cols()));
  Vector x(num_parameters());
  Eigen::Index i = 0;
  if (free_kernel_) {
    x.segment(i, hyper.shape.size()) = hyper.shape;
    i += hyper.shape.size();
  }
  if (free_noise_) x[i++] = hyper.log_noise_std;
  if (free_scales_) x.segment(i, hyper.log_output_scale.size()) = hyper.log_output_scale;
  return x;
}

Hyperparameters KernelEvidenceObjective::ToHyperparameters(const ConstVectorRef& x) const {
  RequireSize("KernelEvidenceObjective::ToHyperparameters x", x.size(), num_parameters());
  Hyperparameters hyper = base_;
  Eigen::Index i = 0;
  if (free_kernel_) {
    hyper.shape = x.segment(i, base_.shape.size());
    i += base_.shape.size();
  }
  if (free_noise_) hyper.log_noise_std = x[i++];
  if (free_scales_) hyper.log_output_scale = x.segment(i, base_.log_output_scale.size());
  return hyper;
}

bool KernelEvidenceObjective::Evaluate(const double* x, double* cost, double* gradient) const {
  ++num_evaluations_;
  const Eigen::Map<const Vector> xv(x, num_parameters());
  if (!InsideBox(xv, lower_, upper_)) {
    ++num_out_of_bounds_;
    return false;
  }
  const Hyperparameters hyper = ToHyperparameters(xv);
  const std::unique_ptr<Kernel> kernel = kernel_->WithParameters(hyper.shape);
  const int num_outputs = static_cast<int>(Y_.cols());
  KernelGP model(*kernel, std::exp(2.0 * hyper.log_noise_std), num_outputs,
                 hyper.log_output_scale.array().exp().matrix());
  if (model.Fit(X_, Y_) != Status::kOk) {
    ++num_failed_;
    return false;
  }
  const bool want = gradient != nullptr;
  Vector d_kernel, d_scales;
  double d_noise = 0.0;
  const double lml = model.LogMarginalLikelihood(want && free_kernel_ ? &d_kernel : nullptr,
                                                 want && free_noise_ ? &d_noise : nullptr,
                                                 want && free_scales_ ? &d_scales : nullptr);
  if (!std::isfinite(lml)) {
    ++num_failed_;
    return false;
  }
  if (want) {
    Vector g(num_parameters());
    Eigen::Index i = 0;
    if (free_kernel_) {
      g.segment(i, d_kernel.size()) = d_kernel;
      i += d_kernel.size();
    }
    if (free_noise_) g[i++] = d_noise;
    if (free_scales_) g.segment(i, d_scales.size()) = d_scales;
    if (!g.allFinite()) {
      ++num_failed_;
      return false;
    }
    g = -g;
    prior_.NegativeLogDensity(xv, g.data());
    Eigen::Map<Vector>(gradient, num_parameters()) = g / num_observations_;
  }
  *cost = (-lml + prior_.NegativeLogDensity(xv)) / num_observations_;
  return true;
}

MaximumLikelihoodSummary FitKernelHyperparameters(const Kernel& kernel, const ConstMatrixRef& X,
                                                  const ConstMatrixRef& Y,
                                                  const MaximumLikelihoodOptions& options,
                                                  Hyperparameters* hyper) {
  if (hyper == nullptr) throw std::invalid_argument("FitKernelHyperparameters: null hyper");
  const KernelEvidenceObjective objective(kernel, X, Y, options, *hyper);
  Vector x = objective.Flatten(*hyper);
  std::vector<std::string> bounds_names;
  const int num_kernel = options.optimize_kernel_parameters ? kernel.num_parameters() : 0;
  for (int i = 0; i < objective.num_parameters(); ++i) {
    const bool noise = options.optimize_noise && i == num_kernel;
    bounds_names.push_back(i < num_kernel ? "kernel_parameter_bounds"
                           : noise        ? "noise_bounds"
                                          : "output_scale_bounds");
  }
  RequireStartInside("FitKernelHyperparameters", x, objective.lower_bounds(),
                     objective.upper_bounds(), objective.names(), bounds_names);
  MaximumLikelihoodSummary summary = Minimize(objective, options, objective.names(), &x);
  for (MaximumLikelihoodStart& start : summary.starts) {
    start.hyperparameters = objective.ToHyperparameters(start.final_x);
  }
  if (summary.usable()) *hyper = objective.ToHyperparameters(x);
  return summary;
}

// ---- shared-parameter regressor ---------------------------------------------------------------

RegressorEvidenceObjective::RegressorEvidenceObjective(const RegressorMap& map,
                                                       const RegressorStatistics& statistics,
                                                       const MaximumLikelihoodOptions& options,
                                                       const Hyperparameters& start)
    : map_(&map),
      statistics_(&statistics),
      blocks_(map.blocks()),
      free_blocks_(options.optimize_block_scales),
      free_noise_(options.optimize_noise),
      base_(start) {
  options.Validate();
  const int N = map.num_outputs();
  if (statistics.num_parameters() != map.dim() || statistics.num_outputs() != N) {
    throw std::invalid_argument("RegressorEvidenceObjective: statistics of " +
                                std::to_string(statistics.num_parameters()) + " parameters and " +
                                std::to_string(statistics.num_outputs()) +
                                " outputs, the map has " + std::to_string(map.dim()) + " and " +
                                std::to_string(N));
  }
  start.Validate(0, static_cast<Eigen::Index>(blocks_.size()), N,
                 "RegressorEvidenceObjective start");
  std::vector<double> lower, upper, width;
  auto add = [&](const std::string& name, const LogBounds& bounds, double prior_width) {
    names_.push_back(name);
    lower.push_back(bounds.lower);
    upper.push_back(bounds.upper);
    width.push_back(prior_width);
  };
  if (free_blocks_) {
    for (const FeatureBlock& b : blocks_) {
      add("log_block_scale_" + b.name, options.block_scale_bounds, options.prior.block_scale_width);
    }
  }
  if (free_noise_) {
    for (int j = 0; j < N; ++j) {
      add("log_output_scale_" + std::to_string(j + 1), options.output_scale_bounds,
          options.prior.noise_width);
    }
  }
  lower_ = Eigen::Map<const Vector>(lower.data(), static_cast<Eigen::Index>(lower.size()));
  upper_ = Eigen::Map<const Vector>(upper.data(), static_cast<Eigen::Index>(upper.size()));
  num_observations_ = std::max(1.0, statistics.count) * N;
  prior_ = MakePrior(options.prior, Flatten(start),
                     Eigen::Map<const Vector>(width.data(), static_cast<Eigen::Index>(width.size())));
}

Vector RegressorEvidenceObjective::Flatten(const Hyperparameters& hyper) const {
  Vector x(num_parameters());
  Eigen::Index i = 0;
  if (free_blocks_) {
    x.segment(i, hyper.log_block_scale.size()) = hyper.log_block_scale;
    i += hyper.log_block_scale.size();
  }
  if (free_noise_) x.segment(i, hyper.log_output_scale.size()) = hyper.log_output_scale;
  return x;
}

Hyperparameters RegressorEvidenceObjective::ToHyperparameters(const ConstVectorRef& x) const {
  RequireSize("RegressorEvidenceObjective::ToHyperparameters x", x.size(), num_parameters());
  Hyperparameters hyper = base_;
  Eigen::Index i = 0;
  if (free_blocks_) {
    hyper.log_block_scale = x.segment(i, base_.log_block_scale.size());
    i += base_.log_block_scale.size();
  }
  if (free_noise_) hyper.log_output_scale = x.segment(i, base_.log_output_scale.size());
  return hyper;
}

bool RegressorEvidenceObjective::Evaluate(const double* x, double* cost, double* gradient) const {
  ++num_evaluations_;
  const Eigen::Map<const Vector> xv(x, num_parameters());
  if (!InsideBox(xv, lower_, upper_)) {
    ++num_out_of_bounds_;
    return false;
  }
  const Hyperparameters hyper = ToHyperparameters(xv);
  const Vector noise =
      (2.0 * (hyper.log_output_scale.array() + hyper.log_noise_std)).exp().matrix();
  RegressorGP model(map_->prior_mean(), RegressorPriorVariance(*map_, hyper.log_block_scale),
                    noise);
  if (model.Fit(*statistics_, /*ladder=*/false) != Status::kOk) {
    ++num_failed_;
    return false;
  }
  RegressorEvidenceGradient g;
  const double lml = model.LogMarginalLikelihood(gradient != nullptr ? &g : nullptr);
  if (!std::isfinite(lml)) {
    ++num_failed_;
    return false;
  }
  if (gradient != nullptr) {
    Vector d(num_parameters());
    Eigen::Index i = 0;
    if (free_blocks_) {
      for (const FeatureBlock& b : blocks_) {
        d[i++] = 2.0 * g.d_log_prior_variance.segment(b.begin, b.size).sum();
      }
    }
    if (free_noise_) {
      d.segment(i, g.d_log_noise_variance.size()) = 2.0 * g.d_log_noise_variance;
    }
    if (!d.allFinite()) {
      ++num_failed_;
      return false;
    }
    d = -d;
    prior_.NegativeLogDensity(xv, d.data());
    Eigen::Map<Vector>(gradient, num_parameters()) = d / num_observations_;
  }
  *cost = (-lml + prior_.NegativeLogDensity(xv)) / num_observations_;
  return true;
}

MaximumLikelihoodSummary FitRegressorHyperparameters(const RegressorMap& map,
                                                     const RegressorStatistics& statistics,
                                                     const MaximumLikelihoodOptions& options,
                                                     Hyperparameters* hyper) {
  if (hyper == nullptr) throw std::invalid_argument("FitRegressorHyperparameters: null hyper");
  const RegressorEvidenceObjective objective(map, statistics, options, *hyper);
  Vector x = objective.Flatten(*hyper);
  std::vector<std::string> bounds_names;
  const int num_blocks = options.optimize_block_scales ? static_cast<int>(map.blocks().size()) : 0;
  for (int i = 0; i < objective.num_parameters(); ++i) {
    bounds_names.push_back(i < num_blocks ? "block_scale_bounds" : "output_scale_bounds");
  }
  RequireStartInside("FitRegressorHyperparameters", x, objective.lower_bounds(),
                     objective.upper_bounds(), objective.names(), bounds_names);
  MaximumLikelihoodSummary summary = Minimize(objective, options, objective.names(), &x);
  for (MaximumLikelihoodStart& start : summary.starts) {
    start.hyperparameters = objective.ToHyperparameters(start.final_x);
  }
  if (summary.usable()) *hyper = objective.ToHyperparameters(x);
  return summary;
}

}  // namespace structgp
