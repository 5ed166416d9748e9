#include "structgp/model/gaussian_process.h"

#include <stdexcept>

#include "structgp/core/validate.h"
#include "structgp/kernel/feature_kernel.h"

namespace structgp {

const char* ToString(Form form) {
  switch (form) {
    case Form::kAuto: return "auto";
    case Form::kWeightSpace: return "weight_space";
    case Form::kFunctionSpace: return "function_space";
  }
  return "unknown";
}

GaussianProcess::GaussianProcess(std::shared_ptr<const FeatureMap> map,
                                 const Hyperparameters& hyper, int num_outputs, Form form)
    : map_(std::move(map)), hyper_(hyper), num_outputs_(num_outputs), requested_(form),
      active_(form) {
  if (!map_) throw std::invalid_argument("GaussianProcess: null feature map");
  hyper_.Validate(*map_, num_outputs);
  phi_.resize(map_->dim());
}

GaussianProcess::GaussianProcess(const Kernel& kernel, double noise_variance, int num_outputs,
                                 const Vector& output_scales)
    : kernel_(kernel.Clone()), num_outputs_(num_outputs), requested_(Form::kFunctionSpace),
      active_(Form::kFunctionSpace) {
  function_space_ = std::make_unique<KernelGP>(*kernel_, noise_variance, num_outputs,
                                               output_scales);
}

int GaussianProcess::input_dim() const { return map_ ? map_->input_dim() : kernel_->input_dim(); }

Status GaussianProcess::Fit(const ConstMatrixRef& X, const ConstMatrixRef& Y) {
  RequireSize("GaussianProcess::Fit X", X.cols(), input_dim(), "columns");
  RequireSize("GaussianProcess::Fit Y", Y.cols(), num_outputs_, "columns");
  RequireSize("GaussianProcess::Fit Y", Y.rows(), X.rows(), "rows (as in X)");
  RequireFinite("GaussianProcess::Fit X", X);
  RequireFinite("GaussianProcess::Fit Y", Y);
  if (!map_) return function_space_->Fit(X, Y);

  Form form = requested_;
  if (form == Form::kAuto) {
    form = map_->dim() <= X.rows() ? Form::kWeightSpace : Form::kFunctionSpace;
  }
  if (form == Form::kWeightSpace) {
    auto model = std::make_unique<WeightSpaceGP>(PriorVariance(*map_, hyper_),
                                                 hyper_.noise_variance(), num_outputs_,
                                                 hyper_.output_scales());
    // Stream the features in chunks: memory O(chunk * D), never O(m * D).
    constexpr Eigen::Index kChunk = 1024;
    SufficientStatistics stats(map_->dim(), num_outputs_);
    Matrix Phi;
    for (Eigen::Index begin = 0; begin < X.rows(); begin += kChunk) {
      const Eigen::Index rows = std::min(kChunk, X.rows() - begin);
      map_->EvaluateRows(X.middleRows(begin, rows), &Phi);
      stats.Accumulate(Phi, Y.middleRows(begin, rows));
    }
    const Status status = model->Fit(stats);
    if (status != Status::kOk) return status;
    weight_space_ = std::move(model);
    function_space_.reset();
  } else {
    kernel_ = std::make_unique<FeatureKernel>(map_, hyper_);
    auto model = std::make_unique<KernelGP>(*kernel_, hyper_.noise_variance(), num_outputs_,
                                            hyper_.output_scales());
    const Status status = model->Fit(X, Y);
    if (status != Status::kOk) return status;
    function_space_ = std::move(model);
    weight_space_.reset();
  }
  active_ = form;
  return Status::kOk;
}

Status GaussianProcess::Predict(const ConstVectorRef& x, VectorRef mean) const {
  if (function_space_) return function_space_->Predict(x, mean);
  if (!weight_space_ || x.size() != input_dim() || !x.allFinite()) return Status::kInvalidInput;
  map_->Evaluate(x, phi_);
  return weight_space_->Predict(phi_, mean);
}

Status GaussianProcess::PredictWithVariance(const ConstVectorRef& x, VectorRef mean,
                                            VectorRef latent_variance,
                                            VectorRef noisy_variance) const {
  if (function_space_) {
    return function_space_->PredictWithVariance(x, mean, latent_variance, noisy_variance);
  }
  if (!weight_space_ || x.size() != input_dim() || !x.allFinite()) return Status::kInvalidInput;
  map_->Evaluate(x, phi_);
  return weight_space_->PredictWithVariance(phi_, mean, latent_variance, noisy_variance);
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
