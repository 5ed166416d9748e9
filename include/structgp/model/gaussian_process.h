#ifndef STRUCTGP_MODEL_GAUSSIAN_PROCESS_H_
#define STRUCTGP_MODEL_GAUSSIAN_PROCESS_H_

/// @file
/// A Gaussian process on robot states x, in whichever form is cheaper: the weight-space form
/// (WeightSpaceGP on phi(x), O(D^3) batch, O(D^2) per sample) when the kernel has a finite
/// feature map with D <= m, the function-space form (KernelGP, O(m^3) batch, O(m^2) per
/// sample) otherwise or when the kernel has no finite map. Both forms give the same
/// posterior; the choice can be forced. A third form serves models whose outputs share their
/// parameters through a regressor (RegressorMap: the rigid-body regressor of `rbd`): RegressorGP.
/// A fourth is one multi-output GP of all joint torques on the Euler-Lagrange kernel (`lagk`:
/// EulerLagrangeGP), exact or through inducing states.
///
/// With per-output hyper-parameters (Hyperparameters::per_output) the feature-map and kernel
/// forms hold one single-output Gaussian process per output, each with its own set: the
/// weight space accumulates Phi^T Phi once and factorises it once per output.

#include <memory>
#include <vector>

#include "structgp/core/status.h"
#include "structgp/core/types.h"
#include "structgp/feature/feature_map.h"
#include "structgp/feature/feature_hyperparameters.h"
#include "structgp/kernel/kernel.h"
#include "structgp/kernel/kernel_hyperparameters.h"
#include "structgp/feature/regressor_map.h"
#include "structgp/model/euler_lagrange_gp.h"
#include "structgp/model/kernel_gp.h"
#include "structgp/model/regressor_gp.h"
#include "structgp/model/sufficient_statistics.h"
#include "structgp/model/weight_space_gp.h"

namespace structgp {

enum class Form {
  kAuto,           ///< weight space when D <= m (number of training samples), else function space
  kWeightSpace,    ///< always the feature form (requires a feature map)
  kFunctionSpace,  ///< always the kernel form
  kRegressor,      ///< a RegressorMap's shared parameters (RegressorGP); the only form of one
  kEulerLagrange,  ///< one GP of all torques on the Euler-Lagrange kernel (EulerLagrangeGP)
};

/// "auto", "weight_space", "function_space", "regressor", "euler_lagrange".
const char* ToString(Form form);

/// Default largest number of rows the function-space form is fitted on. Its batch fit needs
/// O(m^2) memory and O(m^3) time: at m = 5000 that is 200 MB for K and 100 MB for the packed
/// factor and ~10 s on one core; beyond it a subset is used (see BatchFitOptions).
inline constexpr int kDefaultMaxKernelRows = 5000;
/// The most threads the structgp program and the Python module accept for BatchFitOptions::
/// num_threads, LoadOptions::num_threads and RobotModel::PredictRows (each starts that many
/// system threads; the library itself asks only for at least one).
inline constexpr int kMaxThreads = 256;

/// How a batch fit handles large data sets.
struct BatchFitOptions {
  /// Weight space: worker threads that accumulate Phi^T Phi (AccumulateStatistics); the
  /// Euler-Lagrange form's DTC: workers over the blocks of training states
  /// (EulerLagrangeGP::Condition, the same result bit for bit for any number). Weight space:
  /// the result equals the single-thread one up to the order of floating-point additions.
  /// More than one needs a feature map whose Evaluate is thread-safe (see
  /// AccumulateStatistics).
  int num_threads = 1;
  /// Weight space: samples whose features are held at once, per worker.
  Eigen::Index chunk_rows = kDefaultChunkRows;
  /// Function space: with more rows than this, the model is fitted on this many rows, evenly
  /// spaced through the data (row floor(k m / M) for k = 0..M-1), and subsampled() reports
  /// it. 0 means no limit.
  int max_kernel_rows = kDefaultMaxKernelRows;
  /// Euler-Lagrange form: with more rows than this, the posterior conditions on every row
  /// through this many inducing states chosen to cover the training states (the deterministic
  /// training conditional, FarthestStateRows in core/row_subset.h): O(m N (p N)^2) time and
  /// O((p N)^2) memory, plus (p N) x (128 N) per worker (num_threads). Up to it the posterior
  /// is exact, O((m N)^3). 0: always exact.
  int inducing_states = 800;
};

class GaussianProcess {
 public:
  /// A model whose kernel is the feature map with the prior given by hyper.
  GaussianProcess(std::shared_ptr<const FeatureMap> map, const Hyperparameters& hyper,
                  int num_outputs, Form form = Form::kAuto,
                  const BatchFitOptions& batch = BatchFitOptions());
  /// A model with a kernel that has no finite map (rbf, rbfs): always the function space.
  /// hyper holds the kernel's parameters in shape (kernel/kernel_hyperparameters.h): the model
  /// uses kernel.WithParameters(hyper.shape), so only the kernel's type and structure matter.
  /// Throws std::invalid_argument when hyper does not match the kernel and num_outputs.
  GaussianProcess(const Kernel& kernel, const Hyperparameters& hyper, int num_outputs,
                  const BatchFitOptions& batch = BatchFitOptions());

