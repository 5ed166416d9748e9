// The posterior mean of a kernel-form GP whose outputs share one kernel and one noise level:
// f_hat(X_*) = K(X_*, X) alpha with (K(X, X) + sigma_n^2 I) alpha = Y. (Output j with prior
// s_j^2 k and noise s_j^2 sigma_n^2 has the same mean, so per-output scales do not enter.)
// Dense: O(m^3) time and O(m^2) memory for m training rows.

#ifndef STRUCTGP_EXPERIMENTS_KERNEL_MEAN_H_
#define STRUCTGP_EXPERIMENTS_KERNEL_MEAN_H_

#include "structgp/core/types.h"
#include "structgp/kernel/kernel.h"

namespace structgp {

// Solves (K(X, X) + noise_variance I) alpha = Y (m x outputs) by Cholesky. Returns false, and
// leaves *alpha as it was, when the matrix is not positive definite.
bool SolveKernelSystem(const Kernel& kernel, const Matrix& X, const Matrix& Y,
                       double noise_variance, Matrix* alpha);

// K(X_test, X) alpha: the posterior mean at every row of X_test (rows x alpha.cols()), with
// the kernel matrix evaluated for a block of test rows at a time.
Matrix KernelMean(const Kernel& kernel, const Matrix& X, const Matrix& alpha, const Matrix& X_test);

}  // namespace structgp

#endif  // STRUCTGP_EXPERIMENTS_KERNEL_MEAN_H_
