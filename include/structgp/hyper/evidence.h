#ifndef STRUCTGP_HYPER_EVIDENCE_H_
#define STRUCTGP_HYPER_EVIDENCE_H_

/// @file
/// The log marginal likelihood (evidence) of a feature-map model as a function of its
/// Hyperparameters, with its gradient, evaluated on cached sufficient statistics: the data
/// are never touched again, because every hyper-parameter acts through the prior variances,
/// the noise or the output scales (Phi^T Phi does not change).

#include <memory>

#include "structgp/core/status.h"
#include "structgp/feature/feature_map.h"
#include "structgp/feature/feature_hyperparameters.h"
#include "structgp/model/sufficient_statistics.h"
#include "structgp/model/weight_space_gp.h"

namespace structgp {

/// d log p(Y) / d hyper-parameters, in the layout of Hyperparameters (each field holds the
/// derivative with respect to the field of the same name), from the per-feature gradient of
/// a WeightSpaceGP by the chain rule.
Hyperparameters ChainRule(const FeatureMap& map, const Hyperparameters& hyper,
                          const EvidenceGradient& per_feature);

class WeightSpaceEvidence {
 public:
  /// Keeps the map and the statistics (copied). Throws std::invalid_argument when the
  /// statistics do not match the map's dimension.
  WeightSpaceEvidence(std::shared_ptr<const FeatureMap> map, SufficientStatistics stats);

  /// log p(Y | hyper) into *lml and, when gradient is not null, its derivatives. O(D^3).
  /// kNotPositiveDefinite when the posterior precision cannot be factorised, or when the prior
  /// variances or noise are outside what WeightSpaceGP represents (kMaxPriorToNoiseRatio; e.g.
  /// an extreme shape parameter): outputs untouched, no exception.
  Status Evaluate(const Hyperparameters& hyper, double* lml,
                  Hyperparameters* gradient = nullptr) const;

  const FeatureMap& map() const { return *map_; }
  const SufficientStatistics& statistics() const { return stats_; }

 private:
  std::shared_ptr<const FeatureMap> map_;
  SufficientStatistics stats_;
  mutable std::unique_ptr<WeightSpaceGP> model_;  // reused across evaluations
};

/// A quick and robust evidence fit of the noise level and output scales only (the prior shape
/// and block scales stay as given): for each sigma_n, the optimal output scales have the closed
/// form s_j^2 = y_j^T C^{-1} y_j / m, and log sigma_n is found by golden-section search on
/// [log_noise_min, log_noise_max]. About 60 evaluations of O(D^3). Returns the hyper-parameters
/// at the optimum (start's other fields unchanged); throws std::runtime_error when no sigma_n
/// in the range gives a factorisable posterior.
Hyperparameters ProfileNoiseAndScales(const WeightSpaceEvidence& evidence,
                                      const Hyperparameters& start, double log_noise_min = -9.0,
                                      double log_noise_max = 1.0);

}  // namespace structgp

#endif  // STRUCTGP_HYPER_EVIDENCE_H_
