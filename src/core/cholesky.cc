#include "structgp/internal/cholesky.h"

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <stdexcept>
#include <string>

#include <Eigen/Cholesky>

namespace structgp {
namespace internal {
namespace {

// One attempt: factor = lower triangle of A with diagonal A_kk + delta s_k, factorised in
// place; true when accepted (the test of the header, against the unjittered A_kk).
bool Attempt(const ConstMatrixRef& A, JitterScale scale, double mean_diagonal, double delta,
             Matrix* factor) {
  const Eigen::Index n = A.rows();
  factor->triangularView<Eigen::Lower>() = A.triangularView<Eigen::Lower>();
  if (delta > 0.0) {
    if (scale == JitterScale::kDiagonal) {
      factor->diagonal() = (1.0 + delta) * A.diagonal();
    } else {
      factor->diagonal().array() += delta * mean_diagonal;
    }
  }
  // In place: Eigen's LLT on a Ref overwrites the lower triangle of *factor with L (and reads
  // nothing else).
  Eigen::LLT<Eigen::Ref<Matrix>, Eigen::Lower> llt(*factor);
  if (llt.info() != Eigen::Success) return false;
  for (Eigen::Index k = 0; k < n; ++k) {
    const double pivot = (*factor)(k, k);
    if (!std::isfinite(pivot) || !(pivot * pivot >= kMinPivotRatio * A(k, k))) return false;
  }
  return true;
}

// Below this size the recursions below stop and use Eigen's triangular kernels directly.
constexpr Eigen::Index kInverseBlock = 96;

// M (lower triangle, n x n) <- M^{-1}, lower-triangular. With M = [A 0; B D]:
// M^{-1} = [A^{-1} 0; -D^{-1} B A^{-1}  D^{-1}].
void InvertLowerInPlace(Eigen::Ref<Matrix> M) {
  const Eigen::Index n = M.rows();
  if (n <= kInverseBlock) {
    Matrix I = Matrix::Identity(n, n);
    M.triangularView<Eigen::Lower>().solveInPlace(I);
    M.triangularView<Eigen::Lower>() = I;
    return;
  }
  const Eigen::Index k = n / 2;
  InvertLowerInPlace(M.topLeftCorner(k, k));
  InvertLowerInPlace(M.bottomRightCorner(n - k, n - k));
  auto B = M.bottomLeftCorner(n - k, k);
  Matrix BA = B * M.topLeftCorner(k, k).triangularView<Eigen::Lower>();
  B.noalias() = -(M.bottomRightCorner(n - k, n - k).triangularView<Eigen::Lower>() * BA);
}

// M (lower triangle holds a lower-triangular T) <- lower triangle of T^T T. With T = [A 0; B D]:
// T^T T = [A^T A + B^T B, B^T D; D^T B, D^T D].
void LowerTransposeTimesSelfInPlace(Eigen::Ref<Matrix> M) {
  const Eigen::Index n = M.rows();
  if (n <= kInverseBlock) {
    const Matrix T = M.triangularView<Eigen::Lower>();
    Matrix P = Matrix::Zero(n, n);
    P.selfadjointView<Eigen::Lower>().rankUpdate(T.transpose());
    M.triangularView<Eigen::Lower>() = P;
    return;
  }
  const Eigen::Index k = n / 2;
  auto B = M.bottomLeftCorner(n - k, k);
  LowerTransposeTimesSelfInPlace(M.topLeftCorner(k, k));
  M.topLeftCorner(k, k).selfadjointView<Eigen::Lower>().rankUpdate(B.transpose());
  Matrix DB =
      M.bottomRightCorner(n - k, n - k).triangularView<Eigen::Lower>().transpose() * B;
  B = DB;
  LowerTransposeTimesSelfInPlace(M.bottomRightCorner(n - k, n - k));
}

}  // namespace

Matrix InverseFromFactor(const ConstMatrixRef& L) {
  if (L.rows() != L.cols()) {
    throw std::invalid_argument("InverseFromFactor: expected a square factor, got " +
                                std::to_string(L.rows()) + " x " + std::to_string(L.cols()));
  }
  Matrix M = L.triangularView<Eigen::Lower>();
  InvertLowerInPlace(M);
  LowerTransposeTimesSelfInPlace(M);
  M.triangularView<Eigen::StrictlyUpper>() = M.transpose();
  return M;
}

double MeanDiagonal(const ConstMatrixRef& A) { return std::max(A.diagonal().mean(), DBL_MIN); }

CholeskyResult Cholesky::Factorize(const ConstMatrixRef& A, const CholeskyOptions& options) {
  if (A.rows() != A.cols()) {
    throw std::invalid_argument("Cholesky::Factorize: expected a square matrix, got " +
                                std::to_string(A.rows()) + " x " + std::to_string(A.cols()));
  }
  if (!(options.min_jitter >= 0.0) || !std::isfinite(options.min_jitter)) {
    throw std::invalid_argument("CholeskyOptions::min_jitter: expected a finite value >= 0, got " +
                                std::to_string(options.min_jitter));
  }
  const Eigen::Index n = A.rows();
  if (factor_.rows() != n || factor_.cols() != n) factor_.resize(n, n);
  result_ = CholeskyResult();
  const bool diagonal_finite = A.diagonal().allFinite();
  const double mean_diagonal =
      options.scale == JitterScale::kMeanDiagonal && diagonal_finite ? MeanDiagonal(A) : 0.0;

  double delta = options.min_jitter;
  bool accepted = diagonal_finite && Attempt(A, options.scale, mean_diagonal, delta, &factor_);
  if (!accepted && diagonal_finite && options.ladder == JitterLadder::kClimb) {
    // The rungs, computed by repeated multiplication (the values fit_jitter() has always
    // reported), skipping those at or below min_jitter.
    double rung = kJitterFirst;
    for (int k = 0; k < kMaxJitterSteps && !accepted; ++k, rung *= kJitterGrowth) {
      if (rung <= options.min_jitter) continue;
      delta = rung;
      ++result_.steps;
      accepted = Attempt(A, options.scale, mean_diagonal, delta, &factor_);
    }
  }
  result_.jitter = delta;
  if (!accepted) {
    factor_.setZero();
    result_.status = Status::kNotPositiveDefinite;
    return result_;
  }
  factor_.triangularView<Eigen::StrictlyUpper>().setZero();
  result_.status = Status::kOk;
  return result_;
}

}  // namespace internal
}  // namespace structgp
