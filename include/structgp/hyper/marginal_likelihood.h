#ifndef STRUCTGP_HYPER_MARGINAL_LIKELIHOOD_H_
#define STRUCTGP_HYPER_MARGINAL_LIKELIHOOD_H_

/// @file
/// Type-II maximum likelihood: hyper-parameters that maximise the log marginal likelihood
/// log p(Y | hyper), found with limited-memory BFGS and the analytic gradient.
///
/// Two forms:
/// - FitHyperparameters, weight space: a feature map's shape parameters, log block scales,
///   log noise std and log output scales, on cached SufficientStatistics
///   (WeightSpaceEvidence). Each evaluation costs O(D^3), independent of the number of samples.
/// - FitKernelHyperparameters, function space: a Kernel's parameters (Hyperparameters::shape,
///   see core/hyperparameters.h), log noise std and log output scales, with KernelGP. Each evaluation costs O(m^3 + m^2 * num_parameters).
///
/// The objective is f(x) = (-log p(Y | x) - log p(x)) / n over the flat vector x of the free
/// hyper-parameters, n = m P the number of scalar observations, p(x) the prior of
/// MaximumLikelihoodOptions::prior (hyper/hyperprior.h; none: plain ML-II) centred on the
/// starting values: the division keeps f and its gradient of order one whatever the data
/// size, so that one set of tolerances fits all. LBFGS runs from the given start and from
/// MaximumLikelihoodOptions::num_starts - 1 perturbed copies of it; the lowest f wins.
/// All hyper-parameters are log values, and each has a box (LogBounds). The objective
/// declines to evaluate (returns false) outside the box and where the evidence cannot be
/// computed (a Cholesky factorisation fails, a value is not finite): the line search then
/// backs off to a shorter step. Such evaluations are counted in the summary; they never
/// produce a NaN. The result is the best point evaluated.

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "structgp/core/types.h"
#include "structgp/hyper/evidence.h"
#include "structgp/hyper/hyperparameter_layout.h"
#include "structgp/hyper/hyperprior.h"
#include "structgp/feature/feature_hyperparameters.h"
#include "structgp/kernel/kernel_hyperparameters.h"
#include "structgp/kernel/kernel.h"
#include "structgp/feature/regressor_map.h"
#include "structgp/model/regressor_gp.h"

namespace structgp {

/// A free hyper-parameter whose result lies within this distance (in log units) of one of its
/// bounds is listed in MaximumLikelihoodSummary::at_bounds: the optimum may lie beyond it.
inline constexpr double kAtBoundDistance = 1e-3;

/// A closed interval [lower, upper] for a log-scale hyper-parameter.
struct LogBounds {
  double lower = 0.0;
  double upper = 0.0;
  bool Contains(double value) const { return value >= lower && value <= upper; }
};

/// Options of FitHyperparameters and FitKernelHyperparameters.
struct MaximumLikelihoodOptions {
  /// Maximum number of LBFGS iterations. One iteration costs one evaluation of the evidence
  /// and its gradient, more when the line search has to back off.
  int max_iterations = 200;
  /// Converged when max_i |d f / d x_i| <= gradient_tolerance (f = -log p / n).
  double gradient_tolerance = 1e-8;
  /// Converged when |f_new - f_old| <= function_tolerance * |f_old|.
  double function_tolerance = 1e-12;
  /// Converged when ||step|| <= parameter_tolerance * (||x|| + parameter_tolerance).
  double parameter_tolerance = 1e-10;
  /// Wall-clock limit of the minimiser, seconds.
  double max_seconds = 1e6;
  /// Number of correction pairs kept by LBFGS.
  int lbfgs_rank = 20;

  /// Which hyper-parameters are free; the others keep their starting values.
  /// Weight space: the feature map's shape parameters (e.g. log sigma of k_pol).
  bool optimize_shape = true;
  /// Weight space: one log scale per block of the feature map.
  bool optimize_block_scales = true;
  /// Both forms: log sigma_n.
  bool optimize_noise = true;
  /// Both forms: one log scale per output. Off by default: with every block scale and the
  /// noise free as well, multiplying all block scales and sigma_n by c and every output scale
  /// by 1/c leaves the model unchanged, so the optimum is a line. LBFGS is not troubled by
  /// that (the gradient has no component along the line), but the individual values are then
  /// not identified; only their products are.
  bool optimize_output_scales = false;
  /// Function space: all parameters of the Kernel (Kernel::parameters()).
  bool optimize_kernel_parameters = true;

