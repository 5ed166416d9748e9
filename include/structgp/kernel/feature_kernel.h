#ifndef STRUCTGP_KERNEL_FEATURE_KERNEL_H_
#define STRUCTGP_KERNEL_FEATURE_KERNEL_H_

/// @file
/// The kernel of an explicit feature map with its prior,
///     k(a, b) = sum_k Lambda_k phi_k(a) phi_k(b),
/// Lambda = PriorVariance(map, hyper) (size D). With it, KernelGP is the function-space twin
/// of WeightSpaceGP: same predictions and likelihood, at O(m^3) instead of O(D^3).

#include <memory>
#include <string>
#include <vector>

#include "structgp/core/types.h"
#include "structgp/feature/feature_map.h"
#include "structgp/feature/feature_hyperparameters.h"
#include "structgp/kernel/kernel.h"

namespace structgp {

/// Parameters, in this order: the map's shape parameters (names from
/// FeatureMap::shape_parameter_names()), then one log block scale per block of the map
/// (named "log_scale_<block name>"). The noise and output scales of the Hyperparameters are
/// not kernel parameters (KernelGP holds them) and are kept only as given.
///
/// Gradient by the chain rule: d k / d shape_s = sum_k (d Lambda_k / d shape_s) phi_k(a) phi_k(b)
/// and d k / d log_block_scale_b = 2 sum_{k in b} Lambda_k phi_k(a) phi_k(b).
///
/// Evaluate and Gradient cost two feature evaluations and O(D (1 + num_shape_parameters)).
/// Their scratch (three vectors of D) is on the stack for D <= 2048, so they do not allocate
/// and are safe for concurrent calls; a wider map allocates its scratch in each call.
class FeatureKernel : public Kernel {
 public:
  /// map: not null, shared (feature maps are immutable). hyper: validated against the map
  /// (its log_output_scale may have any size). Throws std::invalid_argument on bad input.
  FeatureKernel(std::shared_ptr<const FeatureMap> map, const Hyperparameters& hyper);

  int input_dim() const override { return map_->input_dim(); }
  double Evaluate(const ConstVectorRef& a, const ConstVectorRef& b) const override;

  int num_parameters() const override;
  std::vector<std::string> parameter_names() const override;
  Vector parameters() const override;
  std::unique_ptr<Kernel> WithParameters(const ConstVectorRef& theta) const override;
  void Gradient(const ConstVectorRef& a, const ConstVectorRef& b, VectorRef dk) const override;
  std::unique_ptr<Kernel> Clone() const override;

  const FeatureMap& map() const { return *map_; }
  const std::shared_ptr<const FeatureMap>& shared_map() const { return map_; }
  /// The hyper-parameters the kernel was built with (shape and log_block_scale: its
  /// parameters()).
  const Hyperparameters& hyperparameters() const { return hyper_; }
  /// Lambda (size D).
  const Vector& prior_variance() const { return lambda_; }

 private:
  // Sets the parameters of a kernel not yet shared (WithParameters' copy).
  void AssignParameters(const ConstVectorRef& theta);
  // Recomputes Lambda and d Lambda / d shape from hyper_.
  void UpdatePrior();

  std::shared_ptr<const FeatureMap> map_;
  Hyperparameters hyper_;
  std::vector<FeatureBlock> blocks_;
  Vector lambda_;            // Lambda (D)
  Matrix d_lambda_d_shape_;  // D x num_shape_parameters
};

}  // namespace structgp

#endif  // STRUCTGP_KERNEL_FEATURE_KERNEL_H_
