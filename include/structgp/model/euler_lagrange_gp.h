#ifndef STRUCTGP_MODEL_EULER_LAGRANGE_GP_H_
#define STRUCTGP_MODEL_EULER_LAGRANGE_GP_H_

/// @file
/// One Gaussian process for all joint torques of an N-joint serial chain, in kernel form, with
/// the EulerLagrangeKernel (a prior on each link's kinetic and potential energy): the outputs
/// share one (m N) x (m N) system, so every joint's torques inform the energies that the other
/// joints' torques are derived from. No kinematic parameters. Optional semi-parametric friction
/// per joint: bases qd_i / v_i, tanh(qd_i / width) and 1, independent, prior std s_i.
///
/// Optional effects (feature/effects.h, as RobotModel builds them: features of the states, or of
/// the states and the time, shared by the joints, each joint with its own weights): the
/// covariance of joints i and j gains delta_ij s_i^2 phi(x)^T diag(lambda) phi(x'), a broad
/// fixed prior. With effects of the time (drift) the inputs carry the time as a last column,
/// which only the effects read.
///
/// Hyper-parameters: sigma of the kernel's trigonometric factors, the 2N part weights, one noise
/// std per joint (FitEulerLagrangeGP in hyper/euler_lagrange_fit.h chooses them). The posterior
/// is exact, or through inducing states the deterministic training conditional (DTC):
/// O(m N (p N)^2) time and O((p N)^2) memory instead of O((m N)^3) and O((m N)^2).
///
/// Inputs x = (q, qd, qdd) as rows of X (m x 3N), or (q, qd, qdd, t) (m x (3N + 1)) when the
/// effects take the time; torques Y (m x N).

#include <memory>
#include <string>
#include <vector>

#include <Eigen/Cholesky>

#include "structgp/core/hyperparameters.h"
#include "structgp/core/status.h"
#include "structgp/core/types.h"
#include "structgp/feature/feature_map.h"
#include "structgp/kernel/euler_lagrange_kernel.h"

namespace structgp {

namespace internal {
class Cholesky;
}  // namespace internal

struct EulerLagrangeGPHyperparameters {
  double sigma = 1.0;
  Vector part_weights;  // 2N, >= 0: kinetic 1..N, then potential 1..N (the kernel's parts)
  Vector noise_std;     // N, > 0
  /// Friction: empty (none), or N prior stds s_i > 0 with N velocity scales v_i > 0.
  Vector friction_std;
  Vector friction_velocity_scale;
  double coulomb_width = 0.01;  // rad/s, of tanh(qd / width)
  /// Effects: empty (none), or the prior variance lambda of each effect feature with each
  /// joint's scale s_i > 0.
  Vector effect_prior_variance;
  Vector effect_scale;

  int num_joints() const { return static_cast<int>(noise_std.size()); }
  bool friction() const { return friction_std.size() > 0; }
  bool effects() const { return effect_prior_variance.size() > 0; }
  /// Throws std::invalid_argument naming the first bad field.
  void Validate() const;
};

/// The hyper-parameters in the library's common type (core/hyperparameters.h), as RobotModel
/// and the model file hold them: shape = (log sigma, log part_weights (2N), and with friction
/// log friction_std (N), log friction_velocity_scale (N), log coulomb_width, and with effects
/// log effect_scale (N)); no block scales (the effects' prior variances are the model's, not
/// hyper-parameters);
/// joint j's noise std is exp(log_noise_std + log_output_scale[j]) with log_noise_std = 0 (the
/// regressor form's convention: the joints share one prior, so an output scale scales the
/// noise only). A zero part weight is written as log(1e-300).
Hyperparameters ToHyperparameters(const EulerLagrangeGPHyperparameters& hyperparameters);
/// ToHyperparameters: "log_sigma", "log_weight_kinetic_1".. N,
/// "log_weight_potential_1".. N, with friction "log_friction_std_1".. N,
/// "log_friction_velocity_scale_1".. N, "log_coulomb_width", and with effects
/// "log_effect_scale_1".. N.
std::vector<std::string> EulerLagrangeParameterNames(int num_joints, bool friction,
                                                     bool effects = false);
/// The inverse for an N-joint model with or without friction. Throws std::invalid_argument
/// naming the field whose size or value does not fit.
/// effect_prior_variance: the effects' (empty: none).
EulerLagrangeGPHyperparameters EulerLagrangeFromHyperparameters(
    const Hyperparameters& hyper, int num_joints, bool friction,
    const Vector& effect_prior_variance = Vector());

/// The exact log evidence of fixed data at one sigma (and friction) as a function of some part
/// weights and the noise levels: the parts' Gram matrices are computed once, each evaluation
/// costs one Cholesky factorisation of the (m N) x (m N) covariance (and its inverse for the
/// gradient). The parts not searched keep the weights of `base`. Each evaluation runs on
/// num_threads threads (the covariance's columns, the factorisation and the inverse from 256
/// values on, the parts' gradient terms); its value equals the one-thread value up to rounding.
class EulerLagrangeEvidence {
 public:
  /// parts: indices into the kernel's parts (0..2N-1), each once. Throws std::invalid_argument
  /// on bad sizes, non-finite data, a bad part index or num_threads < 1.
  EulerLagrangeEvidence(const EulerLagrangeGPHyperparameters& base, const ConstMatrixRef& X,
                        const ConstMatrixRef& Y, std::vector<int> parts,
                        const FeatureMap* effects = nullptr, int num_threads = 1);

