#ifndef STRUCTGP_INTERNAL_GRAM_H_
#define STRUCTGP_INTERNAL_GRAM_H_

/// @file
/// The library's one Gram-matrix routine (not API), used by Kernel::Gram, KernelGP::Fit and
/// NystromFeatureMap. Points are columns (input_dim x n, each point contiguous: the layout the
/// models store); every entry is one Kernel::Evaluate call.

#include "structgp/core/types.h"
#include "structgp/kernel/kernel.h"

namespace structgp {
namespace internal {

/// K(i, j) = k(a_i, b_j) for the columns a_i of A and b_j of B; K is resized to
/// A.cols() x B.cols() (allocates only when its size changes). Throws std::invalid_argument
/// when A or B does not have kernel.input_dim() rows.
void KernelGram(const Kernel& kernel, const ConstMatrixRef& A, const ConstMatrixRef& B, Matrix* K);

/// The symmetric Gram matrix of the columns of X: K(i, j) = k(x_i, x_j) evaluated once for
/// i <= j (the earlier point first, the order KernelGP::Add uses) and copied to K(j, i).
/// Equal to KernelGram(kernel, X, X, K) for a kernel that is symmetric in IEEE arithmetic
/// (every built-in one), at half the evaluations. Same resizing and errors.
void KernelGram(const Kernel& kernel, const ConstMatrixRef& X, Matrix* K);

}  // namespace internal
}  // namespace structgp

#endif  // STRUCTGP_INTERNAL_GRAM_H_
