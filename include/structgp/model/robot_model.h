#ifndef STRUCTGP_MODEL_ROBOT_MODEL_H_
#define STRUCTGP_MODEL_ROBOT_MODEL_H_

/// @file
/// An inverse-dynamics model of an N-joint robot built from a ModelSpec: a base kernel (pol,
/// rbf, rbfs or motor), the paper's friction bases when asked ("+fri") and any effects, each
/// added with a broad prior. Inputs are states x = (q, qd, qdd) (3N values, joints in order),
/// followed by the time t in seconds when an effect uses it; outputs are the N joint torques.
///
/// Feature-map bases (pol, motor) become one SumFeatureMap; the model then runs in weight
/// space or function space (GaussianProcess chooses), and every prediction can be split into
/// physical components — pol's inertial M(q)qdd, Coriolis/centrifugal C(q,qd)qd and gravity
/// G(q) blocks, friction, and each effect — each with its own posterior variance.
/// rbf and rbfs have no finite map: they run in function space, with friction and effects
/// added as a feature-map kernel, and give no component split. pol runs the same way, with
/// k_pol evaluated by its formula (PolFormulaKernel, O(N) per pair), when its explicit map
/// would be wider than RobotModelOptions::max_explicit_features (from N = 4 joints by
/// default: D = 8,830 at N = 4, 422,603 at N = 6); effects that use the time then need the
/// explicit map.
///
/// rbd is the rigid-body regressor of a known chain (RobotModelOptions::rigid_body, from a URDF):
/// torque is linear in the links' inertial parameters, shared by every joint, with a prior
/// centred on the chain's values; friction and effects add per-joint columns. It runs as a
/// RegressorGP (GaussianProcess's kRegressor form) with one noise level per joint
/// (feature/rigid_body_regressor_map.h has the prior). lag is the Lagrangian regressor of a serial
/// chain whose kinematics are not known (feature/lagrangian_regressor_map.h): one M(q) and V(q)
/// for all joints, in the same regressor form, up to max_explicit_features parameters (N <= 5).
///
/// lagk is one Gaussian process of all joint torques on the Euler-Lagrange kernel
/// (model/euler_lagrange_gp.h: a prior on each link's kinetic and potential energy, no
/// kinematics, any N), with the semi-parametric friction of "+fri" in the kernel; it runs in
/// GaussianProcess's kEulerLagrange form, exactly or through RobotModelOptions::batch.
/// inducing_states covering the training states. Effects enter as features with the broad
/// prior of the other models, shared by the joints (each joint's scale its RMS torque, fitted);
/// with a time effect (drift) the inputs end with the time, which only the effects read; it has no component split, no coefficients and no online update
/// (GaussianProcess::Add refuses).
///
/// rbd+pol (rbd+rbf, rbd+rbfs, rbd+motor) is the base with the known chain's inverse dynamics as
/// its prior mean: the base (and friction, effects) learns tau - tau_URDF(x), and predictions
/// add tau_URDF(x) back (feature/rigid_body_torque_feature_map.h evaluates it), in whichever form
/// the base runs; the mean is fixed (its inertial parameters are not identified: that is rbd),
/// and the components gain "urdf inertial", "urdf coriolis", "urdf gravity" (zero variance).
/// Fit takes the torques themselves; the hyper-parameter search of FitModel works on the
/// residual targets Y - PriorMeanRows(X).

#include <memory>
#include <string>
#include <vector>

#include "structgp/core/status.h"
#include "structgp/core/types.h"
#include "structgp/feature/feature_map.h"
#include "structgp/feature/feature_hyperparameters.h"
#include "structgp/feature/lagrangian_regressor_map.h"
#include "structgp/feature/rigid_body_torque_feature_map.h"
#include "structgp/feature/rigid_body_regressor_map.h"
#include "structgp/feature/semi_parametric_regressor_map.h"
#include "structgp/kernel/kernel.h"
#include "structgp/kernel/kernel_hyperparameters.h"
#include "structgp/model/gaussian_process.h"
#include "structgp/model/model_spec.h"

