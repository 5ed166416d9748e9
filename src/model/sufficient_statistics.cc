#include "structgp/model/sufficient_statistics.h"

#include "structgp/core/validate.h"

namespace structgp {

SufficientStatistics::SufficientStatistics(int num_features, int num_outputs)
    : gram(Matrix::Zero(num_features, num_features)),
      cross(Matrix::Zero(num_features, num_outputs)),
      y_squared(Vector::Zero(num_outputs)) {}

void SufficientStatistics::Accumulate(const ConstMatrixRef& Phi, const ConstMatrixRef& Y) {
  RequireSize("SufficientStatistics::Accumulate Phi", Phi.cols(), num_features(), "columns");
  RequireSize("SufficientStatistics::Accumulate Y", Y.cols(), num_outputs(), "columns");
  RequireSize("SufficientStatistics::Accumulate Y", Y.rows(), Phi.rows(), "rows (as in Phi)");
  RequireFinite("SufficientStatistics::Accumulate Phi", Phi);
  RequireFinite("SufficientStatistics::Accumulate Y", Y);
  gram.selfadjointView<Eigen::Lower>().rankUpdate(Phi.transpose());
  cross.noalias() += Phi.transpose() * Y;
  y_squared += Y.colwise().squaredNorm().transpose();
  count += static_cast<double>(Phi.rows());
}

}  // namespace structgp
