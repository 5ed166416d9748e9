#ifndef STRUCTGP_FIT_FIT_MODEL_H_
#define STRUCTGP_FIT_FIT_MODEL_H_

/// @file
/// The fitting workflow of a RobotModel in one call, as `structgp fit` runs it: choose the
/// hyper-parameters (type-II maximum likelihood, blocked cross-validation, or the defaults),
/// then fit the model to every row. FitOptions -> FitModel -> FitSummary.
///
///     structgp::FitOptions options;                       // evidence, defaults
///     structgp::FittedModel fit = structgp::FitModel(spec, states, torques, t, options);
///     if (!fit.summary.IsUsable()) { std::cerr << fit.summary.message; ... }
///     std::cout << structgp::FitReport(fit.model, fit.summary);
///
/// Errors: caller mistakes (sizes, NaN/Inf in the data, invalid options, a method the model
/// cannot use) throw std::invalid_argument naming what is wrong; numerical trouble (the
/// evidence cannot be evaluated at the start, every cross-validation candidate fails, the
/// posterior is not positive definite) and a cancelled fit are reported by
/// FitSummary::termination, with the model left as it was (unfitted, or its earlier fit).

#include <functional>
#include <string>
#include <vector>

#include "structgp/core/types.h"
#include "structgp/fit/fit_check.h"
#include "structgp/hyper/euler_lagrange_fit.h"
#include "structgp/hyper/marginal_likelihood.h"
#include "structgp/model/model_spec.h"
#include "structgp/model/robot_model.h"

namespace structgp {

/// How the hyper-parameters are chosen.
enum class HyperparameterMethod {
  /// Type-II maximum likelihood (Ceres LBFGS on the log evidence). Feature-map models: after
  /// profiling the noise and output scales, over the shape, block scales and noise, on cached
  /// Phi^T Phi (O(D^3) per evaluation). Kernel models: over the kernel's parameters and the
  /// noise on at most FitOptions::max_evidence_rows rows (O(m^3) per evaluation).
  kEvidence,
  /// Blocked cross-validation on contiguous folds over a grid of shape and noise values
  /// (feature-map models only).
  kCrossValidation,
  /// RobotModel::DefaultHyperparameters: output scale = torque RMS, noise 10% of it.
  kFixed,
};

/// "ml", "cv", "fixed" (the CLI's --hyper words).
const char* ToString(HyperparameterMethod method);
/// The inverse of ToString; false (nothing written) for any other text.
bool FromString(const std::string& text, HyperparameterMethod* method);

/// What FitOptions::callback is told.
struct FitProgress {
  /// A line for a person ("maximising the evidence over ..."), or empty for an iteration.
  std::string message;
  /// Evidence search: LBFGS iterations so far (0 before the first).
  int iteration = 0;
  /// Evidence search: -log p(Y) at the current point (nats); NaN when not known.
  double negative_log_evidence = 0.0;
  /// Since FitModel was called.
  double seconds = 0.0;
};

/// Returned by FitOptions::callback.
enum class FitCallbackReturn { kContinue, kAbort };

/// Where the output scales s_j (one per joint: prior and noise of joint j both scale with
/// s_j^2) come from.
enum class OutputScaling {
  /// Each joint's torque RMS, then (evidence) profiled with the noise level.
  kPerJointRms,
  /// 1 for every joint, and kept: torques already on one scale share one noise level (the
  /// paper's setting). The evidence then fits the noise by LBFGS with the other groups; no
  /// profile is run.
  kUnit,
};

struct FitOptions {
  HyperparameterMethod method = HyperparameterMethod::kEvidence;
  OutputScaling output_scaling = OutputScaling::kPerJointRms;

  /// kEvidence: the LBFGS settings, which groups are free and their bounds, the prior on the
  /// log hyper-parameters (centred on the data-derived defaults FitModel starts from) and the
  /// number of starts. The defaults fit shape, block scales and noise (output scales profiled
  /// first, then held) by type-II MAP from 3 starts.
  MaximumLikelihoodOptions evidence;
  /// The check of the chosen hyper-parameters on held-out contiguous blocks of the data
  /// (fit/fit_check.h). kEvidence: the runs of the search are checked best objective first and
  /// the first that passes is taken; when none passes and the prior is active, the search is
  /// repeated from the data-derived start alone with the prior's widths divided by
  /// prior_tightening_factor, up to max_prior_tightenings times, and the first that passes is
  /// taken; when none passes, the best objective of the search with the prior as given is kept
  /// and FitSummary::warnings says so (a tighter prior is kept only when it passes). Other
  /// methods: checked, warned.
  FitCheckOptions check;
  /// Calibrate the 2 sigma bands on the held-out check: when it ran, each joint's latent
  /// variance is scaled by the smallest factor >= 1 with which its band covers
  /// check.target_coverage of the held-out torques (FitCheck::latent_variance_scale,
  /// RobotModel::latent_variance_scale). The means are unchanged, and so is a band that
  /// already covers enough; a wider band only where the model itself is unsure (far from
  /// its data), not where the noise dominates. false: the posterior's own variance.
  bool calibrate_bands = true;
  int max_prior_tightenings = 4;
  double prior_tightening_factor = 2.0;
  /// kEvidence on feature-map models with OutputScaling::kPerJointRms: profile the noise
  /// level and the output scales by evidence (a cheap one-dimensional search per output)
  /// before LBFGS.
  bool profile_noise_and_scales = true;
  /// kEvidence on kernel models: the kernel's hyper-parameters are fitted on at most this many
  /// rows (core/row_subset.h: evenly spaced); the model then uses all rows (up to
  /// RobotModelOptions::batch.max_kernel_rows). 0 = every row.
  int max_evidence_rows = 1000;
  /// kEvidence and kFixed on lagk models: the search of hyper/euler_lagrange_fit.h (its sigma
  /// grid, per-link weights, iterations and evidence rows); friction, its Coulomb width and the
  /// inducing states come from the model (spec "+fri", RobotModelOptions). Its evidence is
  /// dense in rows x joints, O((m N)^3) per evaluation: it uses at most
  /// max_euler_lagrange_evidence_values / N evenly spaced rows (400 at six joints).
  EulerLagrangeGPOptions euler_lagrange;
  int max_euler_lagrange_evidence_values = 2400;

