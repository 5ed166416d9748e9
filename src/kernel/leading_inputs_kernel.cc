#include "structgp/kernel/leading_inputs_kernel.h"

#include <stdexcept>

namespace structgp {

LeadingInputsKernel::LeadingInputsKernel(const Kernel& inner, int input_dim)
    : inner_(inner.Clone()), input_dim_(input_dim) {
  if (input_dim < inner.input_dim()) {
    throw std::invalid_argument("LeadingInputsKernel: input_dim " + std::to_string(input_dim) +
                                " is below the inner kernel's " +
                                std::to_string(inner.input_dim()));
  }
}

double LeadingInputsKernel::Evaluate(const ConstVectorRef& a, const ConstVectorRef& b) const {
  const int d = inner_->input_dim();
  return inner_->Evaluate(a.head(d), b.head(d));
}

std::unique_ptr<Kernel> LeadingInputsKernel::WithParameters(const ConstVectorRef& theta) const {
  return std::make_unique<LeadingInputsKernel>(*inner_->WithParameters(theta), input_dim_);
}

void LeadingInputsKernel::Gradient(const ConstVectorRef& a, const ConstVectorRef& b,
                                   VectorRef dk) const {
  const int d = inner_->input_dim();
  inner_->Gradient(a.head(d), b.head(d), dk);
}

std::unique_ptr<Kernel> LeadingInputsKernel::Clone() const {
  return std::make_unique<LeadingInputsKernel>(*inner_, input_dim_);
}

}  // namespace structgp
