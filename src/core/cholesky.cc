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

}  // namespace

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
