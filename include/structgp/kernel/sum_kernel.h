#ifndef STRUCTGP_KERNEL_SUM_KERNEL_H_
#define STRUCTGP_KERNEL_SUM_KERNEL_H_

/// @file
/// k = k_1 + ... + k_P on one input (e.g. rbf + the friction features as a kernel). The
/// parameters are the parts' in order; names get the suffix ".<i>" (0-based part) when two
/// parts share a name.

#include <memory>
#include <string>
#include <vector>

#include "structgp/kernel/kernel.h"

namespace structgp {

class SumKernel : public Kernel {
 public:
  /// Copies (Clone) the parts. Throws std::invalid_argument when empty or when input
  /// dimensions differ.
  explicit SumKernel(const std::vector<const Kernel*>& parts);

  int input_dim() const override { return parts_.front()->input_dim(); }
  double Evaluate(const ConstVectorRef& a, const ConstVectorRef& b) const override;
  int num_parameters() const override { return num_parameters_; }
  std::vector<std::string> parameter_names() const override;
  Vector parameters() const override;
  std::unique_ptr<Kernel> WithParameters(const ConstVectorRef& theta) const override;
  void Gradient(const ConstVectorRef& a, const ConstVectorRef& b, VectorRef dk) const override;
  std::unique_ptr<Kernel> Clone() const override;

  int num_parts() const { return static_cast<int>(parts_.size()); }
  const Kernel& part(int i) const { return *parts_.at(static_cast<size_t>(i)); }

 private:
  std::vector<std::unique_ptr<Kernel>> parts_;
  int num_parameters_ = 0;
};

}  // namespace structgp

#endif  // STRUCTGP_KERNEL_SUM_KERNEL_H_
