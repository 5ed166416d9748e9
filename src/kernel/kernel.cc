#include "structgp/kernel/kernel.h"

#include "structgp/core/validate.h"

namespace structgp {

void Kernel::Gram(const ConstMatrixRef& A, const ConstMatrixRef& B, Matrix* K) const {
  RequireSize("Kernel::Gram A", A.cols(), input_dim(), "columns");
  RequireSize("Kernel::Gram B", B.cols(), input_dim(), "columns");
  K->resize(A.rows(), B.rows());
  Vector a(input_dim()), b(input_dim());
  for (Eigen::Index j = 0; j < B.rows(); ++j) {
    b = B.row(j).transpose();
    for (Eigen::Index i = 0; i < A.rows(); ++i) {
      a = A.row(i).transpose();
      (*K)(i, j) = Evaluate(a, b);
    }
  }
}

}  // namespace structgp
