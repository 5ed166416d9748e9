#include "structgp/feature/feature_map.h"

#include "structgp/core/validate.h"

namespace structgp {

std::vector<FeatureBlock> FeatureMap::blocks() const { return {FeatureBlock{"all", 0, dim()}}; }

void FeatureMap::PriorVariance(const ConstVectorRef& shape, VectorRef lambda,
                               Matrix* jacobian) const {
  RequireSize("FeatureMap::PriorVariance shape", shape.size(), num_shape_parameters());
  RequireSize("FeatureMap::PriorVariance lambda", lambda.size(), dim());
  lambda.setOnes();
  if (jacobian != nullptr) jacobian->setZero(dim(), num_shape_parameters());
}

void FeatureMap::EvaluateRows(const ConstMatrixRef& X, Matrix* Phi) const {
  RequireSize("FeatureMap::EvaluateRows X", X.cols(), input_dim(), "columns");
  Phi->resize(X.rows(), dim());
  Vector x(input_dim());
  Vector phi(dim());
  for (Eigen::Index i = 0; i < X.rows(); ++i) {
    x = X.row(i).transpose();
    Evaluate(x, phi);
    Phi->row(i) = phi.transpose();
  }
}

}  // namespace structgp