namespace structgp {

struct RobotModelOptions {
  /// Weight space when D <= m, else function space; or forced.
  Form form = Form::kAuto;
  /// Velocity scale sigma_f of the Coulomb basis tanh(qd / sigma_f) of "+fri", rad/s.
  double friction_width = 0.01;
  /// Prior standard deviation of friction and effect coefficients, relative to each joint's
  /// torque scale: a broad prior (the semi-parametric sum of the paper, eqs. 43-44).
  double broad_prior_std = 10.0;
  /// Large data sets: threads of the weight-space accumulation and the row limit of the
  /// function-space form (see BatchFitOptions; gp().subsampled() tells when it applied).
  BatchFitOptions batch;
  /// pol: the explicit feature map is used while its dimension D is at most this (or when
  /// form is Form::kWeightSpace); beyond, the model runs in function space on k_pol's
  /// formula. D = 12, 133, 1151, 8830 for N = 1..4.
  int max_explicit_features = 2048;
  /// rbd and rbd+<base>: the robot's chain (RigidBodyChain::FromUrdfFile), required for them,
  /// unused otherwise.
  std::shared_ptr<const RigidBodyChain> rigid_body;
};

/// One physical part of a prediction, for one output.
struct Component {
  std::string name;       ///< "inertial", "coriolis", "gravity", "friction", "coulomb@2", ...
  Vector mean;            ///< per joint (N)
  Vector latent_variance; ///< per joint (N)
};

/// One physical part of the predictions for many rows (RobotModel::PredictComponentRows).
struct ComponentRows {
  std::string name;  ///< as in Component
  Matrix mean;       ///< m x N
  Matrix latent_std; ///< m x N: the posterior standard deviation of this part alone
};

/// A fitted friction or effect coefficient (RobotModel::Coefficients).
struct FeatureCoefficient {
  std::string name;  ///< the feature, as in ParametricFeatureNames() ("coulomb@2", "offset")
  /// The joint torque (1-based) the coefficient belongs to; 0 for a parameter shared by every
  /// joint (rbd/lag: a feature without "@j", e.g. the one "offset" effect).
  int joint = 0;
  double value = 0.0;  ///< posterior mean, in torque units (N m) per unit of the basis
  double std = 0.0;    ///< posterior standard deviation
};

/// Everything a fitted RobotModel's later results depend on (RobotModel::State), so that
/// RobotModel::FromState restores it exactly: the same predictions, components, evidence and
/// online updates, bit for bit (the function-space form refits its stored points in one batch:
/// after online additions that agrees to rounding only).
struct RobotModelState {
  ModelSpec spec;
  int num_joints = 0;
  RobotModelOptions options;
  /// RobotModel::hyperparameters() (a kernel's parameters in shape).
  Hyperparameters hyperparameters;
  /// The form the model was fitted in: kWeightSpace or kFunctionSpace (never kAuto).
  Form form = Form::kWeightSpace;
  /// Weight space: the posterior (restored as it is, without a fit).
  WeightSpaceGPState weight_space;
  /// Weight space with per-joint hyper-parameters (hyperparameters.per_output): each joint's
  /// single-output posterior, in joint order (weight_space is then unused); the function space
  /// stores its points once, in inputs and targets, for every joint.
  std::vector<WeightSpaceGPState> joint_weight_space;
  /// Regressor (rbd): its prior, noise and statistics (restored by a deterministic refit).
  RegressorGPState regressor;
  /// Function space and kEulerLagrange: the stored points (m x input_dim, m x N), whose
  /// factorisation FromState recomputes (O(m^3), exactly as the fit that stored them did).
  Matrix inputs;
  Matrix targets;
  /// kEulerLagrange through inducing states: those states (p x 3N); empty when exact.
  Matrix inducing;
  /// kEulerLagrange through inducing states: the posterior's factors, when known (a saved
  /// model's posterior file), so that FromState does not compute them from every row again
  /// (EulerLagrangeGP::RestoreDtc); null: computed. FromState moves them into the model
  /// (2 (p N)^2 doubles are not copied), leaving the pointee empty. State() leaves it null.
  std::shared_ptr<EulerLagrangeGP::DtcFactors> euler_lagrange_factors;
  /// RobotModel::latent_variance_scale(); empty for all 1.
  Vector latent_variance_scale;
};

class RobotModel {
 public:
  /// Throws std::invalid_argument when the spec cannot be built for num_joints (an effect on
  /// a joint > N, a time effect with an rbf base, pol with N > kMaxPolJoints, ...).
  RobotModel(const ModelSpec& spec, int num_joints, const RobotModelOptions& options = {});

  const ModelSpec& spec() const { return spec_; }
  const RobotModelOptions& options() const { return options_; }
  int num_joints() const { return num_joints_; }
  /// 3N, or 3N + 1 when an effect uses the time.
  int input_dim() const { return 3 * num_joints_ + (uses_time_ ? 1 : 0); }
  bool uses_time() const { return uses_time_; }

  /// The feature map (null for rbf/rbfs bases).
  const std::shared_ptr<const FeatureMap>& feature_map() const { return map_; }
  /// The regressor of rbd and lag models (null otherwise): the base's columns, then friction
  /// and effects.
  const std::shared_ptr<const SemiParametricRegressorMap>& regressor_map() const {
    return regressor_;
  }
  /// The hyper-parameters of the last successful Fit (empty before): for a feature map its
  /// shape parameters and block scales, for a kernel its parameters in shape (see
  /// core/hyperparameters.h), and the noise and output scales of both.
  const Hyperparameters& hyperparameters() const { return hyper_; }
  /// The kernel of rbf/rbfs models, and of pol models beyond max_explicit_features (null
  /// for models with a feature map), with the parameters of the last successful Fit
  /// (hyperparameters().shape), or its defaults before. Immutable (kernel/kernel.h).
  const Kernel* kernel() const { return kernel_.get(); }

