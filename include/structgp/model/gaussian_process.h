#ifndef STRUCTGP_MODEL_GAUSSIAN_PROCESS_H_
#define STRUCTGP_MODEL_GAUSSIAN_PROCESS_H_

/// @file
/// A Gaussian process on robot states x, in whichever form is cheaper: the weight-space form
/// (WeightSpaceGP on phi(x), O(D^3) batch, O(D^2) per sample) when the kernel has a finite
/// feature map with D <= m, the function-space form (KernelGP, O(m^3) batch, O(m^2) per
/// sample) otherwise or when the kernel has no finite map. Both forms give the same
/// posterior; the choice can be forced.

#include <memory>

#include "structgp/core/status.h"
#include "structgp/core/types.h"
#include "structgp/feature/feature_map.h"
#include "structgp/hyper/hyperparameters.h"
#include "structgp/kernel/kernel.h"
#include "structgp/model/kernel_gp.h"
#include "structgp/model/weight_space_gp.h"

namespace structgp {

enum class Form {
  kAuto,           ///< weight space when D <= m (number of training samples), else function space
  kWeightSpace,    ///< always the feature form (requires a feature map)
  kFunctionSpace,  ///< always the kernel form
};

/// "auto", "weight_space", "function_space".
const char* ToString(Form form);

class GaussianProcess {
 public:
  /// A model whose kernel is the feature map with the prior given by hyper.
  GaussianProcess(std::shared_ptr<const FeatureMap> map, const Hyperparameters& hyper,
                  int num_outputs, Form form = Form::kAuto);
  /// A model with a kernel that has no finite map (rbf, rbfs): always the function space.
  GaussianProcess(const Kernel& kernel, double noise_variance, int num_outputs,
                  const Vector& output_scales = Vector());

  /// Fits X (m x input_dim) and Y (m x P); with Form::kAuto picks the form from D and m.
  /// Throws std::invalid_argument on bad sizes or NaN/Inf (naming row and column).
  Status Fit(const ConstMatrixRef& X, const ConstMatrixRef& Y);

  /// The form in use (never kAuto once fitted; before Fit, the requested form).
  Form form() const { return active_; }
  int input_dim() const;
  int num_outputs() const { return num_outputs_; }

  Status Predict(const ConstVectorRef& x, VectorRef mean) const;
  Status PredictWithVariance(const ConstVectorRef& x, VectorRef mean, VectorRef latent_variance,
                             VectorRef noisy_variance) const;
  /// Adds one sample online (O(D^2) or O(m^2)); the function space needs Reserve'd room.
  Status Add(const ConstVectorRef& x, const ConstVectorRef& y);

  double LogMarginalLikelihood() const;

  /// The underlying models; exactly one is non-null after Fit.
  const WeightSpaceGP* weight_space() const { return weight_space_.get(); }
  const KernelGP* function_space() const { return function_space_.get(); }
  KernelGP* mutable_function_space() { return function_space_.get(); }

 private:
  std::shared_ptr<const FeatureMap> map_;  // null for a kernel-only model
  Hyperparameters hyper_;
  std::unique_ptr<Kernel> kernel_;  // the kernel of the function-space form
  int num_outputs_;
  Form requested_;
  Form active_;
  std::unique_ptr<WeightSpaceGP> weight_space_;
  std::unique_ptr<KernelGP> function_space_;
  mutable Vector phi_;  // feature scratch (D)
};

}  // namespace structgp

#endif  // STRUCTGP_MODEL_GAUSSIAN_PROCESS_H_
