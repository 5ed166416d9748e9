#include "structgp/kernel/kernel.h"

#include "structgp/core/validate.h"
#include "structgp/internal/gram.h"

namespace structgp {

void Kernel::Gram(const ConstMatrixRef& A, const ConstMatrixRef& B, Matrix* K) const {
  RequireSize("Kernel::Gram A", A.cols(), input_dim(), "columns");
  RequireSize("Kernel::Gram B", B.cols(), input_dim(), "columns");
  // Points as rows here, as columns (contiguous) in the library's Gram routine.
  const Matrix a = A.transpose();
  const Matrix b = B.transpose();
  internal::KernelGram(*this, a, b, K);
}

}  // namespace structgp