  /// Boxes on the log values. Starting values must lie inside them.
  LogBounds shape_bounds{-10.0, 10.0};
  LogBounds block_scale_bounds{-12.0, 12.0};
  /// log sigma_n; the default keeps sigma_n in [6e-6, 20] in the units of the targets (of
  /// each output divided by its scale). Must lie inside (-50, 50).
  LogBounds noise_bounds{-12.0, 3.0};
  LogBounds output_scale_bounds{-12.0, 12.0};
  LogBounds kernel_parameter_bounds{-12.0, 12.0};

  /// The prior on the log hyper-parameters, centred on the starting values (type-II MAP).
  /// prior.family = HyperpriorFamily::kNone gives plain type-II maximum likelihood.
  HyperpriorOptions prior;

  /// Number of LBFGS runs (>= 1): from the given start, then from num_starts - 1 copies of it
  /// with every free entry moved by an independent N(0, start_perturbation^2) step (log
  /// units, clipped to 0.9 of the way to its bound), drawn from std::mt19937_64(seed). The
  /// run with the lowest objective wins; every run is listed in the summary.
  int num_starts = 3;
  double start_perturbation = 1.0;
  std::uint64_t seed = 20240601;

  /// Progress to stderr: one line per iteration and a final report.
  bool verbose = false;
  /// Called after every LBFGS iteration with the iteration number (counted from 0 in every
  /// run) and the objective -log p(Y) - log p(x) (nats) at the current point; returning false
  /// stops the search (kUserAbort), including the runs not yet started. May be empty.
  std::function<bool(int iteration, double negative_log_likelihood)> iteration_callback;

