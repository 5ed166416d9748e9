#include "structgp/model/robot_model.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "structgp/core/validate.h"
#include "structgp/feature/effect_feature_map.h"
#include "structgp/feature/effects.h"
#include "structgp/feature/friction_feature_map.h"
#include "structgp/feature/motor_feature_map.h"
#include "structgp/feature/pol_feature_map.h"
#include "structgp/feature/rigid_body_torque_feature_map.h"
#include "structgp/feature/sum_feature_map.h"
#include "structgp/internal/workers.h"
#include "structgp/kernel/feature_kernel.h"
#include "structgp/kernel/leading_inputs_kernel.h"
#include "structgp/kernel/pol_kernel.h"
#include "structgp/kernel/rbf_kernel.h"
#include "structgp/kernel/sum_kernel.h"

namespace structgp {
namespace {

// Friction ("+fri") and the effects of spec as one feature map (null when there are none).
std::shared_ptr<const FeatureMap> ExtrasMap(const ModelSpec& spec, int num_joints,
                                            double friction_width, bool with_time,
                                            std::vector<std::string>* part_names);

}  // namespace

RobotModel::RobotModel(const ModelSpec& spec, int num_joints, const RobotModelOptions& options)
    : spec_(spec), num_joints_(num_joints), options_(options) {
  if (num_joints_ < 1) {
    throw std::invalid_argument("RobotModel: num_joints must be >= 1, got " +
                                std::to_string(num_joints_));
  }
  latent_variance_scale_ = Vector::Ones(num_joints_);
  RequireInRange("RobotModelOptions.friction_width", options_.friction_width, 0.0, 1e9);
  RequireInRange("RobotModelOptions.broad_prior_std", options_.broad_prior_std, 0.0, 1e12);
  for (const auto& e : spec_.effects) {
    if (MakeEffect(e.name, e.params)->uses_time()) uses_time_ = true;
    for (int j : e.joints) {
      if (j < 1 || j > num_joints_) {
        throw std::invalid_argument("effect '" + ToString(e) + "' names joint " +
                                    std::to_string(j) + ", but the robot has " +
                                    std::to_string(num_joints_) + " joints");
      }
    }
  }
  if (options_.max_explicit_features < 1) {
    throw std::invalid_argument("RobotModelOptions.max_explicit_features must be >= 1, got " +
                                std::to_string(options_.max_explicit_features));
  }
  if (spec_.base == BaseModel::kRbd || spec_.rigid_body_features) RequireChain();
  if (spec_.rigid_body_features) {
    prior_mean_ = std::make_shared<RigidBodyTorqueFeatureMap>(*options_.rigid_body);
  }
  if (spec_.base == BaseModel::kRbd || spec_.base == BaseModel::kLag) {
    BuildRegressor();
    return;
  }
  if (spec_.base == BaseModel::kLagk) {
    if (num_joints_ > kMaxEulerLagrangeJoints) {
      throw std::invalid_argument("model 'lagk' serves up to " +
                                  std::to_string(kMaxEulerLagrangeJoints) + " joints, got " +
                                  std::to_string(num_joints_));
    }
    if (!spec_.effects.empty()) {
      // The effects alone (friction is in the kernel), with the broad prior of the others.
      ModelSpec effects_only = spec_;
      effects_only.friction = false;
      std::vector<std::string> names;
      // With a time effect every effect takes the time as the last input (the kernel and its
      // friction read the 3N states only).
      effect_map_ =
          ExtrasMap(effects_only, num_joints_, options_.friction_width, uses_time_, &names);
      Hyperparameters h = structgp::DefaultHyperparameters(*effect_map_, num_joints_);
      h.log_block_scale.setConstant(std::log(options_.broad_prior_std));
      effect_prior_variance_ = PriorVariance(*effect_map_, h);
    }
    return;
  }
  const bool pol_by_formula = spec_.base == BaseModel::kPol &&
                              options_.form != Form::kWeightSpace &&
                              (num_joints_ > kMaxPolJoints ||
                               PolFeatureDimension(num_joints_) > options_.max_explicit_features);
  if (spec_.base == BaseModel::kMotor || (spec_.base == BaseModel::kPol && !pol_by_formula)) {
    BuildFeatureMap();
  } else {
    BuildKernel();
  }
}

namespace {

std::shared_ptr<const FeatureMap> ExtrasMap(const ModelSpec& spec, int num_joints,
                                            double friction_width, bool with_time,
                                            std::vector<std::string>* part_names) {
  std::vector<std::shared_ptr<const FeatureMap>> parts;
  if (spec.friction) {
    std::shared_ptr<const FeatureMap> fri =
        std::make_shared<FrictionFeatureMap>(num_joints, FrictionOptions{friction_width, true});
    parts.push_back(with_time ? std::make_shared<IgnoreTrailingInputs>(fri, 1) : fri);
    part_names->push_back("friction");
  }
  for (const auto& e : spec.effects) {
    std::shared_ptr<const Effect> effect = MakeEffect(e.name, e.params);
    parts.push_back(std::make_shared<EffectFeatureMap>(num_joints, effect, e.joints, with_time));
    part_names->push_back(ToString(e));
  }
  if (parts.empty()) return nullptr;
  return std::make_shared<SumFeatureMap>(parts);
}

}  // namespace

void RobotModel::BuildFeatureMap() {
  const int N = num_joints_;
  std::vector<std::shared_ptr<const FeatureMap>> parts;
  std::vector<std::string> names;
  std::shared_ptr<const FeatureMap> base;
  if (spec_.base == BaseModel::kPol) {
    if (N > kMaxPolJoints) {
      throw std::invalid_argument("model 'pol' has an explicit feature map for at most " +
                                  std::to_string(kMaxPolJoints) + " joints, got " +
                                  std::to_string(N));
    }
    base = std::make_shared<PolFeatureMap>(N);
  } else {
    base = std::make_shared<MotorFeatureMap>(N);
  }
  parts.push_back(uses_time_ ? std::make_shared<IgnoreTrailingInputs>(base, 1) : base);
  // Components: the base's own blocks (pol: inertial, coriolis, gravity).
  for (const auto& b : base->blocks()) parts_.push_back(Part{b.name, b.begin, b.size});
  std::vector<std::string> extra_names;
  auto extras = ExtrasMap(spec_, N, options_.friction_width, uses_time_, &extra_names);
  if (extras) {
    parts.push_back(extras);
    const auto& sum = static_cast<const SumFeatureMap&>(*extras);
    for (int i = 0; i < sum.num_parts(); ++i) {
      const int begin = base->dim() + sum.part_begin(i);
      parts_.push_back(Part{extra_names[static_cast<size_t>(i)], begin, sum.part(i).dim()});
      // Named coefficients of friction and effect bases.
      std::vector<std::string> fnames;
      const FeatureMap* inner = &sum.part(i);
      if (auto* ignore = dynamic_cast<const IgnoreTrailingInputs*>(inner)) inner = &ignore->inner();
      if (auto* fri = dynamic_cast<const FrictionFeatureMap*>(inner)) fnames = fri->feature_names();
      if (auto* eff = dynamic_cast<const EffectFeatureMap*>(inner)) fnames = eff->feature_names();
      for (size_t k = 0; k < fnames.size(); ++k) {
        parametric_names_.emplace_back(fnames[k], begin + static_cast<int>(k));
      }
    }
  }
  map_ = parts.size() == 1 ? parts.front() : std::make_shared<SumFeatureMap>(parts);
}

void RobotModel::RequireChain() const {
  const std::string name = "model '" + ToString(spec_) + "'";
  if (!options_.rigid_body) {
    throw std::invalid_argument(name +
                                " needs the robot's kinematic chain (RobotModelOptions.rigid_body; "
                                "at the command line --urdf FILE)");
  }
  if (options_.rigid_body->num_joints() != num_joints_) {
    throw std::invalid_argument(
        name + ": the chain " + options_.rigid_body->root() + " -> " + options_.rigid_body->tip() +
        " of " + options_.rigid_body->source() + " has " +
        std::to_string(options_.rigid_body->num_joints()) + " moving joints, the data have " +
        std::to_string(num_joints_));
  }
}

void RobotModel::BuildRegressor() {
  std::shared_ptr<const RegressorMap> base;
  if (spec_.base == BaseModel::kRbd) {
    base = std::make_shared<RigidBodyRegressorMap>(*options_.rigid_body);
  } else {
    if (num_joints_ > kMaxLagrangianJoints ||
        LagrangianDimension(num_joints_) > options_.max_explicit_features) {
      throw std::invalid_argument(
          "model 'lag' for " + std::to_string(num_joints_) + " joints would have " +
          (num_joints_ > kMaxLagrangianJoints
               ? std::string("too many parameters")
               : std::to_string(LagrangianDimension(num_joints_)) + " parameters") +
          ", more than RobotModelOptions.max_explicit_features = " +
          std::to_string(options_.max_explicit_features) +
          " (lag serves up to 5 joints, lagk any; with a URDF, rbd serves any)");
    }
    base = std::make_shared<LagrangianRegressorMap>(num_joints_);
  }
  SemiParametricOptions options;
  options.friction = spec_.friction;
  options.friction_width = options_.friction_width;
  options.with_time = uses_time_;
  for (const auto& e : spec_.effects) {
    options.effects.push_back(
        RegressorEffect{ToString(e), std::shared_ptr<const Effect>(MakeEffect(e.name, e.params)),
                        e.joints});
  }
  regressor_ = std::make_shared<SemiParametricRegressorMap>(base, options);
  const std::vector<std::string> names = regressor_->parameter_names();
  for (int k = base->dim(); k < regressor_->dim(); ++k) {
    parametric_names_.emplace_back(names[static_cast<size_t>(k)], k);
  }
}

void RobotModel::BuildKernel() {
  const int N = num_joints_;
  std::unique_ptr<Kernel> base;
  if (spec_.base == BaseModel::kPol) {
    base = std::make_unique<PolFormulaKernel>(N);
  } else if (spec_.base == BaseModel::kRbf) {
    base = std::make_unique<RbfKernel>(3 * N, /*ard=*/true);
  } else {
    base = std::make_unique<RbfsKernel>(N, /*ard=*/true);
  }
  // With a time-dependent effect the inputs end with t, which the base kernel does not see.
  if (uses_time_) base = std::make_unique<LeadingInputsKernel>(*base, 3 * N + 1);
  std::vector<std::string> extra_names;
  auto extras = ExtrasMap(spec_, N, options_.friction_width, uses_time_, &extra_names);
  if (!extras) {
    kernel_ = std::move(base);
  } else {
    Hyperparameters h = structgp::DefaultHyperparameters(*extras, N);
    h.log_block_scale.setConstant(std::log(options_.broad_prior_std));
    FeatureKernel extra_kernel(extras, h);
    kernel_ = std::make_unique<SumKernel>(std::vector<const Kernel*>{base.get(), &extra_kernel});
  }
  default_kernel_parameters_ = kernel_->parameters();
}

Hyperparameters RobotModel::DefaultHyperparameters(const ConstMatrixRef& Y) const {
  RequireSize("RobotModel::DefaultHyperparameters Y", Y.cols(), num_joints_, "columns (joints)");
  Hyperparameters h;
  if (regressor_) {
    // The base's prior at its own scale (rbd: feature/rigid_body_regressor_map.h); friction and
    // effects broad, relative to the largest torque spread. lag's unit prior is scaled to it.
    const auto blocks = regressor_->blocks();
    double spread = 0.0;
    for (int j = 0; j < num_joints_; ++j) {
      spread = std::max(spread, Y.rows() > 0 ? std::sqrt(Y.col(j).squaredNorm() / Y.rows()) : 0.0);
    }
    h.log_block_scale = Vector::Constant(static_cast<Eigen::Index>(blocks.size()),
                                         std::log(options_.broad_prior_std *
                                                  (spread > 1e-12 ? spread : 1.0)));
    const int base_blocks = static_cast<int>(regressor_->base().blocks().size());
    for (int b = 0; b < base_blocks; ++b) {
      h.log_block_scale[b] =
          spec_.base == BaseModel::kRbd ? 0.0 : std::log(spread > 1e-12 ? spread : 1.0);
    }
    h.log_output_scale = Vector::Zero(num_joints_);
  } else if (map_) {
    h = structgp::DefaultHyperparameters(*map_, num_joints_);
    // Broad priors on everything that is not the base's own structure.
    const auto blocks = map_->blocks();
    int base_end = 0;
    for (const auto& p : parts_) {
      if (p.name == "inertial" || p.name == "coriolis" || p.name == "gravity" ||
          p.name == "motor" || p.name == "all") {
        base_end = std::max(base_end, p.begin + p.size);
      }
    }
    for (size_t b = 0; b < blocks.size(); ++b) {
      if (blocks[b].begin >= base_end) {
        h.log_block_scale[static_cast<Eigen::Index>(b)] = std::log(options_.broad_prior_std);
      }
    }
  } else if (spec_.base == BaseModel::kLagk) {
    // Without the states: sigma 10, the torque spread shared by the 2N parts at unit part
    // variance, noise 10% of each joint's RMS torque, friction's prior std that RMS and its
    // velocity scale 1 rad/s. (FitModel starts from the states' own scales:
    // EulerLagrangeStart in hyper/euler_lagrange_fit.h.)
    EulerLagrangeGPHyperparameters e;
    const int n = num_joints_;
    Vector rms(n);
    for (int j = 0; j < n; ++j) {
      const double r = Y.rows() > 0 ? std::sqrt(Y.col(j).squaredNorm() / Y.rows()) : 1.0;
      rms[j] = r > 1e-12 ? r : 1.0;
    }
    e.sigma = 10.0;
    if (effect_map_) {
      e.effect_prior_variance = effect_prior_variance_;
      e.effect_scale = rms;
    }
    e.part_weights = Vector::Constant(2 * n, rms.squaredNorm() / n / (2.0 * n));
    e.noise_std = 0.1 * rms;
    if (spec_.friction) {
      e.friction_std = rms;
      e.friction_velocity_scale = Vector::Ones(n);
      e.coulomb_width = options_.friction_width;
    }
    return ToHyperparameters(e);
  } else {
    h.shape = default_kernel_parameters_;
    h.log_block_scale.resize(0);
    h.log_output_scale = Vector::Zero(num_joints_);
  }
  for (int j = 0; j < num_joints_; ++j) {
    const double rms = Y.rows() > 0 ? std::sqrt(Y.col(j).squaredNorm() / Y.rows()) : 1.0;
    h.log_output_scale[j] = std::log(rms > 1e-12 ? rms : 1.0);
  }
  h.log_noise_std = std::log(0.1);
  return h;
}

Status RobotModel::Fit(const ConstMatrixRef& X, const ConstMatrixRef& Y) {
  return Fit(X, Y, DefaultHyperparameters(Y));
}

Status RobotModel::Fit(const ConstMatrixRef& X, const ConstMatrixRef& Y,
                       const Hyperparameters& hyper) {
  RequireSize("RobotModel::Fit X", X.cols(), input_dim(), "columns");
  RequireSize("RobotModel::Fit Y", Y.cols(), num_joints_, "columns (joints)");
  if (hyper.is_per_output() && (spec_.base == BaseModel::kLagk || regressor_)) {
    throw std::invalid_argument("model '" + ToString(spec_) +
                                "' shares its parameters across joints: per-joint "
                                "hyper-parameters are for pol, motor, rbf and rbfs models");
  }
  std::unique_ptr<GaussianProcess> gp;
  if (spec_.base == BaseModel::kLagk) {
    gp = std::make_unique<GaussianProcess>(
        GaussianProcess::EulerLagrange(num_joints_, spec_.friction, hyper, options_.batch,
                                       effect_map_, effect_prior_variance_));
  } else if (regressor_) {
    gp = std::make_unique<GaussianProcess>(regressor_, hyper, options_.batch);
  } else if (map_) {
    gp = std::make_unique<GaussianProcess>(map_, hyper, num_joints_, options_.form,
                                           options_.batch);
  } else {
    gp = std::make_unique<GaussianProcess>(*kernel_, hyper, num_joints_, options_.batch);
  }
  const Status status = prior_mean_ ? gp->Fit(X, Y - PriorMeanRows(X)) : gp->Fit(X, Y);
  if (status != Status::kOk) return status;
  if (kernel_) kernel_ = kernel_->WithParameters(hyper.shape);
  gp_ = std::move(gp);
  hyper_ = hyper;
  latent_variance_scale_ = Vector::Ones(num_joints_);
  return Status::kOk;
}

void RobotModel::SetLatentVarianceScale(const Vector& scale) {
  RequireSize("RobotModel::SetLatentVarianceScale scale", scale.size(), num_joints_,
              "entries (joints)");
  for (Eigen::Index j = 0; j < scale.size(); ++j) {
    if (!(std::isfinite(scale[j]) && scale[j] > 0.0)) {
      throw std::invalid_argument(
          "RobotModel::SetLatentVarianceScale scale[" + std::to_string(j) +
          "]: expected a finite value > 0, got " + std::to_string(scale[j]));
    }
  }
  latent_variance_scale_ = scale;
}

RobotModelState RobotModel::State() const {
  const GaussianProcess& fitted_gp = gp();
  RobotModelState state;
  state.spec = spec_;
  state.num_joints = num_joints_;
  state.options = options_;
  state.hyperparameters = hyper_;
  if (bands_calibrated()) state.latent_variance_scale = latent_variance_scale_;
  state.form = fitted_gp.form();
  if (const EulerLagrangeGP* euler = fitted_gp.euler_lagrange()) {
    state.inputs = euler->inputs();
    state.targets = euler->targets();
    if (euler->dtc()) state.inducing = euler->states();
  } else if (const RegressorGP* regressor = fitted_gp.regressor()) {
    state.regressor = regressor->State();
  } else if (const WeightSpaceGP* ws = fitted_gp.weight_space()) {
    state.weight_space = ws->State();
  } else if (fitted_gp.per_output() && fitted_gp.form() == Form::kWeightSpace) {
    for (int j = 0; j < num_joints_; ++j) {
      state.joint_weight_space.push_back(fitted_gp.output(j).weight_space()->State());
    }
  } else if (fitted_gp.per_output()) {
    // The same points for every joint: each joint's targets are its column.
    state.inputs = fitted_gp.output(0).function_space()->inputs();
    state.targets.resize(state.inputs.rows(), num_joints_);
    for (int j = 0; j < num_joints_; ++j) {
      state.targets.col(j) = fitted_gp.output(j).function_space()->targets().col(0);
    }
  } else {
    state.inputs = fitted_gp.function_space()->inputs();
    state.targets = fitted_gp.function_space()->targets();
  }
  return state;
}

RobotModel RobotModel::FromState(const RobotModelState& state) {
  RobotModel model = RestoreState(state);
  if (state.latent_variance_scale.size() > 0) {
    model.SetLatentVarianceScale(state.latent_variance_scale);
  }
  return model;
}

RobotModel RobotModel::RestoreState(const RobotModelState& state) {
  RobotModel model(state.spec, state.num_joints, state.options);
  const int N = model.num_joints_;
  const Hyperparameters& hyper = state.hyperparameters;
  if (state.form == Form::kEulerLagrange || state.spec.base == BaseModel::kLagk) {
    if (state.form != Form::kEulerLagrange || state.spec.base != BaseModel::kLagk) {
      throw std::invalid_argument("RobotModel::FromState: model '" + ToString(state.spec) +
                                  "' and form " + ToString(state.form) + " do not go together");
    }
    RequireSize("RobotModel::FromState inputs", state.inputs.cols(), model.input_dim(), "columns");
    RequireSize("RobotModel::FromState targets", state.targets.cols(), N, "columns (joints)");
    RequireSize("RobotModel::FromState targets", state.targets.rows(), state.inputs.rows(),
                "rows (as in inputs)");
    if (state.inducing.size() > 0) {
      RequireSize("RobotModel::FromState inducing", state.inducing.cols(), model.input_dim(),
                  "columns");
    }
    RequireFinite("RobotModel::FromState inputs", state.inputs);
    RequireFinite("RobotModel::FromState targets", state.targets);
    RequireFinite("RobotModel::FromState inducing", state.inducing);
    model.gp_ = std::make_unique<GaussianProcess>(GaussianProcess::EulerLagrangeFromData(
        N, state.spec.friction, hyper, state.options.batch, state.inputs, state.targets,
        state.inducing, model.effect_map_, model.effect_prior_variance_,
        state.euler_lagrange_factors.get()));
    model.hyper_ = hyper;
    return model;
  }
  if (state.form == Form::kRegressor || model.regressor_) {
    if (state.form != Form::kRegressor || !model.regressor_) {
      throw std::invalid_argument("RobotModel::FromState: model '" + ToString(state.spec) +
                                  "' and form " + ToString(state.form) + " do not go together");
    }
    model.gp_ = std::make_unique<GaussianProcess>(GaussianProcess::FromRegressor(
        model.regressor_, hyper, state.options.batch, RegressorGP::FromState(state.regressor)));
    model.hyper_ = hyper;
    return model;
  }
  if (state.form == Form::kWeightSpace) {
    if (!model.map_) {
      throw std::invalid_argument("RobotModel::FromState: model '" + ToString(state.spec) +
                                  "' for " + std::to_string(N) +
                                  " joints has no feature map, so no weight-space form");
    }
    ValidateHyperparameters(hyper, *model.map_, N);
    if (hyper.is_per_output()) {
      RequireSize("RobotModel::FromState joint_weight_space",
                  static_cast<Eigen::Index>(state.joint_weight_space.size()), N,
                  "posteriors (one per joint)");
      std::vector<WeightSpaceGP> posteriors;
      for (const WeightSpaceGPState& joint : state.joint_weight_space) {
        posteriors.push_back(WeightSpaceGP::FromState(joint));
      }
      const Eigen::Index rows = std::max<long>(0, posteriors.front().num_samples());
      model.gp_ = std::make_unique<GaussianProcess>(GaussianProcess::FromWeightSpaceOutputs(
          model.map_, hyper, state.options.form, state.options.batch, std::move(posteriors),
          rows));
      model.hyper_ = hyper;
      return model;
    }
    WeightSpaceGP posterior = WeightSpaceGP::FromState(state.weight_space);
    const Eigen::Index rows = std::max<long>(0, posterior.num_samples());
    model.gp_ = std::make_unique<GaussianProcess>(
        GaussianProcess::FromWeightSpace(model.map_, hyper, N, state.options.form,
                                         state.options.batch, std::move(posterior), rows));
    model.hyper_ = hyper;
    return model;
  }
  if (state.form != Form::kFunctionSpace) {
    throw std::invalid_argument(
        "RobotModel::FromState: form: expected weight_space or function_space, got " +
        std::string(ToString(state.form)));
  }
  RequireSize("RobotModel::FromState inputs", state.inputs.cols(), model.input_dim(), "columns");
  RequireSize("RobotModel::FromState targets", state.targets.cols(), N, "columns (joints)");
  RequireSize("RobotModel::FromState targets", state.targets.rows(), state.inputs.rows(),
              "rows (as in inputs)");
  // The stored points are the model's own (a subset already, if one was taken): all of them,
  // in function space, whatever the form option would choose for their number.
  BatchFitOptions batch = state.options.batch;
  batch.max_kernel_rows = 0;
  std::unique_ptr<GaussianProcess> restored =
      model.map_ ? std::make_unique<GaussianProcess>(model.map_, hyper, N, Form::kFunctionSpace,
                                                     batch)
                 : std::make_unique<GaussianProcess>(*model.kernel_, hyper, N, batch);
  const Status status = restored->Fit(state.inputs, state.targets);
  if (status != Status::kOk) {
    throw std::invalid_argument(std::string("RobotModel::FromState: the stored points cannot be "
                                            "refitted: ") +
                                ToString(status));
  }
  if (model.kernel_) model.kernel_ = model.kernel_->WithParameters(hyper.shape);
  model.gp_ = std::move(restored);
  model.hyper_ = hyper;
  return model;
}

const GaussianProcess& RobotModel::gp() const {
  if (!gp_) throw std::logic_error("RobotModel: not fitted");
  return *gp_;
}

GaussianProcess& RobotModel::mutable_gp() {
  if (!gp_) throw std::logic_error("RobotModel: not fitted");
  return *gp_;
}

RobotModel::Workspace RobotModel::MakeWorkspace() const {
  Workspace workspace{gp().MakeWorkspace(), Vector()};
  if (prior_mean_) workspace.prior_mean.resize(num_joints_);
  return workspace;
}

Matrix RobotModel::PriorMeanRows(const ConstMatrixRef& X) const {
  if (X.cols() != input_dim() && X.cols() != 3 * num_joints_) {
    RequireSize("RobotModel::PriorMeanRows X", X.cols(), input_dim(), "columns");
  }
  Matrix mean = Matrix::Zero(X.rows(), num_joints_);
  if (!prior_mean_) return mean;
  Vector tau(num_joints_);
  for (Eigen::Index i = 0; i < X.rows(); ++i) {
    prior_mean_->Torque(X.row(i).head(3 * num_joints_).transpose(), tau);
    mean.row(i) = tau.transpose();
  }
  return mean;
}

namespace {

// Adds the prior mean at x (the state part) to mean, after the GP's prediction succeeded.
Status AddPriorMean(const RigidBodyTorqueFeatureMap* prior_mean, int num_joints,
                    const ConstVectorRef& x, Status status, VectorRef mean, Vector* scratch) {
  if (status != Status::kOk || prior_mean == nullptr) return status;
  if (scratch->size() != num_joints) return Status::kInvalidInput;  // a workspace of another model
  prior_mean->Torque(x.head(3 * num_joints), *scratch);
  mean += *scratch;
  return Status::kOk;
}

}  // namespace

Status RobotModel::Predict(const ConstVectorRef& x, VectorRef mean, Workspace& workspace) const {
  return AddPriorMean(prior_mean_.get(), num_joints_, x, gp().Predict(x, mean, workspace.gp),
                      mean, &workspace.prior_mean);
}

Status RobotModel::PredictWithVariance(const ConstVectorRef& x, VectorRef mean,
                                       VectorRef latent_variance, VectorRef noisy_variance,
                                       Workspace& workspace) const {
  const Status status = AddPriorMean(
      prior_mean_.get(), num_joints_, x,
      gp().PredictWithVariance(x, mean, latent_variance, noisy_variance, workspace.gp), mean,
      &workspace.prior_mean);
  if (status == Status::kOk && bands_calibrated()) {
    // kappa v + sigma^2 = (v + sigma^2) + (kappa - 1) v; allocation-free.
    noisy_variance.array() +=
        (latent_variance_scale_.array() - 1.0) * latent_variance.array();
    latent_variance.array() *= latent_variance_scale_.array();
  }
  return status;
}

Status RobotModel::Predict(const ConstVectorRef& x, VectorRef mean) const {
  Workspace workspace = MakeWorkspace();
  return Predict(x, mean, workspace);
}

Status RobotModel::PredictWithVariance(const ConstVectorRef& x, VectorRef mean,
                                       VectorRef latent_variance, VectorRef noisy_variance) const {
  Workspace workspace = MakeWorkspace();
  return PredictWithVariance(x, mean, latent_variance, noisy_variance, workspace);
}

void RobotModel::PredictRows(const ConstMatrixRef& X, Matrix* mean, Matrix* latent_std,
                             int num_threads) const {
  RequireSize("RobotModel::PredictRows X", X.cols(), input_dim(), "columns");
  RequireFinite("RobotModel::PredictRows X", X);
  if (num_threads < 1) {
    throw std::invalid_argument("RobotModel::PredictRows: expected num_threads >= 1, got " +
                                std::to_string(num_threads));
  }
  const int N = num_joints_;
  const Eigen::Index rows = X.rows();
  mean->resize(rows, N);
  if (latent_std) latent_std->resize(rows, N);
  // Contiguous ranges of rows, one per worker with its own workspace: each row's prediction
  // is the one-thread one, and the first failing row is reported as on one thread (the
  // workers' errors are rethrown in range order).
  const int workers =
      static_cast<int>(std::max<Eigen::Index>(1, std::min<Eigen::Index>(num_threads, rows)));
  internal::RunWorkers(workers, [&](int w) {
    Vector x(input_dim()), m(N), lv(N), nv(N);
    Workspace workspace = MakeWorkspace();
    for (Eigen::Index i = rows * w / workers; i < rows * (w + 1) / workers; ++i) {
      x = X.row(i).transpose();
      const Status s = latent_std ? PredictWithVariance(x, m, lv, nv, workspace)
                                  : Predict(x, m, workspace);
      if (s != Status::kOk) {
        throw std::runtime_error(std::string("RobotModel::PredictRows: row ") +
                                 std::to_string(i) + ": " + ToString(s));
      }
      mean->row(i) = m.transpose();
      if (latent_std) latent_std->row(i) = lv.cwiseSqrt().transpose();
    }
  });
}

std::vector<std::string> RobotModel::ComponentNames() const {
  if (regressor_) return regressor_->component_names();
  std::vector<std::string> names;
  for (const auto& p : parts_) names.push_back(p.name);
  if (prior_mean_) {
    for (const FeatureBlock& b : prior_mean_->blocks()) names.push_back(b.name);
  }
  return names;
}

Status RobotModel::PredictComponents(const ConstVectorRef& x,
                                     std::vector<Component>* components) const {
  if (regressor_) {
    if (!gp_ || gp_->regressor() == nullptr || x.size() != input_dim() || !x.allFinite()) {
      return Status::kInvalidInput;
    }
    const RegressorGP& gp = *gp_->regressor();
    const int N = num_joints_;
    Matrix psi(N, regressor_->dim());
    Vector noisy(N);
    RegressorGP::Workspace workspace = gp.MakeWorkspace();
    const std::unique_ptr<RegressorMap::Scratch> scratch = regressor_->MakeScratch();
    const std::vector<std::string> names = regressor_->component_names();
    components->clear();
    for (size_t c = 0; c < names.size(); ++c) {
      Component component;
      component.name = names[c];
      component.mean.resize(N);
      component.latent_variance.resize(N);
      regressor_->EvaluateComponent(static_cast<int>(c), x, psi, scratch.get());
      const Status status = gp.PredictWithVariance(psi, component.mean, component.latent_variance,
                                                   noisy, workspace);
      if (status != Status::kOk) return status;
      components->push_back(std::move(component));
    }
    return Status::kOk;
  }
  if (!gp_ || !map_ || JointPosterior(0).first == nullptr || x.size() != input_dim() ||
      !x.allFinite()) {
    return Status::kInvalidInput;
  }
  Vector phi(map_->dim());
  map_->Evaluate(x, phi);
  components->clear();
  for (const auto& p : parts_) {
    Component c;
    c.name = p.name;
    c.mean.resize(num_joints_);
    c.latent_variance.resize(num_joints_);
    const auto phi_p = phi.segment(p.begin, p.size);
    const WeightSpaceGP* last = nullptr;
    double quad = 0.0;
    for (int j = 0; j < num_joints_; ++j) {
      const auto [ws, column] = JointPosterior(j);
      if (ws != last) {
        // phi_p^T (A^{-1})_pp phi_p = ||S^T phi_masked||^2, only rows of the part contribute;
        // the same for every column of one posterior.
        quad = (ws->covariance_factor().middleRows(p.begin, p.size).transpose() * phi_p)
                   .squaredNorm();
        last = ws;
      }
      c.mean[j] = ws->weights().col(column).segment(p.begin, p.size).dot(phi_p);
      const double scale = ws->output_scales()[column];
      c.latent_variance[j] = quad * scale * scale * ws->noise_variance();
    }
    components->push_back(std::move(c));
  }
  if (prior_mean_) {
    // The fixed mean's three terms, without variance.
    const int N = num_joints_;
    Vector terms(prior_mean_->dim());
    prior_mean_->Evaluate(x.head(3 * N), terms);
    for (const FeatureBlock& b : prior_mean_->blocks()) {
      components->push_back(Component{b.name, terms.segment(b.begin, b.size), Vector::Zero(N)});
    }
  }
  return Status::kOk;
}

std::pair<double, double> RobotModel::Coefficient(const std::string& feature, int joint) const {
  if (joint < 1 || joint > num_joints_) {
    throw std::invalid_argument("Coefficient: joint " + std::to_string(joint) +
                                " out of range 1.." + std::to_string(num_joints_));
  }
  if (!gp_ || (gp_->regressor() == nullptr && JointPosterior(0).first == nullptr)) {
    throw std::invalid_argument("Coefficient: needs a fitted weight-space model");
  }
  for (const auto& [name, index] : parametric_names_) {
    if (name == feature) return CoefficientAt(index, joint);
  }
  throw std::invalid_argument("Coefficient: the model has no feature '" + feature + "'");
}

std::pair<double, double> RobotModel::CoefficientAt(int index, int joint) const {
  if (gp_->regressor() != nullptr) {
    // Shared parameters: the name says which joint a friction or effect column acts on.
    const RegressorGP& gp = *gp_->regressor();
    const Matrix covariance = gp.ParameterCovariance();
    return {gp.parameters()[index], std::sqrt(std::max(0.0, covariance(index, index)))};
  }
  const auto [ws, column] = JointPosterior(joint - 1);
  const double value = ws->weights()(index, column);
  const double scale = ws->output_scales()[column];
  const double var =
      ws->covariance_factor().row(index).squaredNorm() * ws->noise_variance() * scale * scale;
  return {value, std::sqrt(var)};
}

std::pair<const WeightSpaceGP*, int> RobotModel::JointPosterior(int joint) const {
  if (!gp_) return {nullptr, 0};
  if (gp_->per_output()) return {gp_->output(joint).weight_space(), 0};
  return {gp_->weight_space(), joint};
}

namespace {

// The joint (1-based) of a feature named "<basis>@<joint>" (FrictionFeatureMap, EffectFeatureMap,
// SemiParametricRegressorMap name them so); 0 without a joint suffix.
int FeatureJoint(const std::string& name) {
  const auto at = name.rfind('@');
  if (at == std::string::npos || at + 1 == name.size()) return 0;
  int joint = 0;
  for (size_t i = at + 1; i < name.size(); ++i) {
    if (name[i] < '0' || name[i] > '9' || joint > 100000) return 0;
    joint = 10 * joint + (name[i] - '0');
  }
  return joint;
}

}  // namespace

bool RobotModel::has_components() const {
  if (!gp_) return false;
  if (regressor_) return gp_->regressor() != nullptr;
  return map_ != nullptr && JointPosterior(0).first != nullptr;
}

std::vector<ComponentRows> RobotModel::PredictComponentRows(const ConstMatrixRef& X) const {
  RequireSize("RobotModel::PredictComponentRows X", X.cols(), input_dim(), "columns");
  RequireFinite("RobotModel::PredictComponentRows X", X);
  if (!has_components()) {
    throw std::invalid_argument(
        "RobotModel::PredictComponentRows: components need a fitted weight-space pol or motor "
        "model, or rbd or lag; this is " + ModelLabel(spec_) +
        (gp_ ? std::string(" in ") + ToString(gp_->form()) + " form" : std::string(", not fitted")));
  }
  const std::vector<std::string> names = ComponentNames();
  const Eigen::Index m = X.rows();
  std::vector<ComponentRows> rows(names.size());
  for (size_t c = 0; c < names.size(); ++c) {
    rows[c].name = names[c];
    rows[c].mean.resize(m, num_joints_);
    rows[c].latent_std.resize(m, num_joints_);
  }
  std::vector<Component> parts;
  for (Eigen::Index i = 0; i < m; ++i) {
    const Status s = PredictComponents(X.row(i).transpose(), &parts);
    if (s != Status::kOk) {
      throw std::runtime_error("RobotModel::PredictComponentRows: row " + std::to_string(i) +
                               ": " + ToString(s));
    }
    for (size_t c = 0; c < rows.size(); ++c) {
      rows[c].mean.row(i) = parts[c].mean.transpose();
      rows[c].latent_std.row(i) = parts[c].latent_variance.cwiseMax(0.0).cwiseSqrt().transpose();
    }
  }
  return rows;
}

std::vector<FeatureCoefficient> RobotModel::Coefficients() const {
  if (parametric_names_.empty()) return {};
  const bool regressor = gp_ && gp_->regressor() != nullptr;
  if (!regressor && JointPosterior(0).first == nullptr) {
    throw std::invalid_argument("RobotModel::Coefficients: needs a fitted weight-space or rbd/lag "
                                "model; this is " + ModelLabel(spec_) +
                                (gp_ ? std::string(" in ") + ToString(gp_->form()) + " form"
                                     : std::string(", not fitted")));
  }
  std::vector<FeatureCoefficient> out;
  for (const auto& [name, index] : parametric_names_) {
    const int joint = FeatureJoint(name);
    const int first = joint > 0 ? joint : 1;
    const int last = joint > 0 ? joint : (regressor ? 1 : num_joints_);
    if (joint > num_joints_) continue;  // not a joint suffix of this robot
    for (int j = first; j <= last; ++j) {
      const auto [value, std] = CoefficientAt(index, j);
      out.push_back({name, joint > 0 || !regressor ? j : 0, value, std});
    }
  }
  return out;
}

std::vector<std::string> RobotModel::ParametricFeatureNames() const {
  std::vector<std::string> names;
  for (const auto& entry : parametric_names_) names.push_back(entry.first);
  return names;
}

}  // namespace structgp
