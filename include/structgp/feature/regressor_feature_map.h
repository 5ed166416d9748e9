#ifndef STRUCTGP_FEATURE_REGRESSOR_FEATURE_MAP_H_
#define STRUCTGP_FEATURE_REGRESSOR_FEATURE_MAP_H_

/// @file
/// One row of a regressor (RegressorMap, N x P) as P features: phi(x) = row j of Psi(x). Output
/// j's functions under this map are exactly those the regressor model gives output j (theta
/// free for that output alone), so code that works on one output's features (the diagnosis:
/// what does the model leave unexplained on joint j, which effect lies outside its span) can
/// take a regressor model through it, one joint at a time. Used for spans and residuals, not
/// for prediction (the outputs' shared parameters are not shared here).
///
/// Prior: the regressor's prior_std squared per column (prior_mean is not used). Blocks: the
/// regressor's.
///
/// Evaluate keeps the regressor's scratch (KDL solvers for a rigid-body chain) per thread: the
/// first call on a thread allocates it, later calls on that thread do not.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "structgp/feature/feature_map.h"
#include "structgp/feature/regressor_map.h"

namespace structgp {

class RegressorFeatureMap final : public FeatureMap {
 public:
  /// Row `row` (0-based) of the regressor. Throws std::invalid_argument for a null regressor
  /// or a row out of range.
  RegressorFeatureMap(std::shared_ptr<const RegressorMap> regressor, int row);

  const RegressorMap& regressor() const { return *regressor_; }
  int input_dim() const override { return regressor_->input_dim(); }
  int row() const { return row_; }
  int dim() const override { return regressor_->dim(); }
  void Evaluate(const ConstVectorRef& x, VectorRef phi) const override;
  std::vector<FeatureBlock> blocks() const override;
  void PriorVariance(const ConstVectorRef& shape, VectorRef lambda,
                     Matrix* jacobian = nullptr) const override;

 private:
  std::shared_ptr<const RegressorMap> regressor_;
  int row_;
  std::uint64_t id_;  // tells this map's per-thread scratch from another's
};

}  // namespace structgp

#endif  // STRUCTGP_FEATURE_REGRESSOR_FEATURE_MAP_H_