  /// True when the options are usable; otherwise false with the reason in *error (may be
  /// null).
  bool IsValid(std::string* error) const;
  /// Throws std::invalid_argument with the reason unless IsValid().
  void Validate() const;
  /// The free groups of the weight-space form.
  FreeHyperparameters free_hyperparameters() const;
};

/// How a fit ended.
enum class MaximumLikelihoodTermination {
  /// A tolerance of the options was met.
  kConverged,
  /// max_iterations or max_seconds reached; the result is the best point evaluated.
  kMaxIterations,
  /// The minimiser found no step that lowers the objective along its search directions
  /// (typically against a bound, or at the limit of the evidence's rounding); the result is
  /// the best point evaluated.
  kLineSearchFailed,
  /// The evidence could not be evaluated at the starting point; nothing was changed.
  kInitialPointFailed,
  /// No hyper-parameter is free; the evidence was evaluated at the start only.
  kNoFreeParameters,
  /// MaximumLikelihoodOptions::iteration_callback asked to stop; the result is the best point
  /// evaluated.
  kUserAbort,
};

/// "converged", "max_iterations", "line_search_failed", "initial_point_failed",
/// "no_free_parameters", "user_abort".
const char* ToString(MaximumLikelihoodTermination termination);

/// One LBFGS run of a multi-start fit.
struct MaximumLikelihoodStart {
  /// False when the evidence could not be evaluated at this start (the run was skipped).
  bool usable = false;
  MaximumLikelihoodTermination termination = MaximumLikelihoodTermination::kInitialPointFailed;
  int iterations = 0;
  int num_evaluations = 0;
  /// The starting point and the best point of the run (free entries, layout order), and the
  /// hyper-parameters at the best point.
  Vector initial_x;
  Vector final_x;
  Hyperparameters hyperparameters;
  /// At final_x: -log p(Y | x), -log p(x) (0 without a prior) and their sum, nats; +infinity
  /// when not usable.
  double negative_log_likelihood = 0.0;
  double negative_log_prior = 0.0;
  double objective = 0.0;
  /// Names of the free hyper-parameters within kAtBoundDistance of a bound at final_x.
  std::vector<std::string> at_bounds;
};

/// What a fit did.
struct MaximumLikelihoodSummary {
  MaximumLikelihoodTermination termination = MaximumLikelihoodTermination::kInitialPointFailed;
  /// Human-readable reason, from the minimiser when it ran.
  std::string message;
  /// Names of the free hyper-parameters (the layout of the gradient below).
  std::vector<std::string> parameter_names;
  /// LBFGS iterations (accepted steps).
  int iterations = 0;
  /// Evaluations of the evidence, including failed and out-of-bounds ones.
  int num_evaluations = 0;
  /// Evaluations at which the evidence could not be computed (a factorisation failed or a
  /// value was not finite): the objective returned false and the line search backed off.
  int num_failed_evaluations = 0;
  /// Trial points outside the bounds (rejected without evaluating the evidence).
  int num_out_of_bounds_evaluations = 0;
  /// -log p(Y) at the given start and at the result; +infinity when it could not be
  /// evaluated.
  double initial_negative_log_likelihood = 0.0;
  double final_negative_log_likelihood = 0.0;
  /// -log p(x) of the prior (without its constant; 0 at the start, whose values are its
  /// centre, and without a prior) at the result.
  double final_negative_log_prior = 0.0;
  /// d(-log p(Y) - log p(x)) / d x at the result (the objective's gradient times n), in the
  /// order of parameter_names.
  Vector final_gradient;
  /// Every LBFGS run, in the order they were started (0 = the given start), and the index of
  /// the one that won (the lowest objective; -1 when none could be evaluated). iterations,
  /// termination and message above are the winner's; num_evaluations and elapsed_seconds
  /// count every run.
  std::vector<MaximumLikelihoodStart> starts;
  int best_start = -1;
  /// The runs that could be evaluated, best (lowest objective) first.
  std::vector<int> StartsByObjective() const;
  /// Number of scalar observations n = m P by which the objective is divided.
  double num_observations = 0.0;
  /// Names of the free hyper-parameters that ended within kAtBoundDistance of a bound.
  std::vector<std::string> at_bounds;
  /// Wall-clock time of the whole fit, seconds.
  double elapsed_seconds = 0.0;

  /// True unless the start could not be evaluated.
  bool usable() const { return termination != MaximumLikelihoodTermination::kInitialPointFailed; }
  /// One line: termination, iterations, evaluations, -log p before and after, the prior and
  /// the winning start, time.
  std::string BriefReport() const;
};

/// The objective of FitHyperparameters: f(x) = -log p(Y | hyper(x)) / n, where hyper(x) is
/// `start` with its free entries (by `layout`) replaced by x, and n = m P.
///
/// Not safe for concurrent calls (it counts its evaluations, and the evidence reuses one
/// model); evidence must outlive the objective.
class EvidenceObjective {
 public:
  /// The prior (options.prior) is centred on `start`. Throws std::invalid_argument on invalid
  /// options or when start does not match the map.
  EvidenceObjective(const WeightSpaceEvidence& evidence, const MaximumLikelihoodOptions& options,
                    const Hyperparameters& start);

  int num_parameters() const { return layout_.size(); }
  const HyperparameterLayout& layout() const { return layout_; }
  /// Box of every free entry, from the options.
  const Vector& lower_bounds() const { return lower_; }
  const Vector& upper_bounds() const { return upper_; }
  /// n = m P (at least P).
  double num_observations() const { return num_observations_; }
  /// The prior over the free entries (inactive for HyperpriorFamily::kNone).
  const LogHyperprior& prior() const { return prior_; }

  /// f(x) = (-log p(Y | x) - log p(x)) / n into *cost and, when gradient is not null, df/dx
  /// (num_parameters()). Returns false, writing nothing, when x is not finite or outside the
  /// bounds, or when the evidence cannot be evaluated there.
  bool Evaluate(const double* x, double* cost, double* gradient) const;

  /// The hyper-parameters at x.
  Hyperparameters ToHyperparameters(const ConstVectorRef& x) const;

  int num_evaluations() const { return num_evaluations_; }
  int num_failed_evaluations() const { return num_failed_; }
  int num_out_of_bounds_evaluations() const { return num_out_of_bounds_; }