  /// kCrossValidation: number of contiguous folds (>= 2, at most the number of rows).
  int cv_folds = 5;
  /// kCrossValidation: shape values tried, as offsets from the map's default (log units).
  std::vector<double> cv_shape_offsets = {-2.0, -1.0, 0.0, 1.0, 2.0};
  /// kCrossValidation: noise levels sigma_n tried, relative to each joint's torque scale.
  std::vector<double> cv_noise_levels = {0.3, 0.1, 0.03, 0.01, 0.003, 0.001};

  /// Threads of the hyper-parameter search: accumulating Phi^T Phi of feature-map models, the
  /// joints searched at once with per_joint, and each evidence evaluation of lagk's search (EulerLagrangeGPOptions::num_threads, which
  /// this replaces; the result equals the one-thread result up to rounding). The final fit
  /// uses RobotModelOptions::batch.
  int num_threads = 1;

  /// Called with every progress line and after every LBFGS iteration; kAbort stops the fit
  /// (FitTermination::kUserAbort, the model is left as it was). Called on the thread that
  /// called FitModel. May be empty.
  std::function<FitCallbackReturn(const FitProgress&)> callback;

  /// Each joint its own hyper-parameters (Hyperparameters::per_output: shape, block scales,
  /// noise and output scale): the search, its prior and its held-out check run on each joint's
  /// torque alone, one after the other (about N times the cost of one shared search), then the
  /// held-out check of all joints; the model holds one posterior per joint (N factors instead of
  /// one). pol, motor, rbf and rbfs; rbd, lag and lagk share their parameters across joints
  /// (std::invalid_argument). The online learner needs the shared set (one posterior factor
  /// updated per sample). With num_threads > 1 up to num_threads joints are searched at once
  /// (the same result as one at a time on num_threads / workers threads each; one at a time
  /// when evidence.iteration_callback is set); `callback` is still called on the calling thread.
  bool per_joint = false;

  /// Options of the RobotModel that FitModel(spec, ...) builds.
  RobotModelOptions model;

  /// True when the options are usable; otherwise false with the reason in *error (may be
  /// null).
  bool IsValid(std::string* error) const;
};

/// How a fit ended.
enum class FitTermination {
  /// The hyper-parameter search ended normally (evidence: a tolerance was met; cross-
  /// validation: the grid was scored; fixed: nothing to search) and the model is fitted.
  kConverged,
  /// The evidence search stopped at its iteration or time limit; the model is fitted at the
  /// best point evaluated.
  kMaxIterations,
  /// The evidence search found no step that lowers the objective (usually at a bound, or at
  /// the limit of rounding); the model is fitted at the best point evaluated.
  kLineSearchFailed,
  /// FitOptions::callback or MaximumLikelihoodOptions::iteration_callback asked to stop. The
  /// model is left as it was.
  kUserAbort,
  /// Numerical failure; the model is left as it was. The message names the cause.
  kFailure,
};

/// "converged", "max_iterations", "line_search_failed", "user_abort", "failure".
const char* ToString(FitTermination termination);

struct FitSummary {
  FitTermination termination = FitTermination::kFailure;
  /// Why it ended, from the stage that decided.
  std::string message;
  HyperparameterMethod method = HyperparameterMethod::kEvidence;
  /// One line on how the hyper-parameters were chosen, e.g. "type-II maximum likelihood
  /// (converged, 23 iterations)".
  std::string method_description;
  /// More lines: hyper-parameters at a bound, subsets of rows used, ...
  std::vector<std::string> notes;
  /// Lines the user must read: the fitted model failed its held-out check.
  std::vector<std::string> warnings;

