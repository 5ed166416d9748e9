#include "structgp/internal/gram.h"

#include "structgp/core/validate.h"

namespace structgp {
namespace internal {
namespace {

// The one loop: columns j of K in turn (contiguous writes). With `symmetric`, A and B are the
// same points and only i <= j is evaluated, then mirrored.
void GramImpl(const Kernel& kernel, const ConstMatrixRef& A, const ConstMatrixRef& B,
              bool symmetric, Matrix* K) {
  RequireSize("KernelGram A", A.rows(), kernel.input_dim(), "rows (points are columns)");
  RequireSize("KernelGram B", B.rows(), kernel.input_dim(), "rows (points are columns)");
  if (K->rows() != A.cols() || K->cols() != B.cols()) K->resize(A.cols(), B.cols());
  for (Eigen::Index j = 0; j < B.cols(); ++j) {
    const Eigen::Index rows = symmetric ? j + 1 : A.cols();
    for (Eigen::Index i = 0; i < rows; ++i) (*K)(i, j) = kernel.Evaluate(A.col(i), B.col(j));
  }
  if (!symmetric) return;
  for (Eigen::Index j = 0; j < B.cols(); ++j) {
    for (Eigen::Index i = j + 1; i < A.cols(); ++i) (*K)(i, j) = (*K)(j, i);
  }
}

}  // namespace

void KernelGram(const Kernel& kernel, const ConstMatrixRef& A, const ConstMatrixRef& B, Matrix* K) {
  GramImpl(kernel, A, B, /*symmetric=*/false, K);
}

void KernelGram(const Kernel& kernel, const ConstMatrixRef& X, Matrix* K) {
  GramImpl(kernel, X, X, /*symmetric=*/true, K);
}

}  // namespace internal
}  // namespace structgp
