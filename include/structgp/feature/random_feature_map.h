#ifndef STRUCTGP_FEATURE_RANDOM_FEATURE_MAP_H_
#define STRUCTGP_FEATURE_RANDOM_FEATURE_MAP_H_

/// @file
/// A generic map of random cosine features, for tests and benchmarks of the models: any input
/// dimension, any number of features and blocks, a non-trivial shape parameter.
///
///     phi_k(x) = cos(w_k^T x + b_k),   k = 0..D-1,
///     w_k ~ N(0, I) (input_dim entries),  b_k ~ U[0, 2 pi),
///     lambda_k = exp(-exp(log_decay) * k / D),
///
/// with one shape parameter "log_decay" (default 0). The draws come from std::mt19937_64
/// seeded with `seed` and are turned into uniform and normal numbers by this library's own
/// transforms (53-bit uniforms, Box-Muller), so a seed gives the same map on every platform.
/// Blocks "b0", "b1", ...: block i covers [floor(i D / B), floor((i+1) D / B)).

#include <cstdint>
#include <string>
#include <vector>

#include "structgp/core/types.h"
#include "structgp/feature/feature_map.h"

namespace structgp {

/// Immutable after construction; Evaluate is allocation-free and thread-safe.
class RandomFeatureMap : public FeatureMap {
 public:
  /// Throws std::invalid_argument unless input_dim >= 1, num_features >= 1 and
  /// 1 <= num_blocks <= num_features.
  RandomFeatureMap(int input_dim, int num_features, int num_blocks, std::uint64_t seed);

  int input_dim() const override { return static_cast<int>(frequencies_.cols()); }
  int dim() const override { return static_cast<int>(frequencies_.rows()); }
  /// O(D input_dim) flops and D cosines. Throws std::invalid_argument on a size mismatch.
  void Evaluate(const ConstVectorRef& x, VectorRef phi) const override;
  std::vector<FeatureBlock> blocks() const override { return blocks_; }

  int num_shape_parameters() const override { return 1; }
  std::vector<std::string> shape_parameter_names() const override { return {"log_decay"}; }
  Vector default_shape_parameters() const override { return Vector::Zero(1); }
  /// lambda_k = exp(-exp(log_decay) k / D); d lambda_k / d log_decay = -exp(log_decay) k/D
  /// lambda_k.
  void PriorVariance(const ConstVectorRef& shape, VectorRef lambda,
                     Matrix* jacobian = nullptr) const override;

  /// w_k^T as rows (D x input_dim).
  const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>& frequencies()
      const {
    return frequencies_;
  }
  /// b (size D), in [0, 2 pi).
  const Vector& phases() const { return phases_; }
  std::uint64_t seed() const { return seed_; }

 private:
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> frequencies_;
  Vector phases_;
  std::vector<FeatureBlock> blocks_;
  std::uint64_t seed_;
};

}  // namespace structgp

#endif  // STRUCTGP_FEATURE_RANDOM_FEATURE_MAP_H_
