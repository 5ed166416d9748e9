#ifndef STRUCTGP_MODEL_WEIGHT_SPACE_GP_H_
#define STRUCTGP_MODEL_WEIGHT_SPACE_GP_H_

/// @file
/// The weight-space (feature) form of a Gaussian process: Bayesian linear regression on an
/// explicit feature vector phi in R^D, with P outputs that share one posterior factor.
///
/// Model, for output j = 1..P with scale s_j:
///     y_j = phi^T w_j + e,   w_j ~ N(0, s_j^2 Lambda),   e ~ N(0, s_j^2 sigma_n^2 / v),
/// where Lambda is diagonal and v is the sample's weight (1 unless forgetting or weighting).
/// The posterior precision (in units of s_j^2 sigma_n^2) is
///     A = sum_i v_i phi_i phi_i^T + sigma_n^2 Lambda^{-1},
/// the same for every output; W = A^{-1} Phi^T V Y is the posterior mean of the weights,
/// the latent predictive variance of output j is s_j^2 sigma_n^2 phi^T A^{-1} phi.
///
/// Representation. The model keeps the upper-triangular S with A^{-1} = S S^T (S = L^{-T}
/// when A = L L^T), and W. Adding a sample is Carlson's triangular rank-one update of S,
/// which yields the gain A'^{-1} phi in the same pass. UpdateAndPredict goes further: it
/// stages the update of S and applies it in the same pass that projects the next sample, so
/// a control-loop step (update, keep W current, predict mean and variance at the next state)
/// reads and writes S once. Every result is exact at all times: a non-const reader applies a
/// staged change first, a const prediction reads through it (see below). Removing a sample
/// is the same update with negative weight, and is refused with kNotPositiveDefinite when it
/// would leave A indefinite (phi^T A^{-1} phi * v >= 1 - kMinDowndateMargin).
///
/// Forgetting with factor lambda in (0, 1] multiplies every earlier sample's weight AND the
/// prior precision by lambda before the new sample is added (A <- lambda A + v phi phi^T).
/// After n such steps the model is exactly the batch posterior of the weighted samples with the
/// prior variance Lambda / lambda^n; tests check this equivalence. Directions that the data
/// stop exciting therefore grow in variance, as in every exponentially forgetting estimator.
///
/// Ill-conditioning policy (see docs/reliability.md). Every numerical trouble ends in a Status
/// the caller sees, never in a NaN inside the model:
/// - Construction and Reset require every ratio Lambda_k / sigma_n^2 to lie in
///   [1 / kMaxPriorToNoiseRatio, kMaxPriorToNoiseRatio] (std::invalid_argument otherwise), so
///   that the initial factor S = diag(sqrt(Lambda / sigma_n^2)) is finite and positive.
/// - Fit accepts the Cholesky factor L of A only when every pivot satisfies
///   L_kk^2 >= kMinPivotRatio * A_kk, i.e. no feature direction is, to working precision, a
///   combination of the earlier ones (duplicate samples, collinear features or a tiny noise can
///   make A singular). The test is invariant to the scaling of the features. Otherwise Fit
///   factorises A + delta diag(A) (a relative jitter) along a bounded ladder:
///   delta = kJitterFirst, times kJitterGrowth at each step, at most kMaxJitterSteps steps;
///   fit_jitter() records the delta used (0 when none was needed). When the last step fails
///   too, Fit returns kNotPositiveDefinite and leaves the model unchanged.
/// - Update and UpdateAndPredict cannot lose definiteness (A only gains v phi phi^T), but
///   forgetting multiplies the variance of directions the data do not excite (zero velocities
///   under friction features, say) by 1/lambda per step, without bound. A forgetting step
///   (or a downdate) that could make the largest weight variance in units of sigma_n^2,
///   max_k (S S^T)_kk, exceed kMaxPriorToNoiseRatio is refused with kNotPositiveDefinite (model
///   unchanged): the caller can add the sample without forgetting (lambda = 1) or Reset. The
///   test is O(1) per step: the model keeps a lower bound of the remaining headroom (a step
///   with forgetting lambda multiplies every variance by at most 1/lambda, a downdate by at most
///   1/margin) and recomputes it exactly, O(D^2) without allocating, only when the bound runs
///   out; data that excite every direction therefore never hit it. A sample whose prediction
///   error overflows (huge phi) is refused with kInvalidInput. No rank-one update adds jitter:
///   the model stays the exact posterior.
/// - Predict and PredictWithVariance return kInvalidInput when a result is not finite (only for
///   inputs of absurd magnitude); variances are never negative.
///
/// Real-time contract: after construction, Update, Downdate, Predict and PredictWithVariance
/// allocate no memory, take no lock and throw no exception; bad input returns kInvalidInput
/// and leaves the model unchanged.
///
/// Threads (model apart from workspace): const methods change nothing, not even the staged
/// change of UpdateAndPredict (a const prediction reads through it by Sherman-Morrison, as
/// UpdateAndPredict's own prediction does). Their scratch is a Workspace the caller owns
/// (MakeWorkspace(), one per thread), so one const model may serve concurrent readers. The
/// accessors weights(), covariance_factor(), State(), WeightCovariance and the evidence have
/// non-const overloads that apply a staged change first; their const versions throw
/// std::logic_error while one is staged (has_staged_update()). The predictions without a
/// workspace are non-const and use the model's own scratch.