  /// Default hyper-parameters for torques Y (m x N): output scales from the torque spread,
  /// noise 10% of it, broad priors on friction and effects, the base's default shape (for a
  /// kernel: its default parameters, with broad priors on friction and effects).
  Hyperparameters DefaultHyperparameters(const ConstMatrixRef& Y) const;

  /// Fits X (m x input_dim) and Y (m x N) with the given hyper-parameters (shared by the
  /// joints, or one set per joint in hyper.per_output: pol, motor, rbf and rbfs only): for a feature map
  /// its shape and block scales, for a kernel its parameters in hyper.shape (the layout of
  /// kernel()->parameters(), e.g. a FitKernelHyperparameters result; log_block_scale empty),
  /// and the noise and output scales. On success the model owns hyper (hyperparameters())
  /// and kernel() has its parameters. Throws std::invalid_argument on bad sizes or values; a
  /// numerical failure is a status (the model is then unchanged). std::invalid_argument too
  /// for per-joint sets on rbd, lag or lagk, whose joints share their parameters.
  Status Fit(const ConstMatrixRef& X, const ConstMatrixRef& Y, const Hyperparameters& hyper);
  /// Fits with DefaultHyperparameters(Y).
  Status Fit(const ConstMatrixRef& X, const ConstMatrixRef& Y);

  bool fitted() const { return gp_ != nullptr; }
  /// True when the fitted model's joints each have their own hyper-parameters
  /// (hyperparameters().per_output, FitOptions::per_joint).
  bool per_joint() const { return hyper_.is_per_output(); }

  /// The model's complete state. Throws std::logic_error when not fitted. O(D^2) or
  /// O(m input_dim) copy; allocates.
  RobotModelState State() const;
  /// The model in exactly the given state. Weight space: no fit, O(D^2) (the posterior is
  /// taken from the state; gp().data_rows() is then its num_samples()); function space: the
  /// stored points are factorised again, all of them and in function space, O(m^3).
  /// Throws std::invalid_argument naming what is wrong when the state is inconsistent (sizes
  /// that do not match the spec, a posterior that breaks WeightSpaceGPState's invariants,
  /// stored points that cannot be factorised).
  static RobotModel FromState(const RobotModelState& state);
  const GaussianProcess& gp() const;
  GaussianProcess& mutable_gp();

  /// Scratch of the const predictions, one per thread: the GP's, and the prior mean's.
  struct Workspace {
    GaussianProcess::Workspace gp;
    Vector prior_mean;  ///< N (rbd+<base>)
  };
  /// A workspace for the fitted model (allocates). Throws std::logic_error when not fitted.
  Workspace MakeWorkspace() const;

  /// lagk with effects: their features of the inputs (the 3N states, and the time when
  /// uses_time()) and each feature's prior variance (null and empty otherwise).
  const std::shared_ptr<const FeatureMap>& effect_map() const { return effect_map_; }
  const Vector& effect_prior_variance() const { return effect_prior_variance_; }

  /// rbd+<base>: the fixed prior mean, the known chain's torques (null otherwise).
  const std::shared_ptr<const RigidBodyTorqueFeatureMap>& prior_mean() const {
    return prior_mean_;
  }
  /// The prior mean at every row of X (m x N; zeros without one). Allocates.
  Matrix PriorMeanRows(const ConstMatrixRef& X) const;