 private:
  const WeightSpaceEvidence* evidence_;
  HyperparameterLayout layout_;
  Hyperparameters base_;
  LogHyperprior prior_;
  Vector lower_, upper_;
  double num_observations_;
  mutable Hyperparameters work_;
  mutable Hyperparameters gradient_;
  mutable int num_evaluations_ = 0;
  mutable int num_failed_ = 0;
  mutable int num_out_of_bounds_ = 0;
};

/// Maximises log p(Y | hyper) + log p(hyper) over the free entries of *hyper
/// (options.optimize_*), the prior centred on *hyper, with Ceres' LBFGS from *hyper and from
/// options.num_starts - 1 perturbed starts. On return *hyper holds the best point evaluated
/// (unchanged when the start could not be evaluated: see summary.termination); the other
/// runs' results are in summary.starts. Cost: O(D^3) per evaluation, typically 20-100
/// evaluations per start.
/// Throws std::invalid_argument when the options are invalid, *hyper does not match the map
/// and outputs of the evidence, or a free starting value lies outside its bounds.
MaximumLikelihoodSummary FitHyperparameters(const WeightSpaceEvidence& evidence,
                                            const MaximumLikelihoodOptions& options,
                                            Hyperparameters* hyper);

/// The objective of FitKernelHyperparameters: f(x) = -log p(Y | x) / (m P) with KernelGP.
/// start (and every point) holds the kernel's parameters in shape and no block scales
/// (kernel/kernel_hyperparameters.h). Free entries, in order: the kernel parameters (names from Kernel::parameter_names()) when
/// optimize_kernel_parameters, "log_noise_std" when optimize_noise, "log_output_scale_<j>"
/// (j = 1..P) when optimize_output_scales. Keeps its own copies of the kernel and the data.
/// Not safe for concurrent calls.
class KernelEvidenceObjective {
 public:
  /// X: m x kernel.input_dim(), Y: m x P, m >= 1, all finite. Throws std::invalid_argument on
  /// invalid options, sizes or values.
  KernelEvidenceObjective(const Kernel& kernel, const ConstMatrixRef& X, const ConstMatrixRef& Y,
                          const MaximumLikelihoodOptions& options,
                          const Hyperparameters& start);

  int num_parameters() const { return static_cast<int>(names_.size()); }
  const std::vector<std::string>& names() const { return names_; }
  const Vector& lower_bounds() const { return lower_; }
  const Vector& upper_bounds() const { return upper_; }
  double num_observations() const { return num_observations_; }
  /// The prior over the free entries, centred on start (inactive for HyperpriorFamily::kNone).
  const LogHyperprior& prior() const { return prior_; }

  /// As EvidenceObjective::Evaluate, with an O(m^3 + m^2 num_parameters) evaluation.
  bool Evaluate(const double* x, double* cost, double* gradient) const;

  /// The free entries of hyper, in the order above.
  Vector Flatten(const Hyperparameters& hyper) const;
  /// start with its free entries replaced by x.
  Hyperparameters ToHyperparameters(const ConstVectorRef& x) const;

  int num_evaluations() const { return num_evaluations_; }
  int num_failed_evaluations() const { return num_failed_; }
  int num_out_of_bounds_evaluations() const { return num_out_of_bounds_; }

