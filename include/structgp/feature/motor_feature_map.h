#ifndef STRUCTGP_FEATURE_MOTOR_FEATURE_MAP_H_
#define STRUCTGP_FEATURE_MOTOR_FEATURE_MAP_H_

/// @file
/// The motor baseline of the paper (eq. 54): tau_n = c1 qdd_n + c2 qd_n, a linear model in the
/// joint's own acceleration and velocity.
///
/// Input x = (q, qd, qdd), input_dim() = 3N. Features, in order,
///     acceleration@1, velocity@1, ..., acceleration@N, velocity@N   (qdd_n, qd_n)
/// in one block "motor", unit prior variance, no shape parameter. In a model whose outputs
/// share the feature vector, the coefficients (c1, c2) of joint j are the weights of
/// acceleration@j and velocity@j for output j.

#include <string>
#include <vector>

#include "structgp/core/types.h"
#include "structgp/feature/feature_map.h"

namespace structgp {

/// Immutable after construction; Evaluate is allocation-free and thread-safe.
class MotorFeatureMap : public FeatureMap {
 public:
  /// Throws std::invalid_argument unless num_joints >= 1.
  explicit MotorFeatureMap(int num_joints);

  int num_joints() const { return num_joints_; }

  int input_dim() const override { return 3 * num_joints_; }
  /// 2N.
  int dim() const override { return 2 * num_joints_; }
  /// Throws std::invalid_argument on a size mismatch.
  void Evaluate(const ConstVectorRef& x, VectorRef phi) const override;
  /// One block, "motor".
  std::vector<FeatureBlock> blocks() const override;

  /// Index of qdd_joint (0-based joint) in phi; velocity_index likewise for qd_joint.
  int acceleration_index(int joint) const;
  int velocity_index(int joint) const;
  /// "acceleration@1", "velocity@1", ..., in feature order.
  std::vector<std::string> feature_names() const;

 private:
  int num_joints_;
};

}  // namespace structgp

#endif  // STRUCTGP_FEATURE_MOTOR_FEATURE_MAP_H_