  /// (log w of each searched part, log noise std of each joint).
  int num_parameters() const { return static_cast<int>(parts_.size()) + n_; }
  const std::vector<int>& parts() const { return parts_; }
  /// The mean of each searched part's Gram diagonal (for starting points).
  double MeanPartVariance(int k) const { return grams_[static_cast<size_t>(k)].diagonal().mean(); }

  /// log p(Y), and its gradient (num_parameters()) when gradient is not null; -infinity when
  /// the covariance is not positive definite.
  double Evaluate(const double* log_parameters, double* gradient) const;

 private:
  int n_;
  std::vector<int> parts_;
  std::vector<Matrix> grams_;
  Matrix fixed_;  // friction + the parts not searched
  Vector y_;
  int num_threads_ = 1;
};

class EulerLagrangeGP {
 public:
  /// Throws std::invalid_argument (Validate; effects: a map of 3N inputs, or of 3N + 1 with
  /// the time last, whose dimension is the number of effect prior variances, null exactly when
  /// there are none).
  explicit EulerLagrangeGP(EulerLagrangeGPHyperparameters hyperparameters,
                           std::shared_ptr<const FeatureMap> effects = nullptr);

  const EulerLagrangeGPHyperparameters& hyperparameters() const { return hyper_; }
  const EulerLagrangeKernel& kernel() const { return kernel_; }
  const std::shared_ptr<const FeatureMap>& effects() const { return effects_; }
  int num_joints() const { return hyper_.num_joints(); }
  /// 3N, or 3N + 1 when the effects take the time (its last column).
  int input_dim() const { return input_dim_; }

  /// The posterior on (X, Y): exact when inducing is empty, else DTC through the inducing
  /// states (p x input_dim()). kNotPositiveDefinite when a factorisation fails (the model is then
  /// unchanged). X: m x input_dim(), inducing: p x input_dim(). Throws std::invalid_argument
  /// on bad sizes, non-finite data or num_threads < 1.
  ///
  /// DTC takes the training states in blocks of kDtcBlockStates: each block's covariance with
  /// the inducing states is formed, solved against their factor and its terms added to the
  /// (p N) x (p N) system in block order, so memory is two (p N)^2 factors plus one block's
  /// columns, (p N) x (kDtcBlockStates N), per worker, not the (p N) x (m N) of the whole
  /// cross-covariance. The workers (num_threads, at most the number of blocks) take the blocks
  /// a group at a time, then share the system's rows in panels of kDtcPanelRows; the result is
  /// the same bit for bit for any number of them.
  Status Condition(const ConstMatrixRef& X, const ConstMatrixRef& Y,
                   const ConstMatrixRef& inducing = Matrix(), int num_threads = 1);
  /// Training states per block of the DTC's accumulation (see Condition).
  static constexpr Eigen::Index kDtcBlockStates = 128;
  /// Rows per panel of the system, the unit in which the workers add to it (see Condition).
  static constexpr Eigen::Index kDtcPanelRows = 128;