 private:
  std::unique_ptr<Kernel> kernel_;
  Matrix X_, Y_;
  bool free_kernel_, free_noise_, free_scales_;
  Hyperparameters base_;
  std::vector<std::string> names_;
  LogHyperprior prior_;
  Vector lower_, upper_;
  double num_observations_;
  mutable int num_evaluations_ = 0;
  mutable int num_failed_ = 0;
  mutable int num_out_of_bounds_ = 0;
};

/// Maximises log p(Y | hyper) + log p(hyper) of a KernelGP with the given kernel over the free
/// entries of *hyper (optimize_kernel_parameters, optimize_noise, optimize_output_scales), the
/// prior centred on *hyper, from *hyper and options.num_starts - 1 perturbed starts. *hyper's
/// shape holds the kernel's parameters (kernel/kernel_hyperparameters.h; the
/// kernel's own parameters are not used). On return *hyper holds the best point evaluated
/// (unchanged when the start could not be evaluated); the kernel is not modified. A model is
/// fitted with the result by RobotModel::Fit(X, Y, *hyper) or
/// KernelGP(*kernel.WithParameters(hyper->shape), ...). With a FeatureKernel the result is the weight-space optimum of
/// FitHyperparameters (the same likelihood and prior), at O(m^3) per evaluation instead of O(D^3).
/// Throws std::invalid_argument on invalid options, sizes, values, or a free starting value
/// outside its bounds.
MaximumLikelihoodSummary FitKernelHyperparameters(const Kernel& kernel, const ConstMatrixRef& X,
                                                  const ConstMatrixRef& Y,
                                                  const MaximumLikelihoodOptions& options,
                                                  Hyperparameters* hyper);

/// The objective of FitRegressorHyperparameters: f(x) = (-log p(Y | x) - log p(x)) / (m N) of a
/// RegressorGP
/// (model/regressor_gp.h) on fixed statistics, O(N P^2 + P^3) per evaluation. Hyper-parameters
/// of a regressor: shape empty, one log block scale per block of the map (prior variance of
/// parameter k of block b: (prior_std_k exp(log_block_scale_b))^2), and the noise of output j,
/// sigma_j = exp(log_noise_std + log_output_scale_j). Free entries, in order:
/// "log_block_scale_<block>" for every block when optimize_block_scales (block_scale_bounds),
/// "log_output_scale_<j>" (j = 1..N, the per-output noise levels; output_scale_bounds) when
/// optimize_noise; log_noise_std stays at its start (only the sums are identified). map and
/// statistics must outlive the objective. Not safe for concurrent calls.
class RegressorEvidenceObjective {
 public:
  /// Throws std::invalid_argument on invalid options, or when the statistics or start do not
  /// match the map.
  RegressorEvidenceObjective(const RegressorMap& map, const RegressorStatistics& statistics,
                             const MaximumLikelihoodOptions& options,
                             const Hyperparameters& start);

  int num_parameters() const { return static_cast<int>(names_.size()); }
  const std::vector<std::string>& names() const { return names_; }
  const Vector& lower_bounds() const { return lower_; }
  const Vector& upper_bounds() const { return upper_; }
  double num_observations() const { return num_observations_; }
  /// The prior on the free entries (options.prior: block_scale_width for the block scales,
  /// noise_width for the noise levels), centred on the start.
  const LogHyperprior& prior() const { return prior_; }
  bool Evaluate(const double* x, double* cost, double* gradient) const;
  Vector Flatten(const Hyperparameters& hyper) const;
  Hyperparameters ToHyperparameters(const ConstVectorRef& x) const;
  int num_evaluations() const { return num_evaluations_; }
  int num_failed_evaluations() const { return num_failed_; }
  int num_out_of_bounds_evaluations() const { return num_out_of_bounds_; }

 private:
  LogHyperprior prior_;
  const RegressorMap* map_;
  const RegressorStatistics* statistics_;
  std::vector<FeatureBlock> blocks_;
  bool free_blocks_, free_noise_;
  Hyperparameters base_;
  std::vector<std::string> names_;
  Vector lower_, upper_;
  double num_observations_;
  mutable int num_evaluations_ = 0;
  mutable int num_failed_ = 0;
  mutable int num_out_of_bounds_ = 0;
};

/// Maximises log p(Y | hyper) of a RegressorGP over the free entries of *hyper (see
/// RegressorEvidenceObjective), from *hyper; on return *hyper holds the best point evaluated.
/// Throws std::invalid_argument as the objective does, or when a free start lies outside its
/// bounds.
MaximumLikelihoodSummary FitRegressorHyperparameters(const RegressorMap& map,
                                                     const RegressorStatistics& statistics,
                                                     const MaximumLikelihoodOptions& options,
                                                     Hyperparameters* hyper);

}  // namespace structgp

#endif  // STRUCTGP_HYPER_MARGINAL_LIKELIHOOD_H_
