#include "online/learner_form.h"

#include <algorithm>
#include <utility>

#include "model/factor_kernels.h"

namespace structgp {
namespace online_detail {
namespace {

// Below this scale the statistics are multiplied out, far from underflow of any entry.
constexpr double kMinStatisticsScale = 1e-100;

}  // namespace

FeatureForm::FeatureForm(std::shared_ptr<const FeatureMap> map, int num_outputs,
                         Vector variance_scale)
    : map_(std::move(map)), variance_scale_(std::move(variance_scale)) {
  input_dim_ = map_->input_dim();
  num_outputs_ = num_outputs;
  features_ = map_->dim();
  model_outputs_ = num_outputs;
  columns_ = 1;
  column_weights_ = Vector::Ones(1);
  published_rows_ = features_;
  published_cols_ = num_outputs;
}

FormScratch FeatureForm::MakeScratch() const {
  FormScratch s;
  s.phi.setZero(features_);
  s.f1.setZero(features_);
  return s;
}

void FeatureForm::Encode(const ConstVectorRef& x, const ConstVectorRef& tau, FormScratch& s,
                         MatrixRef phi, MatrixRef y) const {
  map_->Evaluate(x, s.phi);
  phi.col(0) = s.phi;
  y.col(0) = tau;
}

void FeatureForm::Predict(const ConstVectorRef& x, const Matrix& published, const Matrix* factor,
                          FormScratch& s, VectorRef mean, VectorRef variance) const {
  map_->Evaluate(x, s.phi);
  mean.noalias() = published.transpose() * s.phi;
  if (factor == nullptr) return;
  internal::UpperTransposeTimes(factor->data(), features_, features_, s.phi.data(), nullptr,
                                s.f1.data(), nullptr);
  variance = s.f1.squaredNorm() * variance_scale_;
}

RegressorForm::RegressorForm(std::shared_ptr<const RegressorMap> map, Vector prior_mean,
                             Vector noise_variance, double reference_noise,
                             const RegressorStatistics* initial)
    : map_(std::move(map)),
      prior_mean_(std::move(prior_mean)),
      noise_variance_(std::move(noise_variance)),
      reference_noise_(reference_noise) {
  input_dim_ = map_->input_dim();
  num_outputs_ = map_->num_outputs();
  features_ = map_->dim();
  model_outputs_ = 1;
  columns_ = num_outputs_;
  column_weights_ = reference_noise_ * noise_variance_.cwiseInverse();
  published_rows_ = features_;
  published_cols_ = 1;
  initial_ = initial != nullptr ? *initial : RegressorStatistics(features_, num_outputs_);
  ResetStatistics();
}

FormScratch RegressorForm::MakeScratch() const {
  FormScratch s;
  s.psi.setZero(num_outputs_, features_);
  s.psi_t.setZero(features_, num_outputs_);
  // f1 also holds Psi mu (N) in Encode.
  s.f1.setZero(std::max(features_, num_outputs_));
  s.f2.setZero(features_);
  s.map = map_->MakeScratch();
  return s;
}

void RegressorForm::Encode(const ConstVectorRef& x, const ConstVectorRef& tau, FormScratch& s,
                           MatrixRef phi, MatrixRef y) const {
  map_->Evaluate(x, s.psi, s.map.get());
  phi = s.psi.transpose();
  s.f1.head(num_outputs_).noalias() = s.psi * prior_mean_;
  y.row(0) = tau.transpose() - s.f1.head(num_outputs_).transpose();
}

void RegressorForm::Publish(const Matrix& W, Matrix& slot) const { slot = W + prior_mean_; }

void RegressorForm::Predict(const ConstVectorRef& x, const Matrix& published,
                            const Matrix* factor, FormScratch& s, VectorRef mean,
                            VectorRef variance) const {
  map_->Evaluate(x, s.psi, s.map.get());
  mean.noalias() = s.psi * published.col(0);
  if (factor == nullptr) return;
  s.psi_t = s.psi.transpose();
  const int N = num_outputs_, P = features_;
  for (int j = 0; j < N; j += 2) {
    const bool two = j + 1 < N;
    internal::UpperTransposeTimes(factor->data(), P, P, s.psi_t.col(j).data(),
                                  two ? s.psi_t.col(j + 1).data() : nullptr, s.f1.data(),
                                  two ? s.f2.data() : nullptr);
    variance[j] = reference_noise_ * s.f1.squaredNorm();
    if (two) variance[j + 1] = reference_noise_ * s.f2.squaredNorm();
  }
}

void RegressorForm::Account(const ConstVectorRef& phi, double y, int column, double forgetting,
                            double weight) {
  if (forgetting != 1.0) {
    stats_scale_ *= forgetting;
    if (stats_scale_ < kMinStatisticsScale) Renormalise();
  }
  if (weight == 0.0) return;
  // The sample's own weight: the column weight times what forgetting has left of it.
  const double v = weight / column_weights_[column] / stats_scale_;
  const double tau = y + phi.dot(prior_mean_);
  gram_[static_cast<size_t>(column)].selfadjointView<Eigen::Lower>().rankUpdate(phi, v);
  cross_.col(column) += (v * tau) * phi;
  y_squared_[column] += v * tau * tau;
  if (column == 0) count_ += v;
}

void RegressorForm::Renormalise() {
  for (Matrix& G : gram_) G *= stats_scale_;
  cross_ *= stats_scale_;
  y_squared_ *= stats_scale_;
  count_ *= stats_scale_;
  stats_scale_ = 1.0;
}

void RegressorForm::ResetStatistics() {
  gram_ = initial_.gram;  // equal sizes after the first call: no allocation
  cross_ = initial_.cross;
  y_squared_ = initial_.y_squared;
  count_ = initial_.count;
  stats_scale_ = 1.0;
}

RegressorStatistics RegressorForm::Statistics() const {
  RegressorStatistics out(features_, num_outputs_);
  for (int j = 0; j < num_outputs_; ++j) {
    Matrix G = stats_scale_ * gram_[static_cast<size_t>(j)];
    G.triangularView<Eigen::StrictlyUpper>() = G.transpose();
    out.gram[static_cast<size_t>(j)] = G;
  }
  out.cross = stats_scale_ * cross_;
  out.y_squared = stats_scale_ * y_squared_;
  out.count = stats_scale_ * count_;
  return out;
}

}  // namespace online_detail
}  // namespace structgp
