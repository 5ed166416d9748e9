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
#include "structgp/hyper/hyperparameters.h"
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
  /// kNotPositiveDefinite when the posterior precision cannot be factorised (outputs untouched).
  Status Evaluate(const Hyperparameters& hyper, double* lml,
                  Hyperparameters* gradient = nullptr) const;

  const FeatureMap& map() const { return *map_; }
  const SufficientStatistics& statistics() const { return stats_; }

 private:
  std::shared_ptr<const FeatureMap> map_;
  SufficientStatistics stats_;
  mutable std::unique_ptr<WeightSpaceGP> model_;  // reused across evaluations
};

}  // namespace structgp

#endif  // STRUCTGP_HYPER_EVIDENCE_H_
