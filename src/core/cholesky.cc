#include "structgp/internal/cholesky.h"

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Cholesky>

#include "structgp/internal/workers.h"

namespace structgp {
namespace internal {
namespace {

// Below this size a factorisation or inverse runs on the calling thread whatever num_threads.
constexpr Eigen::Index kParallelMinSize = 256;

// Width of the column (or row) chunks that the threads share: fixed, so that what each chunk
// computes, and so the result, does not depend on the number of threads.
constexpr Eigen::Index kChunk = 96;

// Columns factorised per step of the blocked factorisation (its trailing updates are
// products of this inner size).
constexpr Eigen::Index kPanel = 192;

struct Chunk {
  Eigen::Index begin, size;
};

// [0, n) in chunks of kChunk (the last one shorter).
std::vector<Chunk> Chunks(Eigen::Index n) {
  std::vector<Chunk> chunks;
  for (Eigen::Index c = 0; c < n; c += kChunk) chunks.push_back({c, std::min(kChunk, n - c)});
  return chunks;
}

// work(chunk) for every chunk, on at most num_threads threads: the chunks, by decreasing
// cost(chunk), each to the thread with the least cost so far (a fixed assignment; each chunk's
// result is the same whichever thread computes it).
template <typename Cost, typename Work>
void RunChunks(const std::vector<Chunk>& chunks, int num_threads, Cost&& cost, Work&& work) {
  const int workers = static_cast<int>(
      std::max<size_t>(1, std::min<size_t>(static_cast<size_t>(num_threads), chunks.size())));
  std::vector<size_t> order(chunks.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) {
    return cost(chunks[a]) > cost(chunks[b]);
  });
  std::vector<std::vector<size_t>> mine(static_cast<size_t>(workers));
  std::vector<double> load(static_cast<size_t>(workers), 0.0);
  for (size_t i : order) {
    const size_t w = static_cast<size_t>(std::min_element(load.begin(), load.end()) - load.begin());
    mine[w].push_back(i);
    load[w] += cost(chunks[i]);
  }
  RunWorkers(workers, [&](int w) {
    for (size_t i : mine[static_cast<size_t>(w)]) work(chunks[i]);
  });
}

// Right-looking blocked LLT of the lower triangle of M, in place (the strictly upper part is
// scratch): per panel of kPanel columns, Eigen's LLT of the diagonal block, the panel below it
// by a triangular solve (by chunks of rows), then the trailing lower triangle minus the panel
// times its transpose (by chunks of columns, each from its diagonal down). false when a
// diagonal block is not positive definite.
bool ParallelLltInPlace(Eigen::Ref<Matrix> M, int num_threads) {
  const Eigen::Index n = M.rows();
  for (Eigen::Index k = 0; k < n; k += kPanel) {
    const Eigen::Index b = std::min(kPanel, n - k);
    const Eigen::Index rest = n - k - b;
    Eigen::Ref<Matrix> diagonal = M.block(k, k, b, b);
    Eigen::LLT<Eigen::Ref<Matrix>, Eigen::Lower> llt(diagonal);
    if (llt.info() != Eigen::Success) return false;
    if (rest == 0) break;
    const auto L11 = M.block(k, k, b, b).triangularView<Eigen::Lower>();
    auto panel = M.block(k + b, k, rest, b);
    const std::vector<Chunk> chunks = Chunks(rest);
    // L21 = A21 L11^{-T}, rows independent.
    RunChunks(
        chunks, num_threads, [](const Chunk& c) { return static_cast<double>(c.size); },
        [&](const Chunk& c) {
          auto rows = panel.middleRows(c.begin, c.size);
          L11.transpose().solveInPlace<Eigen::OnTheRight>(rows);
        });
    // A22 -= L21 L21^T on the lower triangle.
    RunChunks(
        chunks, num_threads,
        [&](const Chunk& c) { return static_cast<double>(rest - c.begin) * c.size; },
        [&](const Chunk& c) {
          const auto below = panel.middleRows(c.begin, rest - c.begin);
          M.block(k + b + c.begin, k + b + c.begin, rest - c.begin, c.size).noalias() -=
              below * panel.middleRows(c.begin, c.size).transpose();
        });
  }
  return true;
}

// One attempt: factor = lower triangle of A with diagonal A_kk + delta s_k, factorised in
// place; true when accepted (the test of the header, against the unjittered A_kk).
bool Attempt(const ConstMatrixRef& A, JitterScale scale, double mean_diagonal, double delta,
             int num_threads, Matrix* factor) {
  const Eigen::Index n = A.rows();
  factor->triangularView<Eigen::Lower>() = A.triangularView<Eigen::Lower>();
  if (delta > 0.0) {
    if (scale == JitterScale::kDiagonal) {
      factor->diagonal() = (1.0 + delta) * A.diagonal();
    } else {
      factor->diagonal().array() += delta * mean_diagonal;
    }
  }
  if (num_threads > 1 && n >= kParallelMinSize) {
    if (!ParallelLltInPlace(*factor, num_threads)) return false;
  } else {
    // In place: Eigen's LLT on a Ref overwrites the lower triangle of *factor with L (and reads
    // nothing else).
    Eigen::LLT<Eigen::Ref<Matrix>, Eigen::Lower> llt(*factor);
    if (llt.info() != Eigen::Success) return false;
  }
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

Matrix InverseFromFactor(const ConstMatrixRef& L, int num_threads) {
  if (L.rows() != L.cols()) {
    throw std::invalid_argument("InverseFromFactor: expected a square factor, got " +
                                std::to_string(L.rows()) + " x " + std::to_string(L.cols()));
  }
  if (num_threads < 1) {
    throw std::invalid_argument("InverseFromFactor: expected num_threads >= 1, got " +
                                std::to_string(num_threads));
  }
  const Eigen::Index n = L.rows();
  if (num_threads > 1 && n >= kParallelMinSize) {
    // W = L^{-1} by chunks of columns (column c of W is zero above row c: L[c:, c:] W[c:, c] =
    // e), then the lower triangle of W^T W by chunks of columns (column c: W[c:, c:]^T W[c:, c]).
    const std::vector<Chunk> chunks = Chunks(n);
    const auto cost = [n](const Chunk& c) {
      const double rows = static_cast<double>(n - c.begin);
      return rows * rows * static_cast<double>(c.size);
    };
    Matrix W = Matrix::Zero(n, n);
    RunChunks(chunks, num_threads, cost, [&](const Chunk& c) {
      auto X = W.block(c.begin, c.begin, n - c.begin, c.size);
      X.topRows(c.size).setIdentity();
      const auto tail = L.block(c.begin, c.begin, n - c.begin, n - c.begin);
      tail.triangularView<Eigen::Lower>().solveInPlace(X);
    });
    Matrix M(n, n);
    RunChunks(chunks, num_threads, cost, [&](const Chunk& c) {
      const auto tail = W.block(c.begin, c.begin, n - c.begin, n - c.begin);
      const auto columns = W.block(c.begin, c.begin, n - c.begin, c.size);
      M.block(c.begin, c.begin, n - c.begin, c.size).noalias() =
          tail.triangularView<Eigen::Lower>().transpose() * columns;
    });
    M.triangularView<Eigen::StrictlyUpper>() = M.transpose();
    return M;
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
  if (options.num_threads < 1) {
    throw std::invalid_argument("CholeskyOptions::num_threads: expected >= 1, got " +
                                std::to_string(options.num_threads));
  }
  const Eigen::Index n = A.rows();
  if (factor_.rows() != n || factor_.cols() != n) factor_.resize(n, n);
  result_ = CholeskyResult();
  const bool diagonal_finite = A.diagonal().allFinite();
  const double mean_diagonal =
      options.scale == JitterScale::kMeanDiagonal && diagonal_finite ? MeanDiagonal(A) : 0.0;

  double delta = options.min_jitter;
  bool accepted = false;
  try {
    accepted = diagonal_finite &&
               Attempt(A, options.scale, mean_diagonal, delta, options.num_threads, &factor_);
    if (!accepted && diagonal_finite && options.ladder == JitterLadder::kClimb) {
      // The rungs, computed by repeated multiplication (the values fit_jitter() has always
      // reported), skipping those at or below min_jitter.
      double rung = kJitterFirst;
      for (int k = 0; k < kMaxJitterSteps && !accepted; ++k, rung *= kJitterGrowth) {
        if (rung <= options.min_jitter) continue;
        delta = rung;
        ++result_.steps;
        accepted = Attempt(A, options.scale, mean_diagonal, delta, options.num_threads, &factor_);
      }
    }
  } catch (...) {
    // An exception from the threaded path (an allocation of its chunk lists; a thread that
    // cannot start is not one: its chunks run on this thread): no half-done factor is left.
    factor_.setZero();
    throw;
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