  /// A model of a regressor's shared parameters (RegressorGP): hyper has no shape, one log
  /// block scale per block of the map (RegressorPriorVariance) and the noise of output j is
  /// exp(log_noise_std + log_output_scale_j) (see hyper/marginal_likelihood.h,
  /// RegressorEvidenceObjective). form() is kRegressor. Throws std::invalid_argument when
  /// hyper does not match the map.
  GaussianProcess(std::shared_ptr<const RegressorMap> map, const Hyperparameters& hyper,
                  const BatchFitOptions& batch = BatchFitOptions());
  /// A regressor model in the given posterior (RegressorGP::FromState), without a fit.
  static GaussianProcess FromRegressor(std::shared_ptr<const RegressorMap> map,
                                       const Hyperparameters& hyper, const BatchFitOptions& batch,
                                       RegressorGP posterior);

  /// One GP of all num_joints torques on the Euler-Lagrange kernel, with semi-parametric
  /// friction when `friction` and the effects' features with their prior variances when
  /// `effects` is not null (model/euler_lagrange_gp.h). hyper in the layout of
  /// ToHyperparameters (euler_lagrange_gp.h). form() is kEulerLagrange; Add is not available
  /// (kInvalidInput): the posterior is refitted in batch. Throws std::invalid_argument when
  /// hyper does not fit.
  static GaussianProcess EulerLagrange(int num_joints, bool friction, const Hyperparameters& hyper,
                                       const BatchFitOptions& batch = BatchFitOptions(),
                                       std::shared_ptr<const FeatureMap> effects = nullptr,
                                       const Vector& effect_prior_variance = Vector());
  /// The same conditioned on inputs and targets through the given inducing states (empty:
  /// exactly), without choosing them: how a stored model is restored. With dtc_factors (and
  /// inducing states) the posterior's factors are moved in (EulerLagrangeGP::RestoreDtc; the
  /// pointee is left empty) instead of computed from every row. Throws std::invalid_argument
  /// when the sizes do not fit, the factors are refused or the posterior cannot be factorised.
  static GaussianProcess EulerLagrangeFromData(
      int num_joints, bool friction, const Hyperparameters& hyper, const BatchFitOptions& batch,
      const ConstMatrixRef& inputs, const ConstMatrixRef& targets, const ConstMatrixRef& inducing,
      std::shared_ptr<const FeatureMap> effects = nullptr,
      const Vector& effect_prior_variance = Vector(),
      EulerLagrangeGP::DtcFactors* dtc_factors = nullptr);