#include "structgp/core/status.h"
#include "structgp/core/types.h"
#include "structgp/internal/cholesky.h"
#include "structgp/model/sufficient_statistics.h"

namespace structgp {

/// Minimum 1 - v phi^T A^{-1} phi accepted by a downdate. Below it the downdated precision
/// would have a condition number above ~1/kMinDowndateMargin relative to the current one, or
/// be indefinite; the downdate is refused instead.
inline constexpr double kMinDowndateMargin = 1e-10;

/// The acceptance test and the jitter ladder of Fit are the library's one positive-definite
/// factorisation policy (internal/cholesky.h, docs/reliability.md); their constants, under the
/// names this header has always given them:
/// a batch factorisation is accepted when every pivot satisfies L_kk^2 >= kMinPivotRatio A_kk
/// (L_kk^2 / A_kk is the part of feature k's precision not explained by the features before
/// it; below ~1e-13, a few hundred eps, it is rounding error and the factor mostly noise).
inline constexpr double kMinPivotRatio = internal::kMinPivotRatio;
/// First relative jitter of Fit's ladder (A + delta diag(A)): a hundred times the pivot floor,
/// so that the first step normally succeeds.
inline constexpr double kJitterFirst = internal::kJitterFirst;
/// Factor between consecutive jitters of the ladder.
inline constexpr double kJitterGrowth = internal::kJitterGrowth;
/// Number of jitter steps before Fit gives up: the largest jitter is
/// kJitterFirst * kJitterGrowth^(kMaxJitterSteps - 1) = 1e-5 (relative to diag(A)).
inline constexpr int kMaxJitterSteps = internal::kMaxJitterSteps;
/// Largest (and inverse of the smallest) ratio of a prior variance to the noise variance,
/// Lambda_k / sigma_n^2, and largest weight variance in units of sigma_n^2, (S S^T)_kk, that
/// forgetting may reach. It keeps the entries of S far from overflow: squares of 1e100 are
/// still finite.
inline constexpr double kMaxPriorToNoiseRatio = 1e200;

/// True when every Lambda_k / sigma_n^2 lies in [1 / kMaxPriorToNoiseRatio,
/// kMaxPriorToNoiseRatio] (false for NaN or a non-positive noise variance): the priors a
/// WeightSpaceGP accepts.
bool PriorToNoiseRatioOk(const Vector& prior_variance, double noise_variance);

/// Whether WeightSpaceGP::Fit may add jitter when the precision is singular to working
/// precision (the ladder of the policy above).
enum class FitJitter {
  kLadder,  ///< try the bounded jitter ladder before giving up (fitting a model)
  kNone,    ///< give up at once (evidence for hyper-parameter search: an exact value or none)
};

/// Derivatives of the log marginal likelihood.
struct EvidenceGradient {
  /// d log p(Y) / d log Lambda_k, one per feature (size D). A block scale or a shape
  /// parameter follows by the chain rule (see hyper/evidence.h).
  Vector d_log_prior_variance;
  /// d log p(Y) / d log sigma_n.
  double d_log_noise_std = 0.0;
  /// d log p(Y) / d log s_j, one per output (size P).
  Vector d_log_output_scale;
};

/// The complete state of a WeightSpaceGP: everything its later results depend on, so that a
/// model can be saved and restored exactly (io/model_file.h). Field names follow the model's
/// accessors; the sums are the evidence counters of the samples seen since the last
/// Fit/Reset, weighted and forgotten as described above.
///
/// Invariants (checked by WeightSpaceGP::FromState): prior_variance (D) > 0, noise_variance
/// > 0, output_scales (P) > 0; covariance_factor is D x D, upper-triangular (strictly lower
/// part exactly zero) with a positive diagonal, and no posterior variance above the prior one:
/// diag(S S^T)_k <= Lambda_k exp(log_prior_broadening) / noise_variance (to a relative 1e-6);
/// weights is D x P; y_squared has P entries; every value is finite.
struct WeightSpaceGPState {
  Vector prior_variance;              ///< Lambda (D)
  double noise_variance = 0.0;        ///< sigma_n^2
  Vector output_scales;               ///< s (P)
  Matrix covariance_factor;           ///< S, A^{-1} = S S^T (D x D, upper-triangular)
  Matrix weights;                     ///< W (D x P)
  Vector y_squared;                   ///< per output, sum v y^2 (P)
  double weight_sum = 0.0;            ///< sum v (effective_count())
  double log_weight_sum = 0.0;        ///< sum log v
  double log_prior_broadening = 0.0;  ///< log of the prior broadening by forgetting
  double sample_count = 0.0;          ///< samples absorbed (with the sign of downdates)
  long num_samples = 0;               ///< num_samples()
};

class WeightSpaceGP {
 public:
  /// A model of num_features features and num_outputs outputs, at the prior given by
  /// prior_variance (Lambda, size D, all > 0), noise_variance (sigma_n^2 > 0) and
  /// output_scales (size P, all > 0; empty means all 1). Allocates all storage (O(D^2)).
  /// Throws std::invalid_argument on bad sizes or values.
  WeightSpaceGP(const Vector& prior_variance, double noise_variance, int num_outputs,
                const Vector& output_scales = Vector());

