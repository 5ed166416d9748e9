#ifndef STRUCTGP_FEATURE_FEATURE_MAP_H_
#define STRUCTGP_FEATURE_FEATURE_MAP_H_

/// @file
/// An explicit finite feature map x -> phi(x) with a diagonal prior on its weights. Together
/// they define the kernel k(a, b) = sum_k lambda_k phi_k(a) phi_k(b), and a model that uses
/// them is a Bayesian linear regression (WeightSpaceGP).

#include <string>
#include <vector>

#include "structgp/core/types.h"

namespace structgp {

/// A contiguous range of features that share one prior scale and, for the structured maps,
/// one physical meaning ("inertial", "coriolis", "gravity", "friction", ...).
struct FeatureBlock {
  std::string name;
  int begin = 0;
  int size = 0;
};

/// Interface of every feature map.
///
/// Invariants a map must keep (checked for every map by structgp/testing/feature_map_battery.h):
/// - dim() and input_dim() never change after construction;
/// - Evaluate() is a pure function of x, does not allocate and is safe to call concurrently;
/// - blocks() tile [0, dim()) in order, without gaps or overlaps;
/// - the shape parameters act only through the prior variances: changing them never changes
///   phi(x). This is what lets a hyper-parameter search reuse Phi^T Phi.
class FeatureMap {
 public:
  virtual ~FeatureMap() = default;

  /// Length of the input x (3N for a robot state (q, qd, qdd) of N joints).
  virtual int input_dim() const = 0;
  /// Number of features D.
  virtual int dim() const = 0;
  /// phi(x), written into phi (size dim()). Must not allocate.
  virtual void Evaluate(const ConstVectorRef& x, VectorRef phi) const = 0;

  /// The blocks, in order. Default: a single block named "all".
  virtual std::vector<FeatureBlock> blocks() const;

  /// Number of shape parameters (e.g. log sigma of k_pol). Default 0.
  virtual int num_shape_parameters() const { return 0; }
  virtual std::vector<std::string> shape_parameter_names() const { return {}; }
  /// Default values of the shape parameters.
  virtual Vector default_shape_parameters() const { return Vector(); }

  /// Base prior variances lambda(shape) (size dim()) and, when jacobian is not null, their
  /// derivatives d lambda_k / d shape_i (dim() x num_shape_parameters()).
  /// Default: all ones, no shape parameters.
  virtual void PriorVariance(const ConstVectorRef& shape, VectorRef lambda,
                             Matrix* jacobian = nullptr) const;

  /// phi of every row of X (m x input_dim()) into the rows of Phi (resized to m x dim()).
  void EvaluateRows(const ConstMatrixRef& X, Matrix* Phi) const;
};

}  // namespace structgp

#endif  // STRUCTGP_FEATURE_FEATURE_MAP_H_
