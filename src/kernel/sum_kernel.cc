#include "structgp/kernel/sum_kernel.h"

#include <map>
#include <stdexcept>

#include "structgp/core/validate.h"

namespace structgp {

SumKernel::SumKernel(const std::vector<const Kernel*>& parts) {
  if (parts.empty()) throw std::invalid_argument("SumKernel: no parts");
  for (const Kernel* k : parts) {
    if (k == nullptr) throw std::invalid_argument("SumKernel: null part");
    if (k->input_dim() != parts.front()->input_dim()) {
      throw std::invalid_argument("SumKernel: parts have input dimensions " +
                                  std::to_string(parts.front()->input_dim()) + " and " +
                                  std::to_string(k->input_dim()));
    }
    parts_.push_back(k->Clone());
    num_parameters_ += k->num_parameters();
  }
}

double SumKernel::Evaluate(const ConstVectorRef& a, const ConstVectorRef& b) const {
  double k = 0.0;
  for (const auto& p : parts_) k += p->Evaluate(a, b);
  return k;
}

std::vector<std::string> SumKernel::parameter_names() const {
  std::map<std::string, int> count;
  for (const auto& p : parts_) {
    for (const auto& n : p->parameter_names()) ++count[n];
  }
  std::vector<std::string> names;
  for (size_t i = 0; i < parts_.size(); ++i) {
    for (const auto& n : parts_[i]->parameter_names()) {
      names.push_back(count[n] > 1 ? n + "." + std::to_string(i) : n);
    }
  }
  return names;
}

Vector SumKernel::parameters() const {
  Vector theta(num_parameters_);
  int offset = 0;
  for (const auto& p : parts_) {
    theta.segment(offset, p->num_parameters()) = p->parameters();
    offset += p->num_parameters();
  }
  return theta;
}

std::unique_ptr<Kernel> SumKernel::WithParameters(const ConstVectorRef& theta) const {
  RequireSize("SumKernel::WithParameters theta", theta.size(), num_parameters_);
  std::vector<std::unique_ptr<Kernel>> parts;
  std::vector<const Kernel*> raw;
  int offset = 0;
  for (const auto& p : parts_) {
    parts.push_back(p->WithParameters(theta.segment(offset, p->num_parameters())));
    raw.push_back(parts.back().get());
    offset += p->num_parameters();
  }
  return std::make_unique<SumKernel>(raw);
}

void SumKernel::Gradient(const ConstVectorRef& a, const ConstVectorRef& b, VectorRef dk) const {
  int offset = 0;
  for (const auto& p : parts_) {
    p->Gradient(a, b, dk.segment(offset, p->num_parameters()));
    offset += p->num_parameters();
  }
}

std::unique_ptr<Kernel> SumKernel::Clone() const {
  std::vector<const Kernel*> raw;
  for (const auto& p : parts_) raw.push_back(p.get());
  return std::make_unique<SumKernel>(raw);
}

}  // namespace structgp
