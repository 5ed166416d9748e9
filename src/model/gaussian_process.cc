#include "structgp/model/gaussian_process.h"

#include <stdexcept>
#include <string>

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
  function_space_ = std::make_unique<KernelGP>(*kernel_, hyper_.noise_variance(), num_outputs,
                                               hyper_.output_scales());
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

int GaussianProcess::input_dim() const { return map_ ? map_->input_dim() : kernel_->input_dim(); }

Status GaussianProcess::Fit(const ConstMatrixRef& X, const ConstMatrixRef& Y) {
  RequireSize("GaussianProcess::Fit X", X.cols(), input_dim(), "columns");
  RequireSize("GaussianProcess::Fit Y", Y.cols(), num_outputs_, "columns");
  RequireSize("GaussianProcess::Fit Y", Y.rows(), X.rows(), "rows (as in X)");
  RequireFinite("GaussianProcess::Fit X", X);
  RequireFinite("GaussianProcess::Fit Y", Y);
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

GaussianProcess::Workspace GaussianProcess::MakeWorkspace() const {
  Workspace workspace;
  if (function_space_) workspace.function_space = function_space_->MakeWorkspace();
  if (weight_space_) {
    workspace.features.resize(map_->dim());
    workspace.weight_space = weight_space_->MakeWorkspace();
  }
  return workspace;
}

Status GaussianProcess::Predict(const ConstVectorRef& x, VectorRef mean,
                                Workspace& workspace) const {
  if (function_space_) return function_space_->Predict(x, mean, workspace.function_space);
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
  if (function_space_) {
    return function_space_->PredictWithVariance(x, mean, latent_variance, noisy_variance,
                                                workspace.function_space);
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

Status GaussianProcess::Add(const ConstVectorRef& x, const ConstVectorRef& y) {
  if (function_space_) return function_space_->Add(x, y);
  if (!weight_space_ || x.size() != input_dim() || !x.allFinite()) return Status::kInvalidInput;
  map_->Evaluate(x, phi_);
  return weight_space_->Update(phi_, y);
}

double GaussianProcess::LogMarginalLikelihood() const {
  if (function_space_) return function_space_->LogMarginalLikelihood();
  if (!weight_space_) throw std::logic_error("GaussianProcess: not fitted");
  return weight_space_->LogMarginalLikelihood();
}

}  // namespace structgp
