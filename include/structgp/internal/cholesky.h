#ifndef STRUCTGP_INTERNAL_CHOLESKY_H_
#define STRUCTGP_INTERNAL_CHOLESKY_H_

/// @file
/// The library's one positive-definite factorisation (not API): L L^T = A + J, with the one
/// acceptance test and the one bounded jitter ladder below, used by every area that
/// factorises (WeightSpaceGP::Fit, KernelGP::Fit, NystromFeatureMap, Diagnose). The policy
/// and what each caller asks of it are tabulated in docs/reliability.md, section 3.
///
/// Acceptance. A factor is accepted when Eigen's LLT succeeds and every pivot is finite with
///     L_kk^2 >= kMinPivotRatio * A_kk
/// (A_kk before any jitter): L_kk^2 / A_kk is the part of row k's diagonal not explained by the
/// rows before it, and below kMinPivotRatio it is rounding error. The test is invariant to a
/// diagonal scaling of A (features in any units). A finite pivot implies a finite factor: every
/// entry of row k enters L_kk.
///
/// Jitter ladder. J = delta * s, with s = diag(A) (JitterScale::kDiagonal: relative to each
/// diagonal entry, scale invariant as the test above) or s = max(mean(diag A), DBL_MIN) I
/// (JitterScale::kMeanDiagonal: a multiple of the identity, for a kernel's Gram matrix whose
/// jitter acts as a small noise). The attempts are
///     delta = min_jitter (0 by default), then each rung kJitterFirst * kJitterGrowth^k
///     (k = 0 .. kMaxJitterSteps - 1, i.e. 1e-11, 1e-9, 1e-7, 1e-5) above min_jitter,
/// the rungs only with JitterLadder::kClimb. The first accepted attempt wins; the result
/// records its delta and how many attempts failed before it. A caller whose result must be
/// exact (an evidence, the kernel form's exact posterior) passes JitterLadder::kNone.
///
/// Failure. When no attempt is accepted (or diag(A) is not finite, which no jitter repairs),
/// Factorize returns kNotPositiveDefinite, and the factor is set to zero (never NaN); ok() is
/// false.
///
/// Cost and memory. O(n^3 / 3) per attempt plus O(n^2) copies; one n x n matrix. Factorize of
/// a matrix of the size given to the constructor, on one thread, allocates nothing itself (on
/// more threads it starts threads and allocates their lists of chunks);
/// Eigen's blocked LLT that it calls allocates its own GEMM workspace above a few hundred rows
/// (none measured up to n = 300). No real-time path factorises.

#include <utility>

#include "structgp/core/status.h"
#include "structgp/core/types.h"

