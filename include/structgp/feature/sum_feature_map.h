#ifndef STRUCTGP_FEATURE_SUM_FEATURE_MAP_H_
#define STRUCTGP_FEATURE_SUM_FEATURE_MAP_H_

/// @file
/// The concatenation of feature maps phi = (phi_1, ..., phi_P): the map of the sum of their
/// kernels, k = k_1 + ... + k_P (e.g. pol + friction, eq. 43; motor + friction).
///
/// dim() = sum of the parts' dims; the blocks, shape parameters and prior variances are the
/// parts' in order, each part's shape parameters acting on its own features only (the prior
/// Jacobian is block diagonal). A block or shape parameter name that occurs in more than one
/// part gets the suffix ".<i>", i the 0-based part index ("all.0", "all.1"); unique names are
/// kept as they are.

#include <memory>
#include <string>
#include <vector>

#include "structgp/core/types.h"
#include "structgp/feature/feature_map.h"

namespace structgp {

/// Immutable after construction; Evaluate is allocation-free and thread-safe when the parts'
/// are.
class SumFeatureMap : public FeatureMap {
 public:
  /// Throws std::invalid_argument when parts is empty, holds a null pointer, or the parts do
  /// not share one input_dim().
  explicit SumFeatureMap(std::vector<std::shared_ptr<const FeatureMap>> parts);

  int num_parts() const { return static_cast<int>(parts_.size()); }
  const FeatureMap& part(int i) const { return *parts_.at(static_cast<size_t>(i)); }
  /// First feature of part i in phi.
  int part_begin(int i) const { return feature_begin_.at(static_cast<size_t>(i)); }
  /// First shape parameter of part i in the shape vector.
  int part_shape_begin(int i) const { return shape_begin_.at(static_cast<size_t>(i)); }

  int input_dim() const override { return input_dim_; }
  int dim() const override { return dim_; }
  /// Evaluates every part into its segment of phi.
  void Evaluate(const ConstVectorRef& x, VectorRef phi) const override;
  std::vector<FeatureBlock> blocks() const override { return blocks_; }

  int num_shape_parameters() const override { return num_shape_; }
  std::vector<std::string> shape_parameter_names() const override { return shape_names_; }
  Vector default_shape_parameters() const override;
  void PriorVariance(const ConstVectorRef& shape, VectorRef lambda,
                     Matrix* jacobian = nullptr) const override;

 private:
  std::vector<std::shared_ptr<const FeatureMap>> parts_;
  std::vector<int> feature_begin_;
  std::vector<int> shape_begin_;
  std::vector<FeatureBlock> blocks_;
  std::vector<std::string> shape_names_;
  int input_dim_ = 0;
  int dim_ = 0;
  int num_shape_ = 0;
};

}  // namespace structgp

#endif  // STRUCTGP_FEATURE_SUM_FEATURE_MAP_H_
