#include "structgp/hyper/evidence.h"

#include <cmath>
#include <stdexcept>

#include "structgp/core/validate.h"

namespace structgp {

Hyperparameters ChainRule(const FeatureMap& map, const Hyperparameters& hyper,
                          const EvidenceGradient& per_feature) {
  Matrix d_lambda_d_shape;
  const Vector lambda = PriorVariance(map, hyper, &d_lambda_d_shape);
  RequireSize("ChainRule d_log_prior_variance", per_feature.d_log_prior_variance.size(),
              map.dim());
  Hyperparameters g = hyper;
  // d/d shape_i = sum_k (d/d log Lambda_k) (1 / Lambda_k) d Lambda_k / d shape_i.
  const Vector d_lambda = per_feature.d_log_prior_variance.cwiseQuotient(lambda);
  g.shape = d_lambda_d_shape.transpose() * d_lambda;
  // Lambda_k is proportional to exp(2 log_block_scale_b) for k in block b.
  const auto blocks = map.blocks();
  for (size_t b = 0; b < blocks.size(); ++b) {
    g.log_block_scale[static_cast<Eigen::Index>(b)] =
        2.0 * per_feature.d_log_prior_variance.segment(blocks[b].begin, blocks[b].size).sum();
  }
  g.log_noise_std = per_feature.d_log_noise_std;
  g.log_output_scale = per_feature.d_log_output_scale;
  return g;
}

WeightSpaceEvidence::WeightSpaceEvidence(std::shared_ptr<const FeatureMap> map,
                                         SufficientStatistics stats)
    : map_(std::move(map)), stats_(std::move(stats)) {
  if (!map_) throw std::invalid_argument("WeightSpaceEvidence: null feature map");
  RequireSize("WeightSpaceEvidence statistics", stats_.num_features(), map_->dim(), "features");
}

Status WeightSpaceEvidence::Evaluate(const Hyperparameters& hyper, double* lml,
                                     Hyperparameters* gradient) const {
  hyper.Validate(*map_, stats_.num_outputs());
  const Vector lambda = PriorVariance(*map_, hyper);
  if (!model_) {
    model_ = std::make_unique<WeightSpaceGP>(lambda, hyper.noise_variance(),
                                             stats_.num_outputs(), hyper.output_scales());
  } else {
    model_->Reset(lambda, hyper.noise_variance(), hyper.output_scales());
  }
  const Status status = model_->Fit(stats_);
  if (status != Status::kOk) return status;
  EvidenceGradient per_feature;
  const double value = model_->LogMarginalLikelihood(gradient ? &per_feature : nullptr);
  if (!std::isfinite(value)) return Status::kNotPositiveDefinite;
  *lml = value;
  if (gradient != nullptr) *gradient = ChainRule(*map_, hyper, per_feature);
  return Status::kOk;
}

}  // namespace structgp