  /// How the inducing states are chosen among the training states.
  enum class InducingRule {
    kCoverStates,   ///< FarthestStateRows (core/row_subset.h): spread over the states
    kEvenlySpaced,  ///< EvenlySpacedRows: spread over time (can alias with a periodic path)
  };
  /// The rows of X to induce: none (exact) when count is 0 or X has at most count rows, else
  /// count rows by the rule. Throws std::invalid_argument when count < 0.
  static std::vector<int> InducingRows(const ConstMatrixRef& X, int count, InducingRule rule);
  /// The posterior on (X, Y) through the states of InducingRows(X, count, rule): the one place
  /// the library chooses them (GaussianProcess::Fit, FitEulerLagrangeGP).
  Status Condition(const ConstMatrixRef& X, const ConstMatrixRef& Y, int inducing_count,
                   InducingRule rule = InducingRule::kCoverStates, int num_threads = 1);
  bool conditioned() const { return alpha_.size() > 0; }

  /// What a posterior through inducing states holds beyond its data, inducing states,
  /// hyper-parameters and effects: alpha (p N), the lower Cholesky factor of B = I + V V^T
  /// ((p N) x (p N); its upper triangle is not read) and log p(Y). Condition computes them
  /// from every row (minutes at 6-7 joints); RestoreDtc takes them back.
  struct DtcFactors {
    Vector alpha;
    Matrix factor_b;
    double log_evidence = 0.0;
  };
  /// After a Condition through inducing states: alpha and B's factor as held (no copy).
  /// Throws std::logic_error otherwise.
  const Vector& dtc_alpha() const;
  const Matrix& dtc_factor_b() const;
  /// kOk when factors fit a posterior of pn = p N inducing torques: the sizes, every entry
  /// finite (of factor_b's lower triangle), factor_b's diagonal at least 1 (B >= I; 1e-9 below
  /// for rounding), the evidence finite. kInvalidInput otherwise.
  static Status CheckDtcFactors(Eigen::Index pn, const DtcFactors& factors);
  /// The posterior on (X, Y) through `inducing` from the factors of a Condition on the same
  /// data, inducing states, hyper-parameters and effects (a saved model's): K_ZZ is formed and
  /// factorised again ((p N)^3 / 3), as Condition does, and the rest is taken as given, so the
  /// predictions are that Condition's bit for bit without its pass over every row.
  /// kInvalidInput when CheckDtcFactors refuses the factors, kNotPositiveDefinite when K_ZZ
  /// cannot be factorised; the model is then unchanged. Factors of other data or
  /// hyper-parameters are not detected: the caller vouches for them (the model file's
  /// posterior file, by its checksum). Throws std::invalid_argument as Condition on bad data or
  /// inducing states.
  Status RestoreDtc(const ConstMatrixRef& X, const ConstMatrixRef& Y,
                    const ConstMatrixRef& inducing, DtcFactors factors);

  /// The states the posterior is held at: the training states (exact) or the inducing states
  /// (DTC); and the data of the last Condition.
  const Matrix& states() const { return states_; }
  bool dtc() const { return dtc_; }
  const Matrix& inputs() const { return inputs_; }
  const Matrix& targets() const { return targets_; }

  /// Scratch of the one-state predictions (MakeWorkspace), one per thread.
  struct Workspace {
    Matrix ks;     // N x (p N)
    Matrix v;      // (p N) x N
    Matrix block;  // N x N
    Vector phi;    // the effects' features (D)
    Vector g;      // p
  };
  /// Throws std::logic_error when not conditioned. Allocates.
  Workspace MakeWorkspace() const;
  /// The posterior mean (N) and, when latent_variance has N entries, the latent variance at one
  /// input x (input_dim()): allocation-free with a workspace of this posterior, and safe for concurrent
  /// calls with one workspace each. kInvalidInput on bad sizes, a non-finite state or a
  /// workspace of another posterior; throws std::logic_error when not conditioned.
  Status PredictOne(const ConstVectorRef& x, VectorRef mean, VectorRef latent_variance,
                    Workspace& workspace) const;

  /// Posterior mean (m x N) and, when latent_variance is not null, the latent variance (m x N;
  /// add noise_std^2 for the noisy one). kInvalidInput on bad sizes or non-finite states.
  /// Throws std::logic_error when not conditioned.
  Status Predict(const ConstMatrixRef& X, Matrix* mean, Matrix* latent_variance = nullptr) const;

  /// log p(Y) of the conditioned data: exact, or after a DTC condition the DTC's evidence
  /// log N(y; 0, K_XZ K_ZZ^-1 K_ZX + noise) (throws std::logic_error before any condition).
  double LogMarginalLikelihood() const;