namespace structgp {
namespace internal {

/// Smallest accepted L_kk^2 / A_kk: a few hundred eps. The error of L_kk^2 computed from n
/// earlier rows is ~n eps A_kk, so a smaller ratio is mostly noise for n in the hundreds.
inline constexpr double kMinPivotRatio = 1e-13;
/// First rung of the ladder: a hundred times the pivot floor, so that one rung normally
/// lifts every lost pivot above it.
inline constexpr double kJitterFirst = 1e-11;
/// Factor between consecutive rungs.
inline constexpr double kJitterGrowth = 100.0;
/// Number of rungs: the largest jitter is kJitterFirst * kJitterGrowth^(kMaxJitterSteps - 1)
/// = 1e-5 of the diagonal, small against any noise level a model would fit, large enough to
/// repair a Gram matrix of duplicate rows. Beyond it the matrix is not a rounding away from
/// positive definite and is refused.
inline constexpr int kMaxJitterSteps = 4;

/// What the jitter is proportional to (see the file comment).
enum class JitterScale {
  kDiagonal,      ///< A + delta diag(A)
  kMeanDiagonal,  ///< A + delta max(mean(diag A), DBL_MIN) I
};

/// Whether the rungs of the ladder are tried after the first attempt fails.
enum class JitterLadder {
  kClimb,  ///< try the rungs above min_jitter
  kNone,   ///< give up after the first attempt
};

struct CholeskyOptions {
  JitterLadder ladder = JitterLadder::kClimb;
  JitterScale scale = JitterScale::kDiagonal;
  /// A relative jitter always added (a regularisation the caller's model includes, e.g. the
  /// Nystrom features' kNystromRelativeJitter); the rungs at or below it are skipped. >= 0.
  double min_jitter = 0.0;
  /// Threads of each attempt (>= 1). From 256 rows on, more than one runs a blocked
  /// right-looking factorisation whose panel solves and trailing updates are shared among the
  /// threads in fixed chunks of columns: the factor is the same for every thread count from two
  /// on, and equals the one-thread factor (Eigen's LLT) up to rounding, not bit for bit.
  /// Smaller matrices use Eigen's LLT on the calling thread.
  int num_threads = 1;
};

/// How a factorisation ended.
struct CholeskyResult {
  /// kOk, or kNotPositiveDefinite when no attempt was accepted.
  Status status = Status::kNotPositiveDefinite;
  /// delta of the accepted attempt (0 when none was needed; on failure the last one tried).
  double jitter = 0.0;
  /// Attempts that failed before the accepted one (on failure: the attempts made, minus one).
  int steps = 0;
};

/// s of JitterScale::kMeanDiagonal: max(mean of the diagonal of A, DBL_MIN). The absolute
/// jitter of that scale is result.jitter * MeanDiagonal(A).
double MeanDiagonal(const ConstMatrixRef& A);

/// A^{-1} = L^{-T} L^{-1} from the lower Cholesky factor L of A (only L's lower triangle is
/// read), as a full symmetric matrix: the matrix an evidence's gradient needs
/// (tr(A^{-1} dA / d theta)). Two blocked recursions, each about n^3 / 3 flops: L^{-1} in
/// place (the triangular inverse), then the lower triangle of L^{-T} L^{-1}; in all about a
/// third of solving A X = I with the factor (2 n^3). Allocates the result and the recursions'
/// temporaries; not for a real-time path. L must have a nonzero diagonal. With num_threads > 1
/// (from 256 rows on) the two steps run in fixed chunks of columns on that many threads, with
/// an n x n temporary more; the result is the same for every thread count from two on and
/// equals the one-thread result up to rounding. Throws std::invalid_argument on a non-square L
/// or num_threads < 1.
Matrix InverseFromFactor(const ConstMatrixRef& L, int num_threads = 1);

/// L L^T = A + J for symmetric positive definite A (only its lower triangle is read).
///
/// Invariant after an accepted Factorize: factor() is lower-triangular (strictly upper part
/// exactly zero) with a positive, finite diagonal. The solves use the same Eigen kernels, in
/// the same order, as Eigen::LLT<Matrix, Eigen::Lower>, so their results are bit-identical to
/// Eigen's.
class Cholesky {
 public:
  Cholesky() = default;
  /// Reserves the factor for n x n matrices.
  explicit Cholesky(Eigen::Index n) : factor_(Matrix::Zero(n, n)) {}

  /// Factorises A (square; throws std::invalid_argument otherwise) with the policy of the
  /// file comment. Replaces the previous factor.
  CholeskyResult Factorize(const ConstMatrixRef& A, const CholeskyOptions& options = {});

  bool ok() const { return result_.status == Status::kOk; }
  const CholeskyResult& result() const { return result_; }
  Eigen::Index size() const { return factor_.rows(); }

  /// L (zero after a failed Factorize).
  const Matrix& factor() const { return factor_; }
  /// Moves L out (the object is then empty).
  Matrix ReleaseFactor() {
    result_ = CholeskyResult();
    return std::move(factor_);
  }
  /// L as a triangular view, as Eigen::LLT::matrixL().
  Eigen::TriangularView<const Matrix, Eigen::Lower> matrixL() const {
    return factor_.triangularView<Eigen::Lower>();
  }
  /// L^T as a triangular view, as Eigen::LLT::matrixU().
  Eigen::TriangularView<const Eigen::Transpose<const Matrix>, Eigen::Upper> matrixU() const {
    return factor_.adjoint().triangularView<Eigen::Upper>();
  }
  /// (L L^T)^{-1} b, as Eigen::LLT::solve.
  template <typename Rhs>
  typename Rhs::PlainObject solve(const Eigen::MatrixBase<Rhs>& b) const {
    typename Rhs::PlainObject x = b;
    SolveInPlace(x);
    return x;
  }
  /// x <- (L L^T)^{-1} x; allocation-free for a vector.
  template <typename Derived>
  void SolveInPlace(Eigen::MatrixBase<Derived>& x) const {
    matrixL().solveInPlace(x);
    matrixU().solveInPlace(x);
  }

 private:
  Matrix factor_;
  CholeskyResult result_;
};

}  // namespace internal
}  // namespace structgp

#endif  // STRUCTGP_INTERNAL_CHOLESKY_H_