  /// A weight-space model with per-output hyper-parameters (hyper.per_output, one entry per
  /// posterior) in the given single-output posteriors, without a fit: how a stored model is
  /// restored. Throws std::invalid_argument when the sizes do not fit.
  static GaussianProcess FromWeightSpaceOutputs(std::shared_ptr<const FeatureMap> map,
                                                const Hyperparameters& hyper, Form form,
                                                const BatchFitOptions& batch,
                                                std::vector<WeightSpaceGP> posteriors,
                                                Eigen::Index rows);

  /// A weight-space model in the given posterior (WeightSpaceGP::FromState, say), without a
  /// fit: form() is kWeightSpace, data_rows() = fit_rows() = rows. The posterior must have
  /// map->dim() features and num_outputs outputs (std::invalid_argument otherwise); it is
  /// taken as it is (its prior is not compared with PriorVariance(*map, hyper)).
  static GaussianProcess FromWeightSpace(std::shared_ptr<const FeatureMap> map,
                                         const Hyperparameters& hyper, int num_outputs,
                                         Form form, const BatchFitOptions& batch,
                                         WeightSpaceGP posterior, Eigen::Index rows);

  /// Fits X (m x input_dim) and Y (m x P); with Form::kAuto picks the form from D and m
  /// (the form's choice uses all m rows; the function space then keeps at most
  /// BatchFitOptions::max_kernel_rows of them). Throws std::invalid_argument on bad sizes,
  /// bad options or NaN/Inf (naming row and column).
  Status Fit(const ConstMatrixRef& X, const ConstMatrixRef& Y);

  const BatchFitOptions& batch_options() const { return batch_; }
  /// The hyper-parameters the model was built with (shape: the feature map's shape
  /// parameters, or the kernel's parameters).
  const Hyperparameters& hyperparameters() const { return hyper_; }
  /// Rows given to the last successful Fit, and rows the model was fitted on (fewer when the
  /// function space took a subset).
  Eigen::Index data_rows() const { return data_rows_; }
  Eigen::Index fit_rows() const { return fit_rows_; }
  bool subsampled() const { return fit_rows_ < data_rows_; }

  /// The form in use (never kAuto once fitted; before Fit, the requested form).
  Form form() const { return active_; }
  int input_dim() const;
  int num_outputs() const { return num_outputs_; }
  /// True with per-output hyper-parameters: output j is then output(j), a fitted
  /// single-output GaussianProcess, and weight_space() and function_space() are null.
  bool per_output() const { return !outputs_.empty(); }
  /// Output j's own Gaussian process (0-based; per_output() only, std::logic_error otherwise).
  const GaussianProcess& output(int j) const;

  /// Scratch of the const predictions, owned by the caller (one per thread).
  struct Workspace {
    Vector features;                         ///< phi(x), D (weight space)
    WeightSpaceGP::Workspace weight_space;   ///< weight space
    KernelGP::Workspace function_space;      ///< function space
    Matrix regressor;                         ///< Psi(x), N x P (regressor)
    RegressorGP::Workspace regressor_gp;      ///< regressor
    /// regressor: the map's scratch (KDL solvers for rbd). A copy of a workspace shares it:
    /// give each thread its own MakeWorkspace().
    std::shared_ptr<RegressorMap::Scratch> regressor_scratch;
    EulerLagrangeGP::Workspace euler_lagrange;  ///< Euler-Lagrange form
    /// Per-output hyper-parameters: each output's workspace, and one output's results.
    std::vector<Workspace> outputs;
    Vector output_mean, output_latent, output_noisy;  ///< 1 each
  };
  /// A workspace for the fitted form (allocates). After a refit or a Reserve of the function
  /// space, make a new one.
  Workspace MakeWorkspace() const;