  int num_features() const { return static_cast<int>(prior_variance_.size()); }
  int num_outputs() const { return static_cast<int>(weights_.cols()); }

  /// Changes the prior and noise and returns the model to the prior (no data).
  void Reset(const Vector& prior_variance, double noise_variance,
             const Vector& output_scales = Vector());

  /// Batch fit: replaces the posterior by the one given the samples in stats, with the
  /// current prior. O(D^3). When the precision is singular to working precision, a jitter
  /// from the bounded ladder above is added to its diagonal (see fit_jitter()); when even the
  /// largest fails (or at once with FitJitter::kNone), returns kNotPositiveDefinite and leaves
  /// the model unchanged. Throws on size mismatch.
  Status Fit(const SufficientStatistics& stats, FitJitter jitter_policy = FitJitter::kLadder);
  /// Batch fit from features Phi (m x D) and targets Y (m x P).
  Status Fit(const ConstMatrixRef& Phi, const ConstMatrixRef& Y);

  /// Adds one sample (phi, y) with weight `weight` > 0, after forgetting with factor
  /// `forgetting` in (0, 1]. O(D^2), allocation-free. kInvalidInput (model unchanged) on a
  /// size mismatch, a non-finite value or a weight/forgetting out of range.
  Status Update(const ConstVectorRef& phi, const ConstVectorRef& y, double forgetting = 1.0,
                double weight = 1.0);

  /// Removes a sample previously added with the given weight. kNotPositiveDefinite (model
  /// unchanged) when that would lose definiteness; kInvalidInput on bad input.
  Status Downdate(const ConstVectorRef& phi, const ConstVectorRef& y, double weight = 1.0);

  /// Sizes the scratch of UpdateBatch for up to max_steps steps per call (allocates
  /// O(D max_steps + P max_steps); 0 frees it). Copies of the model keep the capacity.
  void ReserveBatch(int max_steps);
  /// Largest k UpdateBatch accepts (0 until ReserveBatch).
  int batch_capacity() const { return batch_capacity_; }

  /// k rank-one changes in order, as k calls of Update and Downdate would make them, with
  /// one projection pass and one update pass over S for all of them (the blocked form of the
  /// rank-one update: docs/derivations.md). Step i uses column i of Phi (D x k) and of Y
  /// (P x k): weights[i] > 0 forgets with forgetting[i] in (0, 1] and adds the sample with
  /// that weight (Update); weights[i] < 0 removes a sample added with weight -weights[i]
  /// (Downdate; forgetting[i] must be 1). The result equals the sequence of single calls to
  /// rounding (not bit for bit: the projections of later steps go through the earlier steps'
  /// modifications). Every step is checked as its single call would check it; at the first
  /// step the single call would refuse, the steps before it are applied, its status is
  /// stored in *status (when not null) and its index returned (k and kOk when every step is
  /// applied). O(k D^2) arithmetic, O(k^2 D) more for the coupling of the steps;
  /// allocation-free for k <= batch_capacity() (kInvalidInput and nothing applied beyond, or
  /// on mismatched sizes).
  int UpdateBatch(const ConstMatrixRef& Phi, const ConstMatrixRef& Y,
                  const ConstVectorRef& forgetting, const ConstVectorRef& weights,
                  Status* status = nullptr);

