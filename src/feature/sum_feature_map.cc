#include "structgp/feature/sum_feature_map.h"

#include <map>
#include <stdexcept>
#include <utility>

#include "structgp/core/validate.h"

namespace structgp {
namespace {

// Appends ".<part>" to every name that occurs in more than one part.
void Disambiguate(const std::vector<int>& part_of, std::vector<std::string>* names) {
  std::map<std::string, int> first_part;
  std::map<std::string, bool> shared;
  for (size_t i = 0; i < names->size(); ++i) {
    const auto it = first_part.find((*names)[i]);
    if (it == first_part.end()) {
      first_part[(*names)[i]] = part_of[i];
    } else if (it->second != part_of[i]) {
      shared[(*names)[i]] = true;
    }
  }
  for (size_t i = 0; i < names->size(); ++i) {
    if (shared.count((*names)[i]) > 0) (*names)[i] += "." + std::to_string(part_of[i]);
  }
}

}  // namespace

SumFeatureMap::SumFeatureMap(std::vector<std::shared_ptr<const FeatureMap>> parts)
    : parts_(std::move(parts)) {
  if (parts_.empty()) throw std::invalid_argument("SumFeatureMap: expected at least one part");
  std::vector<std::string> block_names;
  std::vector<int> block_part;
  std::vector<int> shape_part;
  for (size_t i = 0; i < parts_.size(); ++i) {
    if (parts_[i] == nullptr) {
      throw std::invalid_argument("SumFeatureMap: part " + std::to_string(i) + " is null");
    }
    const FeatureMap& p = *parts_[i];
    if (i == 0) input_dim_ = p.input_dim();
    if (p.input_dim() != input_dim_) {
      throw std::invalid_argument("SumFeatureMap: part " + std::to_string(i) +
                                  ": expected input_dim " + std::to_string(input_dim_) + ", got " +
                                  std::to_string(p.input_dim()) +
                                  " (all parts must read the same state)");
    }
    feature_begin_.push_back(dim_);
    shape_begin_.push_back(num_shape_);
    for (const FeatureBlock& b : p.blocks()) {
      blocks_.push_back(FeatureBlock{b.name, b.begin + dim_, b.size});
      block_names.push_back(b.name);
      block_part.push_back(static_cast<int>(i));
    }
    for (const std::string& name : p.shape_parameter_names()) {
      shape_names_.push_back(name);
      shape_part.push_back(static_cast<int>(i));
    }
    dim_ += p.dim();
    num_shape_ += p.num_shape_parameters();
  }
  Disambiguate(block_part, &block_names);
  for (size_t b = 0; b < blocks_.size(); ++b) blocks_[b].name = block_names[b];
  Disambiguate(shape_part, &shape_names_);
}

void SumFeatureMap::Evaluate(const ConstVectorRef& x, VectorRef phi) const {
  if (x.size() != input_dim_) RequireSize("SumFeatureMap::Evaluate x", x.size(), input_dim_);
  if (phi.size() != dim_) RequireSize("SumFeatureMap::Evaluate phi", phi.size(), dim_);
  for (size_t i = 0; i < parts_.size(); ++i) {
    parts_[i]->Evaluate(x, phi.segment(feature_begin_[i], parts_[i]->dim()));
  }
}

Vector SumFeatureMap::default_shape_parameters() const {
  Vector s(num_shape_);
  for (size_t i = 0; i < parts_.size(); ++i) {
    const int n = parts_[i]->num_shape_parameters();
    if (n > 0) s.segment(shape_begin_[i], n) = parts_[i]->default_shape_parameters();
  }
  return s;
}

void SumFeatureMap::PriorVariance(const ConstVectorRef& shape, VectorRef lambda,
                                  Matrix* jacobian) const {
  RequireSize("SumFeatureMap::PriorVariance shape", shape.size(), num_shape_);
  RequireSize("SumFeatureMap::PriorVariance lambda", lambda.size(), dim_);
  if (jacobian != nullptr) jacobian->setZero(dim_, num_shape_);
  Matrix part_jacobian;
  for (size_t i = 0; i < parts_.size(); ++i) {
    const FeatureMap& p = *parts_[i];
    const int ns = p.num_shape_parameters();
    p.PriorVariance(shape.segment(shape_begin_[i], ns), lambda.segment(feature_begin_[i], p.dim()),
                    jacobian != nullptr ? &part_jacobian : nullptr);
    if (jacobian != nullptr && ns > 0) {
      jacobian->block(feature_begin_[i], shape_begin_[i], p.dim(), ns) = part_jacobian;
    }
  }
}

}  // namespace structgp
