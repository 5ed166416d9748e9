#ifndef STRUCTGP_SRC_ONLINE_LEARNER_FORM_H_
#define STRUCTGP_SRC_ONLINE_LEARNER_FORM_H_

// How OnlineLearner turns samples into the columns of its WeightSpaceGP and how the control
// thread predicts from what the learner publishes. Two forms share the learner's queue, triple
// buffers, window and forgetting logic (online_learner.cc):
// - the feature form: one column phi(x) per sample, P outputs (the torques), weight 1;
// - the regressor form: one column per joint, psi_j(x)^T (row j of Psi(x)), one output (the
//   torque minus the prior mean's prediction, psi_j mu), weight sigma_ref^2 / sigma_j^2; the
//   model is then the posterior of theta - mu, and the published weights are theta = mu + w.
// The scratch of each thread is its own FormScratch (MakeScratch), so Encode (learner) and
// Predict (control thread) never share memory.

#include <memory>
#include <vector>

#include "structgp/core/types.h"
#include "structgp/feature/feature_map.h"
#include "structgp/feature/regressor_map.h"
#include "structgp/model/regressor_gp.h"

namespace structgp {
namespace online_detail {

struct FormScratch {
  Vector phi;   // D (feature form)
  Matrix psi;   // N x P (regressor form)
  Matrix psi_t; // P x N: the rows of psi as contiguous columns
  Vector f1, f2;
  std::unique_ptr<RegressorMap::Scratch> map;
};

class LearnerForm {
 public:
  virtual ~LearnerForm() = default;
  int input_dim() const { return input_dim_; }
  int num_outputs() const { return num_outputs_; }
  int features() const { return features_; }
  int model_outputs() const { return model_outputs_; }
  int columns() const { return columns_; }
  // Weight of column c of every sample (size columns()).
  const Vector& column_weights() const { return column_weights_; }

  virtual FormScratch MakeScratch() const = 0;
  // The columns of sample (x, tau): phi (features x columns), y (model_outputs x columns).
  // Allocation-free.
  virtual void Encode(const ConstVectorRef& x, const ConstVectorRef& tau, FormScratch& s,
                      MatrixRef phi, MatrixRef y) const = 0;
  // What Predict reads from the model's W (features x model_outputs): slot has its size.
  virtual void Publish(const Matrix& W, Matrix& slot) const = 0;
  // Mean (num_outputs) at x, and the latent variance when factor is not null. Allocation-free.
  virtual void Predict(const ConstVectorRef& x, const Matrix& published, const Matrix* factor,
                       FormScratch& s, VectorRef mean, VectorRef variance) const = 0;
  // Published weights' shape.
  int published_rows() const { return published_rows_; }
  int published_cols() const { return published_cols_; }

 protected:
  int input_dim_ = 0, num_outputs_ = 0, features_ = 0, model_outputs_ = 0, columns_ = 1;
  int published_rows_ = 0, published_cols_ = 0;
  Vector column_weights_;
};

class FeatureForm final : public LearnerForm {
 public:
  // variance_scale: sigma_n^2 s_j^2 (P).
  FeatureForm(std::shared_ptr<const FeatureMap> map, int num_outputs, Vector variance_scale);
  FormScratch MakeScratch() const override;
  void Encode(const ConstVectorRef& x, const ConstVectorRef& tau, FormScratch& s, MatrixRef phi,
              MatrixRef y) const override;
  void Publish(const Matrix& W, Matrix& slot) const override { slot = W; }
  void Predict(const ConstVectorRef& x, const Matrix& published, const Matrix* factor,
               FormScratch& s, VectorRef mean, VectorRef variance) const override;

 private:
  std::shared_ptr<const FeatureMap> map_;
  Vector variance_scale_;
};

// The regressor form, with the per-joint statistics of the samples in the model (forgotten
// and removed as the model's), so that the posterior can be handed back as a RegressorGP.
class RegressorForm final : public LearnerForm {
 public:
  // noise_variance: sigma_j^2 (N); reference_noise: sigma_ref^2 (the model's noise variance);
  // initial: statistics the model already holds (empty: none).
  RegressorForm(std::shared_ptr<const RegressorMap> map, Vector prior_mean, Vector noise_variance,
                double reference_noise, const RegressorStatistics* initial);
  FormScratch MakeScratch() const override;
  void Encode(const ConstVectorRef& x, const ConstVectorRef& tau, FormScratch& s, MatrixRef phi,
              MatrixRef y) const override;
  void Publish(const Matrix& W, Matrix& slot) const override;
  void Predict(const ConstVectorRef& x, const Matrix& published, const Matrix* factor,
               FormScratch& s, VectorRef mean, VectorRef variance) const override;

  const RegressorMap& map() const { return *map_; }
  const Vector& prior_mean() const { return prior_mean_; }
  const Vector& noise_variance() const { return noise_variance_; }

  // Learner thread: the statistics follow every applied step of column c (model target y,
  // forgetting, weight > 0 added, < 0 removed, 0 forgetting only). Allocation-free.
  void Account(const ConstVectorRef& phi, double y, int column, double forgetting, double weight);
  // Back to the statistics given at construction (window rebuilds).
  void ResetStatistics();
  // The statistics now (allocates).
  RegressorStatistics Statistics() const;

 private:
  void Renormalise();

  std::shared_ptr<const RegressorMap> map_;
  Vector prior_mean_;
  Vector noise_variance_;
  double reference_noise_;
  // Statistics in units of stats_scale_ (forgetting multiplies the scale only): the true
  // G_j is stats_scale_ * gram_[j] (lower triangle kept), and so on.
  std::vector<Matrix> gram_;
  Matrix cross_;
  Vector y_squared_;
  double count_ = 0.0;
  double stats_scale_ = 1.0;
  RegressorStatistics initial_;
};

}  // namespace online_detail
}  // namespace structgp

#endif  // STRUCTGP_SRC_ONLINE_LEARNER_FORM_H_
