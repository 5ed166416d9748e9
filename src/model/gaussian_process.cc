#include "structgp/model/gaussian_process.h"

#include <stdexcept>
#include <string>
#include <utility>

#include "structgp/core/row_subset.h"
#include "structgp/core/validate.h"
#include "structgp/kernel/feature_kernel.h"

namespace structgp {

const char* ToString(Form form) {
  switch (form) {
    case Form::kAuto:
      return "auto";
    case Form::kWeightSpace:
      return "weight_space";
    case Form::kFunctionSpace:
      return "function_space";
    case Form::kRegressor:
      return "regressor";
    case Form::kEulerLagrange:
      return "euler_lagrange";
  }
  return "unknown";
}

namespace {

void ValidateBatch(const BatchFitOptions& batch) {
  if (batch.num_threads < 1) {
    throw std::invalid_argument("BatchFitOptions::num_threads: expected >= 1, got " +
                                std::to_string(batch.num_threads));
  }
  if (batch.chunk_rows < 1) {
    throw std::invalid_argument("BatchFitOptions::chunk_rows: expected >= 1, got " +
                                std::to_string(batch.chunk_rows));
  }
  if (batch.inducing_states < 0) {
    throw std::invalid_argument("BatchFitOptions::inducing_states: expected >= 0 (0: exact), got " +
                                std::to_string(batch.inducing_states));
  }
  if (batch.max_kernel_rows < 0) {
    throw std::invalid_argument(
        "BatchFitOptions::max_kernel_rows: expected >= 0 (0: no limit), "
        "got " +
        std::to_string(batch.max_kernel_rows));
  }
}

// The evenly spaced subset of X and Y (core/row_subset.h) when m > max_rows > 0; else
// nothing is copied.
bool EvenlySpaced(const ConstMatrixRef& X, const ConstMatrixRef& Y, int max_rows, Matrix* Xs,
                  Matrix* Ys) {
  if (max_rows == 0 || X.rows() <= max_rows) return false;
  const std::vector<int> rows = EvenlySpacedRows(X.rows(), max_rows);
  *Xs = SelectRows(X, rows);
  *Ys = SelectRows(Y, rows);
  return true;
}

}  // namespace

GaussianProcess::GaussianProcess(std::shared_ptr<const FeatureMap> map,
                                 const Hyperparameters& hyper, int num_outputs, Form form,
                                 const BatchFitOptions& batch)
    : map_(std::move(map)),
      hyper_(hyper),
      num_outputs_(num_outputs),
      requested_(form),
      active_(form),
      batch_(batch) {
  ValidateBatch(batch_);
  if (!map_) throw std::invalid_argument("GaussianProcess: null feature map");
  ValidateHyperparameters(hyper_, *map_, num_outputs);
  phi_.resize(map_->dim());
  for (const Hyperparameters& h : hyper_.per_output) {
    outputs_.push_back(GaussianProcess(map_, h, 1, form, batch_));
  }
  y1_.resize(1);
}

GaussianProcess::GaussianProcess(const Kernel& kernel, const Hyperparameters& hyper,
                                 int num_outputs, const BatchFitOptions& batch)
    : hyper_(hyper),
      num_outputs_(num_outputs),
      requested_(Form::kFunctionSpace),
      active_(Form::kFunctionSpace),
      batch_(batch) {
  ValidateBatch(batch_);
  ValidateHyperparameters(hyper_, kernel, num_outputs);
  kernel_ = kernel.WithParameters(hyper_.shape);
  if (hyper_.is_per_output()) {
    for (const Hyperparameters& h : hyper_.per_output) {
      outputs_.push_back(GaussianProcess(kernel, h, 1, batch_));
    }
    y1_.resize(1);
    return;
  }
  function_space_ = std::make_unique<KernelGP>(*kernel_, hyper_.noise_variance(), num_outputs,
                                               hyper_.output_scales());
}

namespace {

// The regressor and Euler-Lagrange forms share their parameters across outputs.
void RequireShared(const Hyperparameters& hyper, const char* form) {
  if (hyper.is_per_output()) {
    throw std::invalid_argument(std::string("GaussianProcess: per-output hyper-parameters are not "
                                            "available in the ") +
                                form + " form, whose outputs share their parameters");
  }
}

void ValidateRegressorHyperparameters(const Hyperparameters& hyper, const RegressorMap& map) {
  RequireShared(hyper, "regressor");
  hyper.Validate(0, static_cast<Eigen::Index>(map.blocks().size()), map.num_outputs(),
                 "regressor Hyperparameters");
}

Vector RegressorNoise(const Hyperparameters& hyper) {
  return (2.0 * (hyper.log_output_scale.array() + hyper.log_noise_std)).exp().matrix();
}

}  // namespace

GaussianProcess::GaussianProcess(std::shared_ptr<const RegressorMap> map,
                                 const Hyperparameters& hyper, const BatchFitOptions& batch)
    : hyper_(hyper),
      num_outputs_(map ? map->num_outputs() : 0),
      requested_(Form::kRegressor),
      active_(Form::kRegressor),
      regressor_map_(std::move(map)),
      batch_(batch) {
  ValidateBatch(batch_);
  if (!regressor_map_) throw std::invalid_argument("GaussianProcess: null regressor map");
  ValidateRegressorHyperparameters(hyper_, *regressor_map_);
  regressor_scratch_ = regressor_map_->MakeScratch() != nullptr;
}

GaussianProcess GaussianProcess::FromRegressor(std::shared_ptr<const RegressorMap> map,
                                               const Hyperparameters& hyper,
                                               const BatchFitOptions& batch,
                                               RegressorGP posterior) {
  GaussianProcess gp(std::move(map), hyper, batch);
  RequireSize("GaussianProcess::FromRegressor posterior parameters", posterior.dim(),
              gp.regressor_map_->dim());
  RequireSize("GaussianProcess::FromRegressor posterior outputs", posterior.num_outputs(),
              gp.num_outputs_);
  const auto rows = static_cast<Eigen::Index>(posterior.statistics().count);
  gp.regressor_gp_ = std::make_unique<RegressorGP>(std::move(posterior));
  gp.data_rows_ = rows;
  gp.fit_rows_ = rows;
  return gp;
}

GaussianProcess::GaussianProcess(EulerLagrangeGPHyperparameters euler,
                                 std::shared_ptr<const FeatureMap> effects,
                                 const Hyperparameters& hyper, const BatchFitOptions& batch)
    : hyper_(hyper),
      num_outputs_(euler.num_joints()),
      requested_(Form::kEulerLagrange),
      active_(Form::kEulerLagrange),
      batch_(batch) {
  ValidateBatch(batch_);
  RequireShared(hyper_, "Euler-Lagrange");
  euler_hyper_ = std::make_unique<EulerLagrangeGPHyperparameters>(std::move(euler));
  euler_effects_ = std::move(effects);
  EulerLagrangeGP check(*euler_hyper_, euler_effects_);  // the map fits the hyper-parameters
}

GaussianProcess GaussianProcess::EulerLagrange(int num_joints, bool friction,
                                               const Hyperparameters& hyper,
                                               const BatchFitOptions& batch,
                                               std::shared_ptr<const FeatureMap> effects,
                                               const Vector& effect_prior_variance) {
  return GaussianProcess(
      EulerLagrangeFromHyperparameters(hyper, num_joints, friction, effect_prior_variance),
      std::move(effects), hyper, batch);
}

GaussianProcess GaussianProcess::EulerLagrangeFromData(
    int num_joints, bool friction, const Hyperparameters& hyper, const BatchFitOptions& batch,
    const ConstMatrixRef& inputs, const ConstMatrixRef& targets, const ConstMatrixRef& inducing,
    std::shared_ptr<const FeatureMap> effects, const Vector& effect_prior_variance,
    EulerLagrangeGP::DtcFactors* dtc_factors) {
  GaussianProcess gp =
      EulerLagrange(num_joints, friction, hyper, batch, std::move(effects), effect_prior_variance);
  auto model = std::make_unique<EulerLagrangeGP>(*gp.euler_hyper_, gp.euler_effects_);
  if (dtc_factors && inducing.size() > 0) {
    const Status status = model->RestoreDtc(inputs, targets, inducing, std::move(*dtc_factors));
    if (status != Status::kOk) {
      throw std::invalid_argument(
          std::string("GaussianProcess::EulerLagrangeFromData: the posterior's factors are "
                      "refused: ") +
          ToString(status));
    }
  } else {
    const Status status = model->Condition(inputs, targets, inducing, batch.num_threads);
    if (status != Status::kOk) {
      throw std::invalid_argument(
          std::string("GaussianProcess::EulerLagrangeFromData: the posterior cannot be "
                      "factorised: ") +
          ToString(status));
    }
  }
  gp.euler_lagrange_ = std::move(model);
  gp.data_rows_ = inputs.rows();
  gp.fit_rows_ = inputs.rows();
  return gp;
}

GaussianProcess GaussianProcess::FromWeightSpace(std::shared_ptr<const FeatureMap> map,
                                                 const Hyperparameters& hyper, int num_outputs,
                                                 Form form, const BatchFitOptions& batch,
                                                 WeightSpaceGP posterior, Eigen::Index rows) {
  GaussianProcess gp(std::move(map), hyper, num_outputs, form, batch);
  RequireSize("GaussianProcess::FromWeightSpace posterior features", posterior.num_features(),
              gp.map_->dim());
  RequireSize("GaussianProcess::FromWeightSpace posterior outputs", posterior.num_outputs(),
              num_outputs);
  if (rows < 0) {
    throw std::invalid_argument("GaussianProcess::FromWeightSpace: expected rows >= 0, got " +
                                std::to_string(rows));
  }
  gp.weight_space_ = std::make_unique<WeightSpaceGP>(std::move(posterior));
  gp.active_ = Form::kWeightSpace;
  gp.data_rows_ = rows;
  gp.fit_rows_ = rows;
  return gp;
}

GaussianProcess GaussianProcess::FromWeightSpaceOutputs(std::shared_ptr<const FeatureMap> map,
                                                        const Hyperparameters& hyper, Form form,
                                                        const BatchFitOptions& batch,
                                                        std::vector<WeightSpaceGP> posteriors,
                                                        Eigen::Index rows) {
  GaussianProcess gp(std::move(map), hyper, static_cast<int>(posteriors.size()), form, batch);
  if (!gp.per_output()) {
    throw std::invalid_argument(
        "GaussianProcess::FromWeightSpaceOutputs: hyper has no per-output sets");
  }
  for (size_t j = 0; j < posteriors.size(); ++j) {
    gp.outputs_[j] = FromWeightSpace(gp.map_, hyper.per_output[j], 1, form, batch,
                                     std::move(posteriors[j]), rows);
  }
  gp.active_ = Form::kWeightSpace;
  gp.data_rows_ = rows;
  gp.fit_rows_ = rows;
  return gp;
}

const GaussianProcess& GaussianProcess::output(int j) const {
  if (outputs_.empty()) throw std::logic_error("GaussianProcess::output: outputs share one model");
  if (j < 0 || j >= static_cast<int>(outputs_.size())) {
    throw std::out_of_range("GaussianProcess::output: " + std::to_string(j) + " not in 0.." +
                            std::to_string(outputs_.size() - 1));
  }
  return outputs_[static_cast<size_t>(j)];
}

int GaussianProcess::input_dim() const {
  if (regressor_map_) return regressor_map_->input_dim();
  if (euler_hyper_) return euler_effects_ ? euler_effects_->input_dim() : 3 * num_outputs_;
  return map_ ? map_->input_dim() : kernel_->input_dim();
}

Status GaussianProcess::Fit(const ConstMatrixRef& X, const ConstMatrixRef& Y) {
  RequireSize("GaussianProcess::Fit X", X.cols(), input_dim(), "columns");
  RequireSize("GaussianProcess::Fit Y", Y.cols(), num_outputs_, "columns");
  RequireSize("GaussianProcess::Fit Y", Y.rows(), X.rows(), "rows (as in X)");
  RequireFinite("GaussianProcess::Fit X", X);
  RequireFinite("GaussianProcess::Fit Y", Y);
  if (!outputs_.empty()) return FitOutputs(X, Y);
  if (regressor_map_) {
    RegressorStatistics stats(regressor_map_->dim(), num_outputs_);
    stats.Accumulate(*regressor_map_, X, Y, batch_.chunk_rows);
    auto model = std::make_unique<RegressorGP>(
        regressor_map_->prior_mean(), RegressorPriorVariance(*regressor_map_, hyper_.log_block_scale),
        RegressorNoise(hyper_));
    const Status status = model->Fit(stats);
    if (status != Status::kOk) return status;
    regressor_gp_ = std::move(model);
    data_rows_ = X.rows();
    fit_rows_ = X.rows();
    return Status::kOk;
  }
  if (euler_hyper_) {
    auto model = std::make_unique<EulerLagrangeGP>(*euler_hyper_, euler_effects_);
    const Status status = model->Condition(X, Y, batch_.inducing_states,
                                           EulerLagrangeGP::InducingRule::kCoverStates,
                                           batch_.num_threads);
    if (status != Status::kOk) return status;
    euler_lagrange_ = std::move(model);
    data_rows_ = X.rows();
    fit_rows_ = X.rows();
    return Status::kOk;
  }
  Matrix Xs, Ys;
  const bool subset = EvenlySpaced(X, Y, batch_.max_kernel_rows, &Xs, &Ys);
  const Eigen::Index kernel_rows = subset ? Xs.rows() : X.rows();
  if (!map_) {
    const Status status = subset ? function_space_->Fit(Xs, Ys) : function_space_->Fit(X, Y);
    if (status != Status::kOk) return status;
    data_rows_ = X.rows();
    fit_rows_ = kernel_rows;
    return status;
  }

  Form form = requested_;
  if (form == Form::kAuto) {
    form = map_->dim() <= X.rows() ? Form::kWeightSpace : Form::kFunctionSpace;
  }
  if (form == Form::kWeightSpace) {
    auto model =
        std::make_unique<WeightSpaceGP>(PriorVariance(*map_, hyper_), hyper_.noise_variance(),
                                        num_outputs_, hyper_.output_scales());
    // Stream the features in chunks: memory O(threads * (D^2 + chunk * D)), never O(m * D).
    AccumulateOptions accumulate;
    accumulate.chunk_rows = batch_.chunk_rows;
    accumulate.num_threads = batch_.num_threads;
    const SufficientStatistics stats = AccumulateStatistics(*map_, X, Y, accumulate);
    const Status status = model->Fit(stats);
    if (status != Status::kOk) return status;
    weight_space_ = std::move(model);
    function_space_.reset();
    fit_rows_ = X.rows();
  } else {
    kernel_ = std::make_unique<FeatureKernel>(map_, hyper_);
    auto model = std::make_unique<KernelGP>(*kernel_, hyper_.noise_variance(), num_outputs_,
                                            hyper_.output_scales());
    const Status status = subset ? model->Fit(Xs, Ys) : model->Fit(X, Y);
    if (status != Status::kOk) return status;
    function_space_ = std::move(model);
    weight_space_.reset();
    fit_rows_ = kernel_rows;
  }
  data_rows_ = X.rows();
  active_ = form;
  return Status::kOk;
}

Status GaussianProcess::FitOutputs(const ConstMatrixRef& X, const ConstMatrixRef& Y) {
  Form form = map_ ? requested_ : Form::kFunctionSpace;
  if (form == Form::kAuto) {
    form = map_->dim() <= X.rows() ? Form::kWeightSpace : Form::kFunctionSpace;
  }
  // New models, taken only when every output fits: a failure leaves the model as it was.
  std::vector<GaussianProcess> fitted;
  if (form == Form::kWeightSpace) {
    // One pass over the data for every output: Phi^T Phi is the same, only its prior and noise
    // (and so its factor) differ.
    AccumulateOptions accumulate;
    accumulate.chunk_rows = batch_.chunk_rows;
    accumulate.num_threads = batch_.num_threads;
    const SufficientStatistics stats = AccumulateStatistics(*map_, X, Y, accumulate);
    for (int j = 0; j < num_outputs_; ++j) {
      const Hyperparameters& h = hyper_.per_output[static_cast<size_t>(j)];
      SufficientStatistics own;
      own.gram = stats.gram;
      own.cross = stats.cross.col(j);
      own.y_squared = stats.y_squared.segment(j, 1);
      own.count = stats.count;
      WeightSpaceGP posterior(PriorVariance(*map_, h), h.noise_variance(), 1, h.output_scales());
      const Status status = posterior.Fit(own);
      if (status != Status::kOk) return status;
      fitted.push_back(
          FromWeightSpace(map_, h, 1, Form::kWeightSpace, batch_, std::move(posterior), X.rows()));
    }
  } else {
    for (int j = 0; j < num_outputs_; ++j) {
      const Hyperparameters& h = hyper_.per_output[static_cast<size_t>(j)];
      GaussianProcess gp = map_ ? GaussianProcess(map_, h, 1, Form::kFunctionSpace, batch_)
                                : GaussianProcess(*kernel_, h, 1, batch_);
      const Status status = gp.Fit(X, Y.col(j));
      if (status != Status::kOk) return status;
      fitted.push_back(std::move(gp));
    }
  }
  outputs_ = std::move(fitted);
  active_ = form;
  data_rows_ = X.rows();
  fit_rows_ = outputs_.front().fit_rows_;
  return Status::kOk;
}

GaussianProcess::Workspace GaussianProcess::MakeWorkspace() const {
  Workspace workspace;
  if (!outputs_.empty()) {
    for (const GaussianProcess& gp : outputs_) workspace.outputs.push_back(gp.MakeWorkspace());
    // Weight space: phi(x) evaluated once for every output.
    if (active_ == Form::kWeightSpace) workspace.features.resize(map_->dim());
    workspace.output_mean.resize(1);
    workspace.output_latent.resize(1);
    workspace.output_noisy.resize(1);
    return workspace;
  }
  if (regressor_gp_) {
    workspace.regressor.resize(num_outputs_, regressor_map_->dim());
    workspace.regressor_gp = regressor_gp_->MakeWorkspace();
    workspace.regressor_scratch = regressor_map_->MakeScratch();
  }
  if (function_space_) workspace.function_space = function_space_->MakeWorkspace();
  if (euler_lagrange_) workspace.euler_lagrange = euler_lagrange_->MakeWorkspace();
  if (weight_space_) {
    workspace.features.resize(map_->dim());
    workspace.weight_space = weight_space_->MakeWorkspace();
  }
  return workspace;
}

bool GaussianProcess::OutputsReady(const ConstVectorRef& x, Eigen::Index mean_size,
                                   Workspace& workspace) const {
  if (mean_size != num_outputs_ || workspace.outputs.size() != outputs_.size() ||
      workspace.output_mean.size() != 1 || workspace.output_latent.size() != 1 ||
      workspace.output_noisy.size() != 1) {
    return false;
  }
  if (active_ != Form::kWeightSpace) return true;
  // The outputs' features, once: each output's posterior is then applied to them.
  if (x.size() != input_dim() || !x.allFinite() || workspace.features.size() != map_->dim() ||
      outputs_.front().weight_space_ == nullptr) {
    return false;
  }
  map_->Evaluate(x, workspace.features);
  return true;
}

Status GaussianProcess::Predict(const ConstVectorRef& x, VectorRef mean,
                                Workspace& workspace) const {
  if (!outputs_.empty()) {
    if (!OutputsReady(x, mean.size(), workspace)) return Status::kInvalidInput;
    const bool weights = active_ == Form::kWeightSpace;
    for (size_t j = 0; j < outputs_.size(); ++j) {
      const Status status =
          weights ? outputs_[j].weight_space_->Predict(workspace.features, workspace.output_mean,
                                                      workspace.outputs[j].weight_space)
                  : outputs_[j].Predict(x, workspace.output_mean, workspace.outputs[j]);
      if (status != Status::kOk) return status;
      mean[static_cast<Eigen::Index>(j)] = workspace.output_mean[0];
    }
    return Status::kOk;
  }
  if (regressor_map_) {
    if (!RegressorInputOk(x, workspace)) return Status::kInvalidInput;
    regressor_map_->Evaluate(x, workspace.regressor, workspace.regressor_scratch.get());
    return regressor_gp_->Predict(workspace.regressor, mean);
  }
  if (function_space_) return function_space_->Predict(x, mean, workspace.function_space);
  if (euler_lagrange_) {
    return euler_lagrange_->PredictOne(x, mean, VectorRef(workspace.features),
                                       workspace.euler_lagrange);
  }
  if (!weight_space_ || x.size() != input_dim() || !x.allFinite() ||
      workspace.features.size() != map_->dim()) {
    return Status::kInvalidInput;
  }
  map_->Evaluate(x, workspace.features);
  return weight_space_->Predict(workspace.features, mean, workspace.weight_space);
}

Status GaussianProcess::PredictWithVariance(const ConstVectorRef& x, VectorRef mean,
                                            VectorRef latent_variance, VectorRef noisy_variance,
                                            Workspace& workspace) const {
  if (!outputs_.empty()) {
    if (latent_variance.size() != num_outputs_ || noisy_variance.size() != num_outputs_ ||
        !OutputsReady(x, mean.size(), workspace)) {
      return Status::kInvalidInput;
    }
    const bool weights = active_ == Form::kWeightSpace;
    for (size_t j = 0; j < outputs_.size(); ++j) {
      const Status status =
          weights ? outputs_[j].weight_space_->PredictWithVariance(
                        workspace.features, workspace.output_mean, workspace.output_latent,
                        workspace.output_noisy, workspace.outputs[j].weight_space)
                  : outputs_[j].PredictWithVariance(x, workspace.output_mean,
                                                    workspace.output_latent,
                                                    workspace.output_noisy, workspace.outputs[j]);
      if (status != Status::kOk) return status;
      const auto k = static_cast<Eigen::Index>(j);
      mean[k] = workspace.output_mean[0];
      latent_variance[k] = workspace.output_latent[0];
      noisy_variance[k] = workspace.output_noisy[0];
    }
    return Status::kOk;
  }
  if (regressor_map_) {
    if (!RegressorInputOk(x, workspace)) return Status::kInvalidInput;
    regressor_map_->Evaluate(x, workspace.regressor, workspace.regressor_scratch.get());
    return regressor_gp_->PredictWithVariance(workspace.regressor, mean, latent_variance,
                                              noisy_variance, workspace.regressor_gp);
  }
  if (function_space_) {
    return function_space_->PredictWithVariance(x, mean, latent_variance, noisy_variance,
                                                workspace.function_space);
  }
  if (euler_lagrange_) {
    if (latent_variance.size() != num_outputs_ || noisy_variance.size() != num_outputs_) {
      return Status::kInvalidInput;
    }
    const Status status =
        euler_lagrange_->PredictOne(x, mean, latent_variance, workspace.euler_lagrange);
    if (status != Status::kOk) return status;
    noisy_variance = latent_variance + euler_hyper_->noise_std.cwiseAbs2();
    return Status::kOk;
  }
  if (!weight_space_ || x.size() != input_dim() || !x.allFinite() ||
      workspace.features.size() != map_->dim()) {
    return Status::kInvalidInput;
  }
  map_->Evaluate(x, workspace.features);
  return weight_space_->PredictWithVariance(workspace.features, mean, latent_variance,
                                            noisy_variance, workspace.weight_space);
}

Status GaussianProcess::Predict(const ConstVectorRef& x, VectorRef mean) const {
  Workspace workspace = MakeWorkspace();
  return Predict(x, mean, workspace);
}

Status GaussianProcess::PredictWithVariance(const ConstVectorRef& x, VectorRef mean,
                                            VectorRef latent_variance,
                                            VectorRef noisy_variance) const {
  Workspace workspace = MakeWorkspace();
  return PredictWithVariance(x, mean, latent_variance, noisy_variance, workspace);
}

bool GaussianProcess::RegressorInputOk(const ConstVectorRef& x, const Workspace& workspace) const {
  return regressor_gp_ && x.size() == input_dim() && x.allFinite() &&
         workspace.regressor.rows() == num_outputs_ &&
         workspace.regressor.cols() == regressor_map_->dim() &&
         workspace.regressor_gp.v.size() == regressor_map_->dim() &&
         (workspace.regressor_scratch != nullptr) == regressor_scratch_;
}

Status GaussianProcess::Add(const ConstVectorRef& x, const ConstVectorRef& y) {
  if (!outputs_.empty()) {
    // Checked here so that a bad sample changes no output.
    if (x.size() != input_dim() || !x.allFinite() || y.size() != num_outputs_ || !y.allFinite()) {
      return Status::kInvalidInput;
    }
    const bool weights = active_ == Form::kWeightSpace && outputs_.front().weight_space_;
    if (weights) map_->Evaluate(x, phi_);  // once for every output
    for (size_t j = 0; j < outputs_.size(); ++j) {
      y1_[0] = y[static_cast<Eigen::Index>(j)];
      const Status status =
          weights ? outputs_[j].weight_space_->Update(phi_, y1_) : outputs_[j].Add(x, y1_);
      if (status != Status::kOk) return status;
    }
    return Status::kOk;
  }
  if (regressor_map_) {
    if (!regressor_gp_ || x.size() != input_dim() || !x.allFinite() || y.size() != num_outputs_ ||
        !y.allFinite()) {
      return Status::kInvalidInput;
    }
    RegressorStatistics stats = regressor_gp_->statistics();
    stats.Accumulate(*regressor_map_, x.transpose(), y.transpose());
    auto model = std::make_unique<RegressorGP>(regressor_gp_->prior_mean(),
                                               regressor_gp_->prior_variance(),
                                               regressor_gp_->noise_variance());
    const Status status = model->Fit(stats);
    if (status != Status::kOk) return status;
    regressor_gp_ = std::move(model);
    ++data_rows_;
    ++fit_rows_;
    return Status::kOk;
  }
  if (function_space_) return function_space_->Add(x, y);
  if (euler_hyper_) return Status::kInvalidInput;  // no online update: refit in batch
  if (!weight_space_ || x.size() != input_dim() || !x.allFinite()) return Status::kInvalidInput;
  map_->Evaluate(x, phi_);
  return weight_space_->Update(phi_, y);
}

double GaussianProcess::LogMarginalLikelihood() const {
  if (!outputs_.empty()) {
    // Independent outputs: the evidence of all is the sum of each one's.
    double sum = 0.0;
    for (const GaussianProcess& gp : outputs_) sum += gp.LogMarginalLikelihood();
    return sum;
  }
  if (regressor_map_) {
    if (!regressor_gp_) throw std::logic_error("GaussianProcess: not fitted");
    return regressor_gp_->LogMarginalLikelihood();
  }
  if (function_space_) return function_space_->LogMarginalLikelihood();
  if (euler_lagrange_) return euler_lagrange_->LogMarginalLikelihood();
  if (!weight_space_) throw std::logic_error("GaussianProcess: not fitted");
  return weight_space_->LogMarginalLikelihood();
}

}  // namespace structgp