  /// Scratch of the const predictions: S^T phi (D doubles).
  struct Workspace {
    Vector projection;
  };
  /// A workspace for this model (D doubles; allocates).
  Workspace MakeWorkspace() const { return Workspace{Vector(num_features())}; }

  /// Predictive mean at phi into mean (size P). O(D P) (O(D^2) while an update is staged).
  /// kInvalidInput on bad input or a workspace of the wrong size. Allocation-free; safe for
  /// concurrent calls with one workspace each.
  Status Predict(const ConstVectorRef& phi, VectorRef mean, Workspace& workspace) const;
  /// Predictive mean and variances at phi: latent (of f) and noisy (of a new observation y),
  /// each of size P. O(D^2). kInvalidInput on bad input or a workspace of the wrong size.
  /// Allocation-free; safe for concurrent calls with one workspace each.
  Status PredictWithVariance(const ConstVectorRef& phi, VectorRef mean, VectorRef latent_variance,
                             VectorRef noisy_variance, Workspace& workspace) const;
  /// The same with the model's own scratch, after applying a staged update (allocation-free;
  /// not for concurrent use).
  Status Predict(const ConstVectorRef& phi, VectorRef mean);
  Status PredictWithVariance(const ConstVectorRef& phi, VectorRef mean, VectorRef latent_variance,
                             VectorRef noisy_variance);

  /// One control-loop step: Update with (phi_update, y, forgetting), then predict at
  /// phi_predict with the updated model. Exactly equal to calling the two in turn, but reads
  /// S once less (the prediction is corrected by Sherman-Morrison). Pass empty latent_variance
  /// and noisy_variance vectors (size 0) to skip the variance. On failure nothing is changed.
  Status UpdateAndPredict(const ConstVectorRef& phi_update, const ConstVectorRef& y,
                          const ConstVectorRef& phi_predict, VectorRef mean,
                          VectorRef latent_variance, VectorRef noisy_variance,
                          double forgetting = 1.0);

  /// Log marginal likelihood log p(Y) of the (weighted) samples seen since the last Fit/Reset,
  /// under the current prior (including the prior broadening caused by forgetting). O(D^2 P).
  /// Const versions: std::logic_error while an update is staged (see the file comment).
  double LogMarginalLikelihood() const;
  double LogMarginalLikelihood();
  /// The same, with its derivatives. O(D^2 P).
  double LogMarginalLikelihood(EvidenceGradient* gradient) const;
  double LogMarginalLikelihood(EvidenceGradient* gradient);

  /// Posterior mean of the weights, D x P.
  const Matrix& weights() const;
  const Matrix& weights();
  /// Upper-triangular S with A^{-1} = S S^T (the strictly lower part is zero).
  const Matrix& covariance_factor() const;
  const Matrix& covariance_factor();
  /// Posterior covariance of the weights of output j: s_j^2 sigma_n^2 S S^T. O(D^3).
  Matrix WeightCovariance(int output) const;
  Matrix WeightCovariance(int output);
  /// True between UpdateAndPredict and the next non-const call (which applies the change).
  bool has_staged_update() const { return staged_; }
  /// Applies a staged update now (one O(D^2) pass; nothing when none is staged).
  void ApplyStagedUpdate() { Commit(nullptr, nullptr, nullptr, nullptr); }
  /// The prior variance currently in force: Lambda / lambda^n after n forgetting steps.
  Vector effective_prior_variance() const;
  const Vector& prior_variance() const { return prior_variance_; }
  double noise_variance() const { return noise_variance_; }
  const Vector& output_scales() const { return output_scales_; }
  /// The model's complete state (the non-const version applies a staged update first; the
  /// const one throws std::logic_error while one is staged). O(D^2) copy; allocates.
  WeightSpaceGPState State() const;
  WeightSpaceGPState State();
  /// A model in exactly the given state: every later result (prediction, update, evidence)
  /// is bit-identical to that of the model State() was taken from. Allocates all storage.
  /// Throws std::invalid_argument naming the field when the state breaks an invariant of
  /// WeightSpaceGPState.
  static WeightSpaceGP FromState(const WeightSpaceGPState& state);

  /// The relative jitter delta of the last successful Fit, which factorised A + delta diag(A)
  /// (0 when the factorisation needed none, and after Reset). Updates never add jitter.
  double fit_jitter() const { return fit_jitter_; }

