#ifndef STRUCTGP_HYPER_EULER_LAGRANGE_FIT_H_
#define STRUCTGP_HYPER_EULER_LAGRANGE_FIT_H_

/// @file
/// The fitting workflow of an EulerLagrangeGP: type-II maximum likelihood of its part weights
/// and per-joint noise levels (Ceres LBFGS on their logs, analytic gradient) at each sigma of a
/// grid on evenly spaced rows, the best evidence winning; then the posterior on every row,
/// exactly or through inducing states that cover the training states (DTC). Options -> Summary.

#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "structgp/core/status.h"
#include "structgp/core/types.h"
#include "structgp/hyper/hyperprior.h"
#include "structgp/model/euler_lagrange_gp.h"

namespace structgp {

struct EulerLagrangeGPOptions {
  /// One weight per link's kinetic and potential energy (2N); false: link N's only (one
  /// kinetic and one potential energy for the whole chain, 2 weights).
  bool per_link = true;
  std::vector<double> sigmas = {1.0, 3.0, 10.0, 30.0, 100.0};
  /// Semi-parametric friction, its prior std the joint's RMS torque and its velocity scale the
  /// joint's RMS velocity.
  bool friction = false;
  double coulomb_width = 0.01;
  /// Effects (model/euler_lagrange_gp.h): their features of the 3N states, or of the states
  /// and the time (X's last column then), and each feature's prior variance (both empty: none);
  /// each joint's scale s_i is its RMS torque.
  std::shared_ptr<const FeatureMap> effects;
  Vector effect_prior_variance;
  /// Type-II maximum likelihood on this many evenly spaced rows (0 or more than m: all).
  int hyperparameter_rows = 800;
  /// Condition on every row through this many inducing states (DTC); 0: exactly.
  int inducing_states = 0;
  /// How they are chosen (EulerLagrangeGP::InducingRows): kCoverStates (spread over the
  /// states) or kEvenlySpaced (spread over time, which can alias with a periodic trajectory).
  using InducingRule = EulerLagrangeGP::InducingRule;
  InducingRule inducing_rule = InducingRule::kCoverStates;
  /// Threads of each evidence evaluation of the search (EulerLagrangeEvidence) and workers of
  /// the DTC's accumulation over the training states (EulerLagrangeGP::Condition).
  int num_threads = 1;
  int max_iterations = 80;
  /// The prior on the searched log values (type-II MAP, as FitModel's other searches): each
  /// searched part's log weight centred on its data-derived start at each sigma (the torques'
  /// mean square shared by the parts) with width prior.block_scale_width, each joint's log
  /// noise on 10% of its RMS torque with width prior.noise_width. The sigma whose evidence plus
  /// log prior is largest wins. Without it (kNone) a part that the evidence rows hardly excite
  /// (a light link's kinetic energy on a slow log) can be switched off (its weight driven to
  /// e^-15), and predictions of motions that need it are then confident and wrong. With a start
  /// the centres stay the data-derived ones, so a refit from a model maximises the same
  /// objective as a fit from scratch. FitModel passes FitOptions::evidence.prior.
  HyperpriorOptions prior;
  /// Start the search from these hyper-parameters instead of the grid's data-derived starts
  /// (a model refitted with an effect added: the diagnosis loop passes the model's own): at
  /// their sigma alone (`sigmas` is then not used), from their part weights and noise levels,
  /// so that the refit stays at the model's optimum where the added effect leaves it one.
  /// Friction's and the effects' scales stay data-derived, as without it. Must have the data's
  /// number of joints and positive weights on the searched parts.
  std::optional<EulerLagrangeGPHyperparameters> start;
  /// Throws std::invalid_argument naming the first bad field.
  void Validate() const;
};

struct EulerLagrangeGPSummary {
  Status status = Status::kOk;
  std::string message;  // why, when status is not kOk
  EulerLagrangeGPHyperparameters hyperparameters;
  double log_evidence = 0.0;  // of the hyper-parameter rows, at the chosen hyper-parameters
  double log_prior = 0.0;     // log p(x) of the prior there (0 at its centre; 0 without one)
  std::vector<double> sigmas, log_evidence_per_sigma;  // NaN where the search was not usable
  std::vector<double> log_prior_per_sigma;             // at each sigma's optimum
  /// LBFGS iterations at each sigma, and whether its search started from the previous sigma's
  /// optimum (the start with the larger evidence of the two: see FitEulerLagrangeGP).
  std::vector<int> iterations_per_sigma;
  std::vector<bool> warm_start_per_sigma;
  /// Evaluations of the evidence (with its gradient) at each sigma, and the evidence at the
  /// first sigma's start (NaN when it was not finite).
  std::vector<int> evaluations_per_sigma;
  double initial_log_evidence = std::numeric_limits<double>::quiet_NaN();
  int hyperparameter_rows = 0;
  int rows = 0;
  int inducing_states = 0;  // 0: exact
  double seconds = 0.0;
  /// What a user should know about the fit, one sentence each: the searched parts that the
  /// hyper-parameter rows do not excite (their prior variance there at rounding level, e.g. a
  /// log without joint accelerations leaves link 1's kinetic energy unseen), whose weights
  /// start from the median of the other parts' and stay near it, not measured by the data.
  std::vector<std::string> warnings;
};

/// The search's data-derived start at one sigma, without searching: the part weights share
/// the torques' mean square (each part scaled by its mean prior variance on the evidence rows;
/// a part they do not excite, its variance at most 1e-12 of the largest part's, at the median
/// of the other parts' log weights),
/// noise 10% of each joint's RMS torque, friction's prior std that RMS and its velocity scale
/// the joint's RMS velocity. Throws std::invalid_argument as FitEulerLagrangeGP.
EulerLagrangeGPHyperparameters EulerLagrangeStart(const ConstMatrixRef& X, const ConstMatrixRef& Y,
                                                  const EulerLagrangeGPOptions& options,
                                                  double sigma);

/// The sigmas are searched in increasing order (options.prior: evidence plus log prior
/// maximised, and compared between sigmas). At each one the search starts from the
/// data-derived start (EulerLagrangeStart) or from the optimum of the sigma before it (each
/// part's weight carried over at the same mean prior variance, the noise levels as they were),
/// whichever has the larger evidence: neighbouring sigmas have neighbouring optima, so the
/// warm start saves iterations and is never a worse start than the cold one.
///
/// On a failure the summary's status says why and *gp is left empty. With gp null only the
/// hyper-parameters are chosen (no posterior is computed; inducing_states unused). Throws
/// std::invalid_argument on bad sizes, non-finite data or bad options.
EulerLagrangeGPSummary FitEulerLagrangeGP(const ConstMatrixRef& X, const ConstMatrixRef& Y,
                                          const EulerLagrangeGPOptions& options,
                                          std::optional<EulerLagrangeGP>* gp);

}  // namespace structgp

#endif  // STRUCTGP_HYPER_EULER_LAGRANGE_FIT_H_
