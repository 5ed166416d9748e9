#include "structgp/hyper/evidence.h"

#include <cmath>
#include <algorithm>
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
  ValidateHyperparameters(hyper, *map_, stats_.num_outputs());
  const Vector lambda = PriorVariance(*map_, hyper);
  // Hyper-parameters far out (a shape parameter whose prior variances underflow, a noise of
  // 1e-300) give a prior the model cannot represent (weight_space_gp.h): an ordinary failed
  // evaluation, so that an optimiser backs off.
  if (!lambda.allFinite() || !PriorToNoiseRatioOk(lambda, hyper.noise_variance())) {
    return Status::kNotPositiveDefinite;
  }
  if (!model_) {
    model_ = std::make_unique<WeightSpaceGP>(lambda, hyper.noise_variance(),
                                             stats_.num_outputs(), hyper.output_scales());
  } else {
    model_->Reset(lambda, hyper.noise_variance(), hyper.output_scales());
  }
  // No jitter: the evidence of a jittered model is not the evidence of these hyper-parameters.
  const Status status = model_->Fit(stats_, FitJitter::kNone);
  if (status != Status::kOk) return status;
  EvidenceGradient per_feature;
  const double value = model_->LogMarginalLikelihood(gradient ? &per_feature : nullptr);
  if (!std::isfinite(value)) return Status::kNotPositiveDefinite;
  *lml = value;
  if (gradient != nullptr) *gradient = ChainRule(*map_, hyper, per_feature);
  return Status::kOk;
}

Hyperparameters ProfileNoiseAndScales(const WeightSpaceEvidence& evidence,
                                      const Hyperparameters& start, double log_noise_min,
                                      double log_noise_max) {
  const double m = evidence.statistics().count;
  // Profile: at fixed sigma_n, with unit scales, d log p / d log s_j = quad_j - m = 0 gives
  // s_j^2 = quad_j / m, where quad_j = y_j^T C^{-1} y_j (unit scale) is the gradient + m.
  auto profiled = [&](double log_noise, Hyperparameters* h) {
    h->log_noise_std = log_noise;
    h->log_output_scale.setZero();
    double value = 0.0;
    Hyperparameters g;
    if (evidence.Evaluate(*h, &value, &g) != Status::kOk) return -HUGE_VAL;
    for (Eigen::Index j = 0; j < h->log_output_scale.size(); ++j) {
      const double quad = g.log_output_scale[j] + m;
      h->log_output_scale[j] = 0.5 * std::log(std::max(quad / m, 1e-300));
    }
    if (evidence.Evaluate(*h, &value) != Status::kOk) return -HUGE_VAL;
    return value;
  };
  Hyperparameters h = start;
  const double golden = 0.6180339887498949;
  double a = log_noise_min, b = log_noise_max;
  double c = b - golden * (b - a), d = a + golden * (b - a);
  double fc = profiled(c, &h), fd = profiled(d, &h);
  for (int it = 0; it < 60 && b - a > 1e-4; ++it) {
    if (fc >= fd) {
      b = d, d = c, fd = fc;
      c = b - golden * (b - a);
      fc = profiled(c, &h);
    } else {
      a = c, c = d, fc = fd;
      d = a + golden * (b - a);
      fd = profiled(d, &h);
    }
  }
  const double best = fc >= fd ? c : d;
  if (!std::isfinite(profiled(best, &h))) {
    throw std::runtime_error("ProfileNoiseAndScales: no noise level in the range gives a "
                             "positive definite posterior");
  }
  return h;
}

}  // namespace structgp