  /// Evidence search: LBFGS iterations of the run taken, and evaluations of the evidence (all
  /// kinds, every run).
  int iterations = 0;
  int num_evaluations = 0;
  /// Evidence search: -log p(Y) at the start and at the result, nats (NaN when not searched).
  double initial_negative_log_evidence = 0.0;
  double final_negative_log_evidence = 0.0;
  /// Evidence search: -log p(x) of the prior at the result (0 without a prior).
  double final_negative_log_prior = 0.0;
  /// Names of the hyper-parameters that ended within kAtBoundDistance of a bound.
  std::vector<std::string> at_bounds;
  /// Evidence search: every LBFGS run of the search the result came from (objectives
  /// -log p(Y) - log p(x) in nats, MaximumLikelihoodStart), the run with the lowest objective
  /// and the run taken (they differ when the best failed the held-out check); -1 when not
  /// searched.
  std::vector<MaximumLikelihoodStart> starts;
  int best_start = -1;
  int chosen_start = -1;
  /// Evidence search: how many times the prior was tightened after failed checks (the result
  /// comes from the last search when its check passed, else from the first).
  int prior_tightenings = 0;
  /// The held-out check of the chosen hyper-parameters (check.ran false when not run).
  FitCheck check;
  /// Cross-validation: held-out mean nMSE of the chosen candidate, candidates scored.
  double cv_mean_nmse = 0.0;
  int cv_candidates = 0;

  /// Rows given, rows the hyper-parameter search evaluated, rows the fitted model holds.
  int rows = 0;
  int hyperparameter_rows = 0;
  int model_rows = 0;

  /// Wall-clock seconds of the hyper-parameter search and of the whole call.
  double hyperparameter_seconds = 0.0;
  double total_seconds = 0.0;

  /// FitOptions::per_joint: each joint's own search, in joint order (its method description,
  /// iterations, starts, evidence of its torque, its held-out check, notes and warnings). The
  /// fields above then hold the sums of iterations, evaluations and evidence (the outputs are
  /// independent, so the evidence of all is the sum), every joint's notes and warnings
  /// prefixed with its name, and the held-out check of all joints with their own sets; starts
  /// are per joint only. Empty otherwise.
  std::vector<FitSummary> joints;

  /// True when the model was fitted (kConverged, kMaxIterations, kLineSearchFailed).
  bool IsUsable() const;
  /// One line: method, termination, iterations, evidence, time.
  std::string BriefReport() const;
};

/// Chooses the hyper-parameters of *model by options.method and fits it to every row.
/// states: m x 3N (q, qd, qdd), torques: m x N, t: m times in seconds, or empty when the
/// data have none (then the model must not use the time). Rows in time order (the folds of
/// cross-validation are contiguous). Throws std::invalid_argument on caller mistakes (see the
/// file comment); a numerical failure is a termination value.
FitSummary FitModel(const FitOptions& options, const ConstMatrixRef& states,
                    const ConstMatrixRef& torques, const ConstVectorRef& t, RobotModel* model);

/// "the latent variance of joints 1, 5 and 6 scaled by 4.65, 10.1, 7.92": a model's calibrated
/// bands (RobotModel::latent_variance_scale) in words, empty when they are the posterior's own.
std::string CalibratedBandsText(const RobotModel& model);

/// A model with the summary of its fit.
struct FittedModel {
  RobotModel model;
  FitSummary summary;
};

/// Builds the model of spec for torques.cols() joints with options.model, then fits it as
/// above. Throws std::invalid_argument when the spec cannot be built for that robot.
FittedModel FitModel(const ModelSpec& spec, const ConstMatrixRef& states,
                     const ConstMatrixRef& torques, const ConstVectorRef& t,
                     const FitOptions& options = FitOptions());

/// The model's inputs for these data: the states, followed by t when the model uses the
/// time. Throws std::invalid_argument when the model needs t and t is empty, or on sizes.
Matrix ModelInputs(const RobotModel& model, const ConstMatrixRef& states, const ConstVectorRef& t);

/// Multi-line description of a fitted model and its fit (one line saying why when the fit is
/// not usable): features and form, how the
/// hyper-parameters were chosen (with the notes), every hyper-parameter, the noise per joint,
/// the log evidence and the friction and effect coefficients with their posterior std.
std::string FitReport(const RobotModel& model, const FitSummary& summary);

/// Starts FitModel's hyper-parameter search from `model`'s, where its kind has such a start: a
/// fitted lagk model's hyper-parameters, at its sigma (EulerLagrangeGPOptions::start). A model
/// with effects added is refitted so (RunDiagnosisLoop, `structgp fit --start-from`). Returns
/// false, with *options unchanged, for any other model.
bool StartFromModel(const RobotModel& model, FitOptions* options);

/// The same as JSON (`structgp fit --json`): {"model", "num_joints", "form", "size",
/// "summary": every field of FitSummary (enums as their ToString words, each start's
/// termination, iterations and objective, the held-out check), and when the fit is usable
/// "log_marginal_likelihood", "noise_std" (per joint) and "coefficients" (RobotModel::
/// Coefficients: name, joint, value, std)}. Numbers that are not finite are written as null.
std::string ToJson(const RobotModel& model, const FitSummary& summary);

}  // namespace structgp

#endif  // STRUCTGP_FIT_FIT_MODEL_H_
