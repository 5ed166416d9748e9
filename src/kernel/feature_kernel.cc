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

namespace {

// Features of one evaluation live on the stack up to this width (three vectors of D doubles:
// 48 KiB at the limit), so Evaluate and Gradient allocate nothing and are safe for concurrent
// calls; a wider map takes its scratch from the heap for each call.
constexpr int kStackFeatures = 2048;

// Calls f(phi_a, phi_b, product) on scratch of `dim` entries each, every vector aligned as a
// Vector's storage is (same arithmetic as on Vectors).
template <typename F>
auto WithFeatureScratch(int dim, F&& f) {
  using AlignedMap = Eigen::Map<Vector, Eigen::AlignedMax>;
  constexpr int kLane = EIGEN_MAX_ALIGN_BYTES / sizeof(double) > 0
                            ? EIGEN_MAX_ALIGN_BYTES / sizeof(double)
                            : 1;
  const int stride = (dim + kLane - 1) / kLane * kLane;
  auto run = [&](double* s) {
    AlignedMap phi_a(s, dim), phi_b(s + stride, dim), product(s + 2 * stride, dim);
    return f(phi_a, phi_b, product);
  };
  if (stride <= kStackFeatures) {
    alignas(EIGEN_MAX_ALIGN_BYTES > 0 ? EIGEN_MAX_ALIGN_BYTES : 16) double
        buffer[3 * kStackFeatures];
    return run(buffer);
  }
  Eigen::Matrix<double, Eigen::Dynamic, 1> heap(3 * static_cast<Eigen::Index>(stride));
  return run(heap.data());
}

}  // namespace

double FeatureKernel::Evaluate(const ConstVectorRef& a, const ConstVectorRef& b) const {
  return WithFeatureScratch(map_->dim(), [&](auto& phi_a, auto& phi_b, auto& product) {
    map_->Evaluate(a, phi_a);
    map_->Evaluate(b, phi_b);
    product = phi_a.cwiseProduct(phi_b);
    return lambda_.dot(product);
  });
}

void FeatureKernel::Gradient(const ConstVectorRef& a, const ConstVectorRef& b, VectorRef dk) const {
  assert(dk.size() == num_parameters());
  WithFeatureScratch(map_->dim(), [&](auto& phi_a, auto& phi_b, auto& product) {
    map_->Evaluate(a, phi_a);
    map_->Evaluate(b, phi_b);
    product = phi_a.cwiseProduct(phi_b);
    const int num_shape = map_->num_shape_parameters();
    if (num_shape > 0) dk.head(num_shape).noalias() = d_lambda_d_shape_.transpose() * product;
    for (size_t k = 0; k < blocks_.size(); ++k) {
      const FeatureBlock& block = blocks_[k];
      dk[num_shape + static_cast<Eigen::Index>(k)] =
          2.0 *
          lambda_.segment(block.begin, block.size).dot(product.segment(block.begin, block.size));
    }
    return 0;
  });
}

std::unique_ptr<Kernel> FeatureKernel::Clone() const {
  return std::make_unique<FeatureKernel>(*this);
}

}  // namespace structgp
