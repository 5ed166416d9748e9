#include "kernel_mean.h"

#include <Eigen/Cholesky>
#include <algorithm>

namespace structgp {
namespace {

// Test rows whose kernel row block is evaluated at once: 2000 x m doubles, 16 MB at m = 1000.
constexpr Eigen::Index kPredictChunk = 2000;

}  // namespace

bool SolveKernelSystem(const Kernel& kernel, const Matrix& X, const Matrix& Y,
                       double noise_variance, Matrix* alpha) {
  Matrix K;
  kernel.Gram(X, X, &K);
  K.diagonal().array() += noise_variance;
  const Eigen::LLT<Matrix> llt(K);
  if (llt.info() != Eigen::Success) return false;
  *alpha = llt.solve(Y);
  return true;
}

Matrix KernelMean(const Kernel& kernel, const Matrix& X, const Matrix& alpha,
                  const Matrix& X_test) {
  Matrix mean(X_test.rows(), alpha.cols());
  Matrix k_star;
  for (Eigen::Index begin = 0; begin < X_test.rows(); begin += kPredictChunk) {
    const Eigen::Index rows = std::min<Eigen::Index>(kPredictChunk, X_test.rows() - begin);
    kernel.Gram(X_test.middleRows(begin, rows), X, &k_star);
    mean.middleRows(begin, rows).noalias() = k_star * alpha;
  }
  return mean;
}

}  // namespace structgp