  /// Predictive mean (P) and variances at x with the caller's workspace: allocation-free, and
  /// safe for concurrent calls on one const model with one workspace each (see KernelGP for
  /// the kernels that allow it). kInvalidInput on bad input or an unfitted model.
  Status Predict(const ConstVectorRef& x, VectorRef mean, Workspace& workspace) const;
  Status PredictWithVariance(const ConstVectorRef& x, VectorRef mean, VectorRef latent_variance,
                             VectorRef noisy_variance, Workspace& workspace) const;
  /// The same with a workspace made for the call: allocates (not for the real-time path).
  Status Predict(const ConstVectorRef& x, VectorRef mean) const;
  Status PredictWithVariance(const ConstVectorRef& x, VectorRef mean, VectorRef latent_variance,
                             VectorRef noisy_variance) const;
  /// Adds one sample online (O(D^2) or O(m^2)); the function space needs Reserve'd room. The
  /// regressor form adds the sample to its statistics and refits (O(N P^2 + P^3)). The
  /// Euler-Lagrange form has no online update: kInvalidInput. Per-output hyper-parameters:
  /// every output takes the sample in turn (O(P D^2)); a sample of the wrong size or with a
  /// NaN changes none, a numerical failure of output j leaves outputs 0..j-1 updated.
  Status Add(const ConstVectorRef& x, const ConstVectorRef& y);

  double LogMarginalLikelihood() const;

  /// The underlying models; exactly one is non-null after Fit, none with per_output().
  const WeightSpaceGP* weight_space() const { return weight_space_.get(); }
  const KernelGP* function_space() const { return function_space_.get(); }
  KernelGP* mutable_function_space() { return function_space_.get(); }
  const RegressorGP* regressor() const { return regressor_gp_.get(); }
  const EulerLagrangeGP* euler_lagrange() const { return euler_lagrange_.get(); }
  /// The regressor of the kRegressor form (null otherwise).
  const std::shared_ptr<const RegressorMap>& regressor_map() const { return regressor_map_; }

 private:
  GaussianProcess(EulerLagrangeGPHyperparameters euler, std::shared_ptr<const FeatureMap> effects,
                  const Hyperparameters& hyper, const BatchFitOptions& batch);

  std::shared_ptr<const FeatureMap> map_;  // null for a kernel-only model
  Hyperparameters hyper_;
  std::unique_ptr<Kernel> kernel_;  // the kernel of the function-space form
  int num_outputs_;
  Form requested_;
  Form active_;
  std::unique_ptr<WeightSpaceGP> weight_space_;
  std::unique_ptr<KernelGP> function_space_;
  std::shared_ptr<const RegressorMap> regressor_map_;
  std::unique_ptr<RegressorGP> regressor_gp_;
  // Euler-Lagrange form: its hyper-parameters (from hyper_) and posterior.
  std::unique_ptr<EulerLagrangeGPHyperparameters> euler_hyper_;
  std::unique_ptr<EulerLagrangeGP> euler_lagrange_;
  std::shared_ptr<const FeatureMap> euler_effects_;
  bool regressor_scratch_ = false;  // the regressor map needs scratch
  BatchFitOptions batch_;
  Eigen::Index data_rows_ = 0;
  Eigen::Index fit_rows_ = 0;
  Vector phi_;  // feature scratch of Add (D)
  // Per-output hyper-parameters: one single-output model per output (empty otherwise).
  std::vector<GaussianProcess> outputs_;
  Vector y1_;  // one output's target in Add (1)
  bool RegressorInputOk(const ConstVectorRef& x, const Workspace& workspace) const;
  // Per-output hyper-parameters: the fit of every output, and the check of a prediction's
  // sizes and workspace.
  Status FitOutputs(const ConstMatrixRef& X, const ConstMatrixRef& Y);
  // In weight space also evaluates phi(x) into workspace.features, once for every output.
  bool OutputsReady(const ConstVectorRef& x, Eigen::Index mean_size, Workspace& workspace) const;
};

}  // namespace structgp

#endif  // STRUCTGP_MODEL_GAUSSIAN_PROCESS_H_