  /// Predictive mean (N) and variances at x; see GaussianProcess. With a workspace:
  /// allocation-free and safe for concurrent calls on one const model, one workspace each;
  /// without: a workspace is made for the call (allocates).
  Status Predict(const ConstVectorRef& x, VectorRef mean, Workspace& workspace) const;
  Status PredictWithVariance(const ConstVectorRef& x, VectorRef mean, VectorRef latent_variance,
                             VectorRef noisy_variance, Workspace& workspace) const;
  Status Predict(const ConstVectorRef& x, VectorRef mean) const;
  Status PredictWithVariance(const ConstVectorRef& x, VectorRef mean, VectorRef latent_variance,
                             VectorRef noisy_variance) const;
  /// The factor kappa_j on joint j's latent variance in every prediction with variance: the
  /// latent variance returned is kappa_j v_j and the noisy one kappa_j v_j + sigma_j^2, where
  /// v_j is the posterior's (the mean is unchanged). All 1 (the posterior as it is) unless set;
  /// FitModel sets it from the held-out check when FitOptions::calibrate_bands (so that the
  /// 2 sigma band covers FitCheckOptions::target_coverage of held-out blocks), and Fit resets
  /// it to 1 (new hyper-parameters, a new calibration). Size N.
  const Vector& latent_variance_scale() const { return latent_variance_scale_; }
  /// True when latent_variance_scale() is not all 1.
  bool bands_calibrated() const { return !latent_variance_scale_.isOnes(0.0); }
  /// Sets latent_variance_scale(). Throws std::invalid_argument unless scale has N entries,
  /// each finite and > 0.
  void SetLatentVarianceScale(const Vector& scale);
  /// Means (m x N) and, if not null, latent standard deviations (m x N) for every row of X.
  /// On num_threads threads (contiguous ranges of rows, a workspace each; allocates): the
  /// same result bit for bit for any number, and the same first failing row in the error.
  /// Throws std::invalid_argument on bad sizes, NaN/Inf or num_threads < 1,
  /// std::runtime_error naming the row when a prediction fails numerically. More than one
  /// thread needs feature maps whose Evaluate may be called concurrently (the library's are).
  void PredictRows(const ConstMatrixRef& X, Matrix* mean, Matrix* latent_std = nullptr,
                   int num_threads = 1) const;

  /// True when the fitted model splits its predictions into components: a weight-space
  /// feature-map model (pol, motor), or rbd/lag.
  bool has_components() const;
  /// Names of the physical components, in order (weight-space feature-map models only).
  std::vector<std::string> ComponentNames() const;
  /// Splits the prediction at x into components (their means add up to the full mean).
  /// Weight-space feature-map models only: otherwise returns kInvalidInput.
  Status PredictComponents(const ConstVectorRef& x, std::vector<Component>* components) const;

  /// PredictComponents for every row of X (m x input_dim()), one entry per component, in
  /// ComponentNames() order. Throws std::invalid_argument on bad sizes, NaN/Inf or a model
  /// without components (has_components() false), std::runtime_error naming the row when a
  /// prediction fails numerically (as PredictRows). Allocates.
  std::vector<ComponentRows> PredictComponentRows(const ConstMatrixRef& X) const;

  /// Fitted coefficient of a named feature (e.g. "coulomb@2", "viscous@1") for joint `joint`
  /// (1-based), with its posterior standard deviation. Weight space only; throws when the
  /// feature does not exist.
  std::pair<double, double> Coefficient(const std::string& feature, int joint) const;
  /// Names of all features that have a physical meaning (friction and effect bases).
  std::vector<std::string> ParametricFeatureNames() const;
  /// Every friction and effect coefficient with its posterior std, in ParametricFeatureNames()
  /// order: a feature of joint j ("coulomb@2", "cogging.sin@3") on joint j's torque; a feature
  /// of every joint ("offset") once per joint torque in weight space, once (joint 0) as the
  /// shared parameter of rbd/lag. Empty for a model without such features (rbf, rbfs, pol
  /// beyond its explicit map). Throws std::invalid_argument when the model is not fitted.
  std::vector<FeatureCoefficient> Coefficients() const;

 private:
  struct Part {
    std::string name;
    int begin;
    int size;
  };
  // Coefficient of parameter `index` on joint `joint`'s torque (1-based), with its std.
  std::pair<double, double> CoefficientAt(int index, int joint) const;
  // Joint `joint`'s (0-based) weight-space posterior and its column in it: the shared
  // posterior's column joint, or with per-joint hyper-parameters the joint's own posterior's
  // only column; null when the model is not fitted in weight space.
  std::pair<const WeightSpaceGP*, int> JointPosterior(int joint) const;
  void BuildFeatureMap();
  void BuildKernel();
  void BuildRegressor();
  void RequireChain() const;
  // FromState without the latent variance scale.
  static RobotModel RestoreState(const RobotModelState& state);

  ModelSpec spec_;
  int num_joints_;
  RobotModelOptions options_;
  bool uses_time_ = false;
  std::shared_ptr<const FeatureMap> map_;
  std::shared_ptr<const SemiParametricRegressorMap> regressor_;
  std::shared_ptr<const RigidBodyTorqueFeatureMap> prior_mean_;
  std::shared_ptr<const FeatureMap> effect_map_;  // lagk
  Vector effect_prior_variance_;                  // lagk
  std::vector<Part> parts_;                                   // component ranges in phi
  std::vector<std::pair<std::string, int>> parametric_names_;  // feature name -> index
  std::unique_ptr<Kernel> kernel_;  // at hyper_.shape once fitted
  Vector default_kernel_parameters_;
  Hyperparameters hyper_;
  Vector latent_variance_scale_;  // N, all 1 unless set
  std::unique_ptr<GaussianProcess> gp_;
};

}  // namespace structgp

#endif  // STRUCTGP_MODEL_ROBOT_MODEL_H_