  /// Sum of the weights of the samples in the posterior (m without forgetting).
  double effective_count() const { return weight_sum_; }
  /// Number of samples absorbed since the last Fit/Reset (Fit counts its samples).
  long num_samples() const { return num_samples_; }

 private:
  // Brings S and W up to date with the sample deferred by UpdateAndPredict, if any, in one
  // pass over S; in the same pass y1 = S'^T x1 and y2 = S'^T x2 when x1 is not null (x2 may be
  // null: then only y1). Without a deferred sample it is a plain projection.
  void Commit(const double* x1, const double* x2, double* y1, double* y2);
  // Prepares the rank-one change for f = work_f_ (already scaled), observation variance r and
  // covariance scale `scale`, with prediction error work_err_; Commit applies it.
  void Stage(double r, double scale, double alpha);
  // Throws std::logic_error naming `what` while an update is staged.
  void RequireNotStaged(const char* what) const;
  // Evidence bookkeeping of one added (sign +1) or removed (sign -1) sample.
  void Account(const ConstVectorRef& y, double forgetting, double weight, double sign);
  bool InputOk(const ConstVectorRef& phi, const ConstVectorRef& y) const;
  // Recomputes log_variance_headroom_ exactly from S (after applying a staged change). O(D^2),
  // allocation-free (uses work_h_ as scratch).
  void RefreshHeadroom();
  // Takes `cost` (the log of the largest factor by which a step may multiply a variance) from
  // the headroom, refreshing it first when it is short; false (nothing taken) when even the
  // exact headroom is too small.
  bool TakeHeadroom(double cost);

  Vector prior_variance_;  // Lambda (D)
  double noise_variance_;  // sigma_n^2
  Vector output_scales_;   // s (P)

  // S (D x D, upper triangle; A^{-1} = S S^T) and W (D x P). A staged rank-one change is
  // applied at the next non-const call.
  Matrix factor_;
  Matrix weights_;

  // Data summaries for the evidence (all weighted): sum v y^2 per output, sum v, sum log v,
  // the log of the factor by which the prior variance has been broadened by forgetting.
  Vector y_squared_;
  double weight_sum_ = 0.0;
  double log_weight_sum_ = 0.0;
  double log_prior_broadening_ = 0.0;
  double sample_count_ = 0.0;
  long num_samples_ = 0;
  double fit_jitter_ = 0.0;
  // A lower bound of log(kMaxPriorToNoiseRatio) - log(max_k (S S^T)_kk): how much the largest
  // weight variance may still grow before forgetting is refused (see the policy above).
  double log_variance_headroom_ = 0.0;

  // The staged change: Carlson coefficients, 1 / alpha, the prediction error, and for the
  // const reads f = scale S^T phi and the scale.
  bool staged_ = false;
  Vector staged_a_, staged_b_, staged_c_;
  double staged_inv_alpha_ = 0.0;
  Vector staged_err_;
  Vector staged_f_;
  double staged_scale_ = 1.0;

  // Plans steps [begin, k) of UpdateBatch against the current S (coefficients, errors,
  // accounting) until a step needs the exact headroom or is refused; returns the number
  // planned and sets *status (kOk: all planned or the headroom must be refreshed first, with
  // *refresh set).
  int PlanBatch(const ConstMatrixRef& Phi, const ConstMatrixRef& Y,
                const ConstVectorRef& forgetting, const ConstVectorRef& weights, int begin,
                Status* status, bool* refresh);
  // Applies the n planned steps to S and W in one pass.
  void ApplyBatch(int n);

  // UpdateBatch scratch (batch_capacity_ columns each): projections z, f, Carlson
  // coefficients, gains (D x K); errors (P x K); 1 / alpha and scales (K); gain coefficients
  // of W (K x P); the fused pass's broadcast coefficients.
  int batch_capacity_ = 0;
  Matrix batch_z_, batch_f_, batch_a_, batch_b_, batch_c_, batch_gain_;
  Matrix batch_err_;
  Vector batch_inv_alpha_, batch_scale_;
  Matrix batch_coef_;
  Vector batch_splat_;  // broadcast coefficients of the fused pass

  // Scratch of the non-const methods, sized at construction.
  Vector work_f_;     // S^T phi
  Vector work_h_;     // S^T phi2
  Vector work_gain_;  // scale * S f
  Vector work_err_;   // y - W^T phi (P)
};

}  // namespace structgp

#endif  // STRUCTGP_MODEL_WEIGHT_SPACE_GP_H_
