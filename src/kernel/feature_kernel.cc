#include "structgp/kernel/feature_kernel.h"

#include <cassert>
#include <stdexcept>
#include <utility>

#include "structgp/core/validate.h"

namespace structgp {

FeatureKernel::FeatureKernel(std::shared_ptr<const FeatureMap> map, const Hyperparameters& hyper)
    : map_(std::move(map)), hyper_(hyper) {
  if (map_ == nullptr) throw std::invalid_argument("FeatureKernel: the feature map is null");
  ValidateHyperparameters(hyper_, *map_, static_cast<int>(hyper_.log_output_scale.size()));
  blocks_ = map_->blocks();
  const int dim = map_->dim();
  phi_a_.resize(dim);
  phi_b_.resize(dim);
  product_.resize(dim);
  UpdatePrior();
}

void FeatureKernel::UpdatePrior() { lambda_ = PriorVariance(*map_, hyper_, &d_lambda_d_shape_); }

int FeatureKernel::num_parameters() const {
  return map_->num_shape_parameters() + static_cast<int>(blocks_.size());
}

std::vector<std::string> FeatureKernel::parameter_names() const {
  std::vector<std::string> names = map_->shape_parameter_names();
  for (const FeatureBlock& block : blocks_) names.push_back("log_scale_" + block.name);
  return names;
}

Vector FeatureKernel::parameters() const {
  Vector theta(num_parameters());
  theta << hyper_.shape, hyper_.log_block_scale;
  return theta;
}

std::unique_ptr<Kernel> FeatureKernel::WithParameters(const ConstVectorRef& theta) const {
  auto kernel = std::make_unique<FeatureKernel>(*this);
  kernel->AssignParameters(theta);
  return kernel;
}

void FeatureKernel::AssignParameters(const ConstVectorRef& theta) {
  RequireSize("FeatureKernel::WithParameters theta", theta.size(), num_parameters());
  RequireFinite("FeatureKernel::WithParameters theta", theta);
  const int num_shape = map_->num_shape_parameters();
  hyper_.shape = theta.head(num_shape);
  hyper_.log_block_scale = theta.tail(static_cast<Eigen::Index>(blocks_.size()));
  UpdatePrior();
}

void FeatureKernel::EvaluateFeatures(const ConstVectorRef& a, const ConstVectorRef& b) const {
  map_->Evaluate(a, phi_a_);
  map_->Evaluate(b, phi_b_);
  product_ = phi_a_.cwiseProduct(phi_b_);
}

double FeatureKernel::Evaluate(const ConstVectorRef& a, const ConstVectorRef& b) const {
  EvaluateFeatures(a, b);
  return lambda_.dot(product_);
}

void FeatureKernel::Gradient(const ConstVectorRef& a, const ConstVectorRef& b, VectorRef dk) const {
  assert(dk.size() == num_parameters());
  EvaluateFeatures(a, b);
  const int num_shape = map_->num_shape_parameters();
  if (num_shape > 0) dk.head(num_shape).noalias() = d_lambda_d_shape_.transpose() * product_;
  for (size_t k = 0; k < blocks_.size(); ++k) {
    const FeatureBlock& block = blocks_[k];
    dk[num_shape + static_cast<Eigen::Index>(k)] =
        2.0 *
        lambda_.segment(block.begin, block.size).dot(product_.segment(block.begin, block.size));
  }
}

std::unique_ptr<Kernel> FeatureKernel::Clone() const {
  return std::make_unique<FeatureKernel>(*this);
}

}  // namespace structgp