  /// log p(Y | X, hyper-parameters), exact, and when gradient is not null its gradient in
  /// (log part_weights (2N), log noise_std (N)). -infinity when the covariance is not positive
  /// definite.
  static double LogEvidence(const EulerLagrangeGPHyperparameters& hyperparameters,
                            const ConstMatrixRef& X, const ConstMatrixRef& Y,
                            Vector* gradient = nullptr);

 private:
  void SetEffectStates();
  // The posterior of a Condition or RestoreDtc: its factors (factor_b empty: exact), alpha and
  // evidence, at `states` (the training states, or the inducing states), conditioned on (X, Y).
  void Adopt(Matrix factor, Matrix factor_b, Vector alpha, double log_evidence,
             const ConstMatrixRef& states, const ConstMatrixRef& X, const ConstMatrixRef& Y);
  // K_ZZ + jitter = L L^T, as every posterior through inducing states forms it; false when it
  // cannot be factorised. Throws std::invalid_argument on bad inducing states.
  bool FactorizeInducing(const ConstMatrixRef& inducing, internal::Cholesky* llt) const;

  EulerLagrangeGPHyperparameters hyper_;
  EulerLagrangeKernel kernel_;
  std::shared_ptr<const FeatureMap> effects_;
  int input_dim_;               // 3N, or 3N + 1 with the time
  Matrix effect_z_;             // effects: phi(z_t)^T diag(lambda), p x D
  Matrix states_;               // training states (exact) or inducing states (DTC)
  Matrix states_t_;             // states_ transposed: one contiguous column per state
  Matrix inputs_, targets_;     // the data of the last Condition
  Vector alpha_;                // exact: C^-1 y; DTC: L^-T B^-1 V S^-1/2 y
  // Lower Cholesky factors as plain matrices (an Eigen::LLT that was never computed holds an
  // indeterminate status, which a copy or move of the model would read).
  Matrix factor_;    // exact: of C; DTC: of K_ZZ
  Matrix factor_b_;  // DTC: of B = I + V V^T, V = L^-1 K_ZX S^-1/2
  bool dtc_ = false;
  double log_evidence_ = 0.0;   // of the conditioned data (exact or DTC)
};

/// Nystrom features of one joint's torque under an EulerLagrangeGP's prior (kernel, friction
/// and effects at its hyper-parameters): phi(x) = L^-1 k_j(x), where k_j(x) holds the
/// covariance of joint j's torque at x with every joint's torque at the inducing states Z
/// (p N entries) and L L^T is their covariance plus a relative jitter. phi(x)^T phi(x') is the
/// Nystrom approximation of the covariance of joint j's torques at x and x'. This is how the
/// diagnosis scores candidate effects against a lagk model, one joint at a time.
class EulerLagrangeJointFeatureMap : public FeatureMap {
 public:
  /// Most effect features it evaluates without allocating (a stack buffer).
  static constexpr int kMaxJointMapEffectFeatures = 256;

  /// gp: its hyper-parameters and effects are copied (it need not be conditioned). Z: p x
  /// gp.input_dim() inducing states (with the time when the gp's effects take it); joint 0-based; at most kMaxJointMapEffectFeatures effect features. Throws std::invalid_argument on bad sizes or values,
  /// std::runtime_error when the inducing covariance cannot be factorised.
  EulerLagrangeJointFeatureMap(const EulerLagrangeGP& gp, const ConstMatrixRef& Z, int joint);

  int input_dim() const override { return input_dim_; }
  int dim() const override { return static_cast<int>(factor_.rows()); }
  /// Allocation-free (at most kMaxEulerLagrangeJoints joints).
  void Evaluate(const ConstVectorRef& x, VectorRef phi) const override;
  /// One block, "euler_lagrange_nystrom", unit prior variances.
  std::vector<FeatureBlock> blocks() const override;

 private:
  int n_;
  int joint_;
  EulerLagrangeGPHyperparameters hyper_;
  EulerLagrangeKernel kernel_;
  std::shared_ptr<const FeatureMap> effects_;
  int input_dim_;     // the gp's
  Matrix states_t_;   // input_dim x p
  Matrix effect_z_;   // p x D: phi_e(z)^T diag(lambda)
  Matrix factor_;     // lower, (p N) x (p N)
};

}  // namespace structgp

#endif  // STRUCTGP_MODEL_EULER_LAGRANGE_GP_H_
