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
/// The objective is f(x) = -log p(Y | x) / n over the flat vector x of the free
/// hyper-parameters, n = m P the number of scalar observations: the division keeps f and its
/// gradient of order one whatever the data size, so that one set of tolerances fits all.
/// All hyper-parameters are log values, and each has a box (LogBounds). The objective
/// declines to evaluate (returns false) outside the box and where the evidence cannot be
/// computed (a Cholesky factorisation fails, a value is not finite): the line search then
/// backs off to a shorter step. Such evaluations are counted in the summary; they never
/// produce a NaN. The result is the best point evaluated.

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "structgp/core/types.h"
#include "structgp/hyper/evidence.h"
#include "structgp/hyper/hyperparameter_layout.h"
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

  /// Progress to stderr: one line per iteration and a final report.
  bool verbose = false;
  /// Called after every LBFGS iteration with the iteration number and -log p(Y) (nats) at
  /// the current point; returning false stops the search (kUserAbort). May be empty.
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
  /// -log p(Y) at the start and at the result; +infinity when it could not be evaluated.
  double initial_negative_log_likelihood = 0.0;
  double final_negative_log_likelihood = 0.0;
  /// d(-log p(Y)) / d x at the result, in the order of parameter_names (not divided by n).
  Vector final_gradient;
  /// Number of scalar observations n = m P by which the objective is divided.
  double num_observations = 0.0;
  /// Names of the free hyper-parameters that ended within kAtBoundDistance of a bound.
  std::vector<std::string> at_bounds;
  /// Wall-clock time of the whole fit, seconds.
  double elapsed_seconds = 0.0;

  /// True unless the start could not be evaluated.
  bool usable() const { return termination != MaximumLikelihoodTermination::kInitialPointFailed; }
  /// One line: termination, iterations, evaluations, -log p before and after, time.
  std::string BriefReport() const;
};

/// The objective of FitHyperparameters: f(x) = -log p(Y | hyper(x)) / n, where hyper(x) is
/// `start` with its free entries (by `layout`) replaced by x, and n = m P.
///
/// Not safe for concurrent calls (it counts its evaluations, and the evidence reuses one
/// model); evidence must outlive the objective.
class EvidenceObjective {
 public:
  /// Throws std::invalid_argument on invalid options or when start does not match the map.
  EvidenceObjective(const WeightSpaceEvidence& evidence, const MaximumLikelihoodOptions& options,
                    const Hyperparameters& start);

  int num_parameters() const { return layout_.size(); }
  const HyperparameterLayout& layout() const { return layout_; }
  /// Box of every free entry, from the options.
  const Vector& lower_bounds() const { return lower_; }
  const Vector& upper_bounds() const { return upper_; }
  /// n = m P (at least P).
  double num_observations() const { return num_observations_; }

  /// f(x) into *cost and, when gradient is not null, df/dx (num_parameters()). Returns false,
  /// writing nothing, when x is not finite or outside the bounds, or when the evidence cannot
  /// be evaluated there.
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
  Vector lower_, upper_;
  double num_observations_;
  mutable Hyperparameters work_;
  mutable Hyperparameters gradient_;
  mutable int num_evaluations_ = 0;
  mutable int num_failed_ = 0;
  mutable int num_out_of_bounds_ = 0;
};

/// Maximises log p(Y | hyper) over the free entries of *hyper (options.optimize_*), starting
/// from *hyper, with Ceres' LBFGS. On return *hyper holds the best point evaluated (unchanged
/// when the start could not be evaluated: see summary.termination). Cost: O(D^3) per
/// evaluation, typically 20-100 evaluations.
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
  Vector lower_, upper_;
  double num_observations_;
  mutable int num_evaluations_ = 0;
  mutable int num_failed_ = 0;
  mutable int num_out_of_bounds_ = 0;
};

/// Maximises log p(Y | hyper) of a KernelGP with the given kernel over the free entries of
/// *hyper (optimize_kernel_parameters, optimize_noise, optimize_output_scales), starting from
/// *hyper, whose shape holds the kernel's parameters (kernel/kernel_hyperparameters.h; the
/// kernel's own parameters are not used). On return *hyper holds the best point evaluated
/// (unchanged when the start could not be evaluated); the kernel is not modified. A model is
/// fitted with the result by RobotModel::Fit(X, Y, *hyper) or
/// KernelGP(*kernel.WithParameters(hyper->shape), ...). With a FeatureKernel the result is the weight-space optimum of
/// FitHyperparameters (the same likelihood), at O(m^3) per evaluation instead of O(D^3).
/// Throws std::invalid_argument on invalid options, sizes, values, or a free starting value
/// outside its bounds.
MaximumLikelihoodSummary FitKernelHyperparameters(const Kernel& kernel, const ConstMatrixRef& X,
                                                  const ConstMatrixRef& Y,
                                                  const MaximumLikelihoodOptions& options,
                                                  Hyperparameters* hyper);

/// The objective of FitRegressorHyperparameters: f(x) = -log p(Y | x) / (m N) of a RegressorGP
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
  bool Evaluate(const double* x, double* cost, double* gradient) const;
  Vector Flatten(const Hyperparameters& hyper) const;
  Hyperparameters ToHyperparameters(const ConstVectorRef& x) const;
  int num_evaluations() const { return num_evaluations_; }
  int num_failed_evaluations() const { return num_failed_; }
  int num_out_of_bounds_evaluations() const { return num_out_of_bounds_; }

 private:
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
