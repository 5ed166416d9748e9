#ifndef STRUCTGP_KERNEL_LEADING_INPUTS_KERNEL_H_
#define STRUCTGP_KERNEL_LEADING_INPUTS_KERNEL_H_

/// @file
/// A kernel on the leading inputs of a longer input: k(a, b) = inner(a_1..d, b_1..d) for inputs
/// of input_dim >= d = inner.input_dim(). A model with a time-dependent effect (drift) takes
/// (q, qd, qdd, t); its base kernel sees the state alone. The parameters are the inner kernel's.

#include <memory>
#include <string>
#include <vector>

#include "structgp/kernel/kernel.h"

namespace structgp {

class LeadingInputsKernel : public Kernel {
 public:
  /// Copies (Clone) inner. Throws std::invalid_argument unless input_dim >= inner.input_dim().
  LeadingInputsKernel(const Kernel& inner, int input_dim);

  int input_dim() const override { return input_dim_; }
  double Evaluate(const ConstVectorRef& a, const ConstVectorRef& b) const override;
  int num_parameters() const override { return inner_->num_parameters(); }
  std::vector<std::string> parameter_names() const override { return inner_->parameter_names(); }
  Vector parameters() const override { return inner_->parameters(); }
  std::unique_ptr<Kernel> WithParameters(const ConstVectorRef& theta) const override;
  void Gradient(const ConstVectorRef& a, const ConstVectorRef& b, VectorRef dk) const override;
  std::unique_ptr<Kernel> Clone() const override;

  const Kernel& inner() const { return *inner_; }

 private:
  std::unique_ptr<Kernel> inner_;
  int input_dim_;
};

}  // namespace structgp

#endif  // STRUCTGP_KERNEL_LEADING_INPUTS_KERNEL_H_
