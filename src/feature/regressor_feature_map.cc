#include "structgp/feature/regressor_feature_map.h"

#include <atomic>
#include <stdexcept>
#include <utility>

#include "per_thread_scratch.h"
#include "structgp/core/validate.h"

namespace structgp {
namespace internal {

std::uint64_t NewScratchOwner() {
  static std::atomic<std::uint64_t> next{1};
  return next.fetch_add(1);
}

}  // namespace internal

namespace {

struct RowScratch {
  std::unique_ptr<RegressorMap::Scratch> scratch;
  Matrix psi;
};

}  // namespace

RegressorFeatureMap::RegressorFeatureMap(std::shared_ptr<const RegressorMap> regressor, int row)
    : regressor_(std::move(regressor)), row_(row), id_(internal::NewScratchOwner()) {
  if (!regressor_) throw std::invalid_argument("RegressorFeatureMap: null regressor");
  RequireInRange("RegressorFeatureMap row", row, 0, regressor_->num_outputs(), true);
}

void RegressorFeatureMap::Evaluate(const ConstVectorRef& x, VectorRef phi) const {
  if (x.size() != input_dim()) RequireSize("RegressorFeatureMap::Evaluate x", x.size(), input_dim());
  if (phi.size() != dim()) RequireSize("RegressorFeatureMap::Evaluate phi", phi.size(), dim());
  RowScratch& local = internal::PerThreadScratch<RowScratch>(id_, [this] {
    return RowScratch{regressor_->MakeScratch(), Matrix(regressor_->num_outputs(), regressor_->dim())};
  });
  regressor_->Evaluate(x, local.psi, local.scratch.get());
  phi = local.psi.row(row_).transpose();
}

std::vector<FeatureBlock> RegressorFeatureMap::blocks() const { return regressor_->blocks(); }

void RegressorFeatureMap::PriorVariance(const ConstVectorRef& shape, VectorRef lambda,
                                        Matrix* jacobian) const {
  RequireSize("RegressorFeatureMap::PriorVariance shape", shape.size(), 0);
  RequireSize("RegressorFeatureMap::PriorVariance lambda", lambda.size(), dim());
  lambda = regressor_->prior_std().array().square().matrix();
  if (jacobian != nullptr) jacobian->resize(dim(), 0);
}

}  // namespace structgp
