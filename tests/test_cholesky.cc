// The library's one positive-definite factorisation (internal/cholesky.h): the factor against
// Eigen's LLT (bit-identical) and against A itself (L L^T = A + J to the backward-error bound),
// the jitter ladder on rank-deficient and slightly indefinite matrices (status, the rung used,
// never NaN), matrices that no jitter rescues (status and a zero factor), the pivot floor that
// Eigen alone does not apply, scale invariance, bad arguments, and no allocation; and the
// workers that the threaded factorisation runs on when a thread cannot be started.

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstdint>
#include <iostream>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <system_error>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Cholesky>
#include <Eigen/QR>

#include "alloc_counter.h"
#include "structgp/internal/cholesky.h"
#include "structgp/internal/workers.h"

namespace structgp {
namespace {

using internal::Cholesky;
using internal::CholeskyOptions;
using internal::CholeskyResult;
using internal::JitterLadder;
using internal::JitterScale;

constexpr double kEps = DBL_EPSILON;

std::mt19937_64 SeededRng(std::uint64_t seed) {
  std::cout << "[ seed     ] " << seed << std::endl;
  return std::mt19937_64(seed);
}

Matrix RandomMatrix(int rows, int cols, std::mt19937_64* rng) {
  std::normal_distribution<double> normal(0.0, 1.0);
  return Matrix::NullaryExpr(rows, cols, [&]() { return normal(*rng); });
}

// Q diag(eigenvalues) Q^T with a random orthogonal Q, symmetrised exactly.
Matrix WithSpectrum(const Vector& eigenvalues, std::mt19937_64* rng) {
  const int n = static_cast<int>(eigenvalues.size());
  const Matrix Q = Eigen::HouseholderQR<Matrix>(RandomMatrix(n, n, rng)).householderQ();
  const Matrix A = Q * eigenvalues.asDiagonal() * Q.transpose();
  return 0.5 * (A + A.transpose());
}

// The rungs of the ladder, computed as the header defines them.
double Rung(int k) {
  double rung = internal::kJitterFirst;
  for (int i = 0; i < k; ++i) rung *= internal::kJitterGrowth;
  return rung;
}

// Backward error of Cholesky (Higham, Accuracy and Stability, Thm 10.3): the computed L has
// L L^T = M + E with |E| <= gamma_{n+1} |L| |L^T|, gamma_k = k eps / (1 - k eps), and by
// Cauchy-Schwarz (|L| |L^T|)_ij <= ||L_i|| ||L_j|| = sqrt((L L^T)_ii (L L^T)_jj). The entrywise
// bound used below, 2 gamma_{n+1} sqrt(M_ii M_jj), allows for the rounding of M_ii itself.
void ExpectReconstructs(const Matrix& L, const Matrix& M) {
  const int n = static_cast<int>(M.rows());
  const double gamma = (n + 1) * kEps / (1.0 - (n + 1) * kEps);
  const Matrix LLt = L * L.transpose();
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const double bound = 2.0 * gamma * std::sqrt(M(i, i) * M(j, j));
      ASSERT_LE(std::abs(LLt(i, j) - M(i, j)), bound) << "entry (" << i << ", " << j << ")";
    }
  }
}

// The documented state of an accepted factor: lower-triangular, strictly upper part exactly
// zero, positive finite diagonal.
void ExpectValidFactor(const Matrix& L) {
  ASSERT_TRUE(L.allFinite());
  for (Eigen::Index j = 0; j < L.cols(); ++j) {
    EXPECT_GT(L(j, j), 0.0) << "pivot " << j;
    for (Eigen::Index i = 0; i < j; ++i) ASSERT_EQ(L(i, j), 0.0) << "(" << i << ", " << j << ")";
  }
}

// A well-conditioned and a wide-spectrum (cond 1e10) matrix, at a scale far from 1: no jitter,
// and the factor is Eigen's LLT bit for bit (the callers' results depend on it), with the solve
// bit-identical too; L L^T = A to the backward-error bound.
TEST(Cholesky, MatchesEigenBitForBitAndReconstructsA) {
  auto rng = SeededRng(11);
  for (const double decades : {2.0, 10.0}) {
    SCOPED_TRACE("spectrum over " + std::to_string(decades) + " decades");
    const int n = 60;
    Vector spectrum(n);
    for (int i = 0; i < n; ++i) spectrum[i] = 1e3 * std::pow(10.0, -decades * i / (n - 1));
    const Matrix A = WithSpectrum(spectrum, &rng);
    Cholesky chol;
    const CholeskyResult result = chol.Factorize(A);
    ASSERT_EQ(result.status, Status::kOk);
    EXPECT_TRUE(chol.ok());
    EXPECT_EQ(result.jitter, 0.0);
    EXPECT_EQ(result.steps, 0);
    ExpectValidFactor(chol.factor());
    const Eigen::LLT<Matrix, Eigen::Lower> reference(A);
    ASSERT_EQ(reference.info(), Eigen::Success);
    const Matrix L_reference = reference.matrixL();
    EXPECT_TRUE(chol.factor() == L_reference) << "factor differs from Eigen's LLT";
    ExpectReconstructs(chol.factor(), A);
    const Matrix B = RandomMatrix(n, 3, &rng);
    EXPECT_TRUE(chol.solve(B) == reference.solve(B)) << "solve differs from Eigen's LLT";
    const Matrix from_views = chol.matrixU().solve(chol.matrixL().solve(B));
    EXPECT_TRUE(from_views == chol.solve(B));
  }
}

// A rank-deficient Gram matrix (n = 40 points in a 10-dimensional feature space): singular to
// working precision, so the first attempt fails the pivot floor; a rung of the ladder rescues it,
// the result says which, and the factor is that of A + delta diag(A), exactly as documented.
TEST(Cholesky, LadderRescuesARankDeficientMatrixAndReportsTheRung) {
  auto rng = SeededRng(12);
  const int n = 40;
  const Matrix F = RandomMatrix(n, 10, &rng);
  const Matrix A = F * F.transpose();
  Cholesky chol;
  const CholeskyResult result = chol.Factorize(A);
  ASSERT_EQ(result.status, Status::kOk);
  ASSERT_GE(result.steps, 1);
  ASSERT_LE(result.steps, internal::kMaxJitterSteps);
  EXPECT_EQ(result.jitter, Rung(result.steps - 1));
  ExpectValidFactor(chol.factor());
  Matrix jittered = A;
  jittered.diagonal() = (1.0 + result.jitter) * A.diagonal();
  ExpectReconstructs(chol.factor(), jittered);
  const Matrix L_reference = Eigen::LLT<Matrix, Eigen::Lower>(jittered).matrixL();
  EXPECT_TRUE(chol.factor() == L_reference);

  // Without the ladder the same matrix is refused: status, zero factor, no NaN.
  CholeskyOptions exact;
  exact.ladder = JitterLadder::kNone;
  const CholeskyResult refused = chol.Factorize(A, exact);
  EXPECT_EQ(refused.status, Status::kNotPositiveDefinite);
  EXPECT_FALSE(chol.ok());
  EXPECT_EQ(refused.jitter, 0.0);
  EXPECT_EQ(refused.steps, 0);
  EXPECT_TRUE(chol.factor().isZero(0.0));
}

// Slightly indefinite (smallest eigenvalue -1e-8 of a unit spectrum, e.g. a kernel matrix with
// rounding): the rungs 1e-11 and 1e-9 of the diagonal cannot lift it, 1e-7 can. The ladder takes
// exactly the third rung.
TEST(Cholesky, LadderClimbsToTheFirstRungThatMakesAnIndefiniteMatrixDefinite) {
  auto rng = SeededRng(13);
  const int n = 30;
  Vector spectrum = Vector::Ones(n);
  spectrum[n - 1] = -1e-8;
  const Matrix A = WithSpectrum(spectrum, &rng);
  ASSERT_GT(A.diagonal().minCoeff(), 0.5);  // so 1e-9 diag(A) < 1e-8 < 1e-7 diag(A)
  Cholesky chol;
  const CholeskyResult result = chol.Factorize(A);
  ASSERT_EQ(result.status, Status::kOk);
  EXPECT_EQ(result.steps, 3);
  EXPECT_EQ(result.jitter, Rung(2));
  ExpectValidFactor(chol.factor());
  Matrix jittered = A;
  jittered.diagonal() = (1.0 + result.jitter) * A.diagonal();
  ExpectReconstructs(chol.factor(), jittered);
}

// Clearly indefinite (an eigenvalue -1), NaN on the diagonal, NaN off it, Inf: no jitter of
// the ladder rescues these. Status kNotPositiveDefinite, the factor set to zero (never NaN).
TEST(Cholesky, MatricesNoJitterRescuesEndInAStatusAndAZeroFactor) {
  auto rng = SeededRng(14);
  const int n = 12;
  Vector spectrum = Vector::Ones(n);
  spectrum[0] = -1.0;
  const Matrix indefinite = WithSpectrum(spectrum, &rng);
  Matrix nan_diagonal = WithSpectrum(Vector::Ones(n), &rng);
  nan_diagonal(4, 4) = std::numeric_limits<double>::quiet_NaN();
  Matrix nan_off_diagonal = WithSpectrum(Vector::Ones(n), &rng);
  nan_off_diagonal(7, 2) = std::numeric_limits<double>::quiet_NaN();
  Matrix inf_off_diagonal = WithSpectrum(Vector::Ones(n), &rng);
  inf_off_diagonal(9, 3) = std::numeric_limits<double>::infinity();

  Cholesky chol(n);
  CholeskyResult result = chol.Factorize(indefinite);
  EXPECT_EQ(result.status, Status::kNotPositiveDefinite);
  EXPECT_EQ(result.steps, internal::kMaxJitterSteps);
  EXPECT_EQ(result.jitter, Rung(internal::kMaxJitterSteps - 1));  // the last one tried
  EXPECT_TRUE(chol.factor().isZero(0.0));

  result = chol.Factorize(nan_diagonal);
  EXPECT_EQ(result.status, Status::kNotPositiveDefinite);
  EXPECT_EQ(result.steps, 0) << "a NaN diagonal is not retried";
  EXPECT_TRUE(chol.factor().isZero(0.0));

  for (const Matrix* bad : {&nan_off_diagonal, &inf_off_diagonal}) {
    result = chol.Factorize(*bad);
    EXPECT_EQ(result.status, Status::kNotPositiveDefinite);
    EXPECT_FALSE(chol.ok());
    EXPECT_TRUE(chol.factor().isZero(0.0));
  }
}

// A pivot lost to rounding that Eigen's LLT accepts (it only refuses pivots <= 0): A =
// [[1, 1], [1, 1 + 4 eps]] has L_11^2 / A_11 = 4 eps < kMinPivotRatio. The module refuses it
// without the ladder and takes the first rung with it; scaling A by any diagonal D (features
// in other units) changes neither outcome.
TEST(Cholesky, PivotFloorCatchesWhatEigenAcceptsAndIsScaleInvariant) {
  Matrix A(2, 2);
  A << 1.0, 1.0, 1.0, 1.0 + 4 * kEps;
  ASSERT_EQ(Eigen::LLT<Matrix>(A).info(), Eigen::Success);
  CholeskyOptions exact;
  exact.ladder = JitterLadder::kNone;
  for (const double scale : {1.0, 1e-150, 1e150}) {
    SCOPED_TRACE("D = diag(1, " + std::to_string(scale) + ")");
    const Vector d = Eigen::Vector2d(1.0, scale);
    const Matrix scaled = d.asDiagonal() * A * d.asDiagonal();
    Cholesky chol;
    EXPECT_EQ(chol.Factorize(scaled, exact).status, Status::kNotPositiveDefinite);
    const CholeskyResult result = chol.Factorize(scaled);
    ASSERT_EQ(result.status, Status::kOk);
    EXPECT_EQ(result.steps, 1);
    EXPECT_EQ(result.jitter, internal::kJitterFirst);
    ExpectValidFactor(chol.factor());
  }
}

// JitterScale::kMeanDiagonal with a floor, as NystromFeatureMap uses it: duplicate points make
// the Gram matrix singular; the floor alone is added (no rung needed), as a multiple of the
// identity, and the factor is Eigen's of K + (floor * MeanDiagonal(K)) I bit for bit.
TEST(Cholesky, MeanDiagonalFloorIsAlwaysAddedAsAMultipleOfTheIdentity) {
  auto rng = SeededRng(15);
  const int n = 20;
  Matrix F = RandomMatrix(n, 30, &rng);
  F.row(7) = F.row(3);  // a duplicate point
  F.row(0) *= 10.0;     // an uneven diagonal: the mean differs from each entry
  const Matrix K = F * F.transpose();
  CholeskyOptions options;
  options.scale = JitterScale::kMeanDiagonal;
  options.min_jitter = 1e-8;
  Cholesky chol;
  const CholeskyResult result = chol.Factorize(K, options);
  ASSERT_EQ(result.status, Status::kOk);
  EXPECT_EQ(result.steps, 0);
  EXPECT_EQ(result.jitter, 1e-8);
  EXPECT_EQ(internal::MeanDiagonal(K), K.diagonal().mean());
  Matrix jittered = K;
  jittered.diagonal().array() += result.jitter * internal::MeanDiagonal(K);
  const Matrix L_reference = Eigen::LLT<Matrix, Eigen::Lower>(jittered).matrixL();
  EXPECT_TRUE(chol.factor() == L_reference);
  ExpectReconstructs(chol.factor(), jittered);

  // Rungs at or below the floor are skipped: a matrix the floor cannot lift goes to 1e-7 next.
  Vector spectrum = Vector::Ones(n);
  spectrum[0] = -5e-8;
  const Matrix indefinite = WithSpectrum(spectrum, &rng);
  const CholeskyResult climbed = chol.Factorize(indefinite, options);
  ASSERT_EQ(climbed.status, Status::kOk);
  EXPECT_EQ(climbed.steps, 1);
  EXPECT_EQ(climbed.jitter, Rung(2));
}

// The inverse from the factor against the factor's solve of A X = I (an independent route:
// two triangular solves), at sizes on both sides of the recursions' block (96) and odd splits;
// A^{-1} A = I to rounding of the condition number; exactly symmetric.
TEST(Cholesky, InverseFromFactorEqualsSolvingForTheIdentity) {
  std::mt19937_64 rng = SeededRng(41);
  std::uniform_real_distribution<double> log_eigenvalue(-4.0, 2.0);
  for (int n : {1, 2, 7, 95, 96, 97, 193, 250, 517}) {
    const Vector eigenvalues =
        Vector::NullaryExpr(n, [&]() { return std::pow(10.0, log_eigenvalue(rng)); });
    const Matrix A = 3.7e2 * WithSpectrum(eigenvalues, &rng);
    Cholesky chol;
    ASSERT_EQ(chol.Factorize(A, {JitterLadder::kNone}).status, Status::kOk) << "n = " << n;
    const Matrix reference = chol.solve(Matrix::Identity(n, n));
    const Matrix inverse = internal::InverseFromFactor(chol.factor());
    ASSERT_EQ(inverse.rows(), n);
    ASSERT_EQ(inverse.cols(), n);
    EXPECT_EQ((inverse - inverse.transpose()).cwiseAbs().maxCoeff(), 0.0) << "n = " << n;
    // cond(A) <= 1e6: both routes agree to ~cond * n * eps of the inverse's size.
    const double scale = reference.cwiseAbs().maxCoeff();
    EXPECT_LE((inverse - reference).cwiseAbs().maxCoeff(), 1e6 * n * kEps * scale) << "n = " << n;
    EXPECT_LE((inverse * A - Matrix::Identity(n, n)).cwiseAbs().maxCoeff(), 1e6 * n * kEps)
        << "n = " << n;
  }
  // Only the lower triangle of the factor is read.
  const Matrix A = WithSpectrum(Vector::LinSpaced(130, 1.0, 5.0), &rng);
  Cholesky chol;
  ASSERT_TRUE(chol.Factorize(A).status == Status::kOk);
  Matrix L = chol.factor();
  L.triangularView<Eigen::StrictlyUpper>().setConstant(std::nan(""));
  EXPECT_TRUE(internal::InverseFromFactor(L).isApprox(chol.solve(Matrix::Identity(130, 130)),
                                                      1e-12));
  EXPECT_THROW(internal::InverseFromFactor(Matrix::Zero(3, 2)), std::invalid_argument);
}

// More than one thread (internal/cholesky.h): from 256 rows on a blocked factorisation and a
// column-split inverse on the threads. Against the backward-error bound and the one-thread
// results (Eigen's LLT, the recursive inverse): equal up to rounding at every thread count and
// bit for bit among thread counts from two on, on sizes around the threshold and the panel
// width, with the ladder and failures as one thread reports them.
TEST(Cholesky, ThreadsGiveTheOneThreadFactorAndInverseUpToRounding) {
  std::mt19937_64 rng = SeededRng(43);
  std::uniform_real_distribution<double> log_eigenvalue(-2.0, 2.0);
  for (int n : {255, 256, 300, 384, 517}) {
    const Vector eigenvalues =
        Vector::NullaryExpr(n, [&]() { return std::pow(10.0, log_eigenvalue(rng)); });
    Matrix A = 2.5e3 * WithSpectrum(eigenvalues, &rng);
    // Only the lower triangle is read, on every path.
    Matrix A_upper_nan = A;
    A_upper_nan.triangularView<Eigen::StrictlyUpper>().setConstant(std::nan(""));
    Cholesky one;
    ASSERT_EQ(one.Factorize(A, {JitterLadder::kNone}).status, Status::kOk);
    const Matrix inverse_one = internal::InverseFromFactor(one.factor());
    CholeskyOptions two_threads{JitterLadder::kNone};
    two_threads.num_threads = 2;
    Cholesky two;
    ASSERT_EQ(two.Factorize(A, two_threads).status, Status::kOk);
    const Matrix inverse_two = internal::InverseFromFactor(two.factor(), 2);
    for (int threads : {2, 3, 8}) {
      SCOPED_TRACE("n = " + std::to_string(n) + ", threads = " + std::to_string(threads));
      CholeskyOptions options{JitterLadder::kNone};
      options.num_threads = threads;
      Cholesky many;
      const CholeskyResult result = many.Factorize(A_upper_nan, options);
      ASSERT_EQ(result.status, Status::kOk);
      EXPECT_EQ(result.steps, 0);
      // From 256 rows on the blocked path runs: its rounding differs from Eigen's LLT.
      if (n >= 256) {
        EXPECT_FALSE(many.factor() == one.factor()) << "the threaded path did not run";
      }
      ExpectValidFactor(many.factor());
      ExpectReconstructs(many.factor(), A);
      const double scale = one.factor().cwiseAbs().maxCoeff();
      EXPECT_LE((many.factor() - one.factor()).cwiseAbs().maxCoeff(), 1e4 * n * kEps * scale);
      Matrix L = many.factor();
      L.triangularView<Eigen::StrictlyUpper>().setConstant(std::nan(""));
      const Matrix inverse = internal::InverseFromFactor(L, threads);
      EXPECT_EQ((inverse - inverse.transpose()).cwiseAbs().maxCoeff(), 0.0);
      const double inverse_scale = inverse_one.cwiseAbs().maxCoeff();
      EXPECT_LE((inverse - inverse_one).cwiseAbs().maxCoeff(), 1e4 * n * kEps * inverse_scale);
      EXPECT_LE((inverse * A - Matrix::Identity(n, n)).cwiseAbs().maxCoeff(), 1e4 * n * kEps);
      // The threads share fixed chunks: the same bits from two threads on.
      EXPECT_TRUE(many.factor() == two.factor());
      EXPECT_TRUE(inverse == inverse_two);
    }
  }
  // The ladder on threads: a Gram matrix of rank 40 at n = 300 needs the same rung as on one
  // thread; an indefinite matrix ends in the status and a zero factor.
  const Matrix features = RandomMatrix(300, 40, &rng);
  const Matrix gram = features * features.transpose();
  Cholesky one;
  const CholeskyResult one_result = one.Factorize(gram);
  ASSERT_EQ(one_result.status, Status::kOk);
  ASSERT_GT(one_result.steps, 0);
  CholeskyOptions options;
  options.num_threads = 2;
  Cholesky many;
  const CholeskyResult result = many.Factorize(gram, options);
  ASSERT_EQ(result.status, Status::kOk);
  EXPECT_EQ(result.steps, one_result.steps);
  EXPECT_EQ(result.jitter, one_result.jitter);
  Matrix jittered = gram;
  jittered.diagonal() = (1.0 + result.jitter) * gram.diagonal();
  ExpectReconstructs(many.factor(), jittered);
  Vector spectrum = Vector::Ones(300);
  spectrum[150] = -1.0;
  const CholeskyResult failed = many.Factorize(WithSpectrum(spectrum, &rng), options);
  EXPECT_EQ(failed.status, Status::kNotPositiveDefinite);
  EXPECT_EQ(many.factor().cwiseAbs().maxCoeff(), 0.0);
}

// A thread that cannot be started (std::thread throws at the system's thread limit) costs
// time, not the result: its items run on the calling thread. Starts fail after `allowed`.
struct FailingStart {
  int allowed = 0;
  mutable int calls = 0;
  template <typename Run>
  std::thread operator()(Run&& run) const {
    if (calls++ >= allowed) {
      throw std::system_error(std::make_error_code(std::errc::resource_unavailable_try_again),
                              "thread limit");
    }
    return std::thread(std::forward<Run>(run));
  }
};

TEST(Workers, ItemsWithoutAThreadRunOnTheCallingThreadOnce) {
  const std::thread::id caller = std::this_thread::get_id();
  for (int allowed : {0, 1, 2, 5}) {
    SCOPED_TRACE("threads allowed: " + std::to_string(allowed));
    const int workers = 5;
    std::vector<int> runs(workers, 0);
    std::vector<std::thread::id> ran_on(workers);
    FailingStart start{allowed};
    internal::RunWorkers(workers, [&](int w) {
      ++runs[static_cast<size_t>(w)];
      ran_on[static_cast<size_t>(w)] = std::this_thread::get_id();
    }, start);
    EXPECT_EQ(start.calls, std::min(allowed + 1, workers - 1));
    for (int w = 0; w < workers; ++w) {
      EXPECT_EQ(runs[static_cast<size_t>(w)], 1) << "item " << w;
      // Item 0 and the items past the last started thread run on the caller, the others not.
      const bool on_caller = w == 0 || w > allowed;
      EXPECT_EQ(ran_on[static_cast<size_t>(w)] == caller, on_caller) << "item " << w;
    }
  }
}

TEST(Workers, AnItemsExceptionIsRethrownAfterEveryItemRan) {
  for (int allowed : {0, 4}) {
    std::vector<int> runs(5, 0);
    try {
      internal::RunWorkers(5, [&](int w) {
        ++runs[static_cast<size_t>(w)];
        if (w == 1 || w == 3) throw std::runtime_error("item " + std::to_string(w));
      }, FailingStart{allowed});
      ADD_FAILURE() << "no exception";
    } catch (const std::runtime_error& e) {
      EXPECT_EQ(std::string(e.what()), "item 1");  // the first by index
    }
    EXPECT_EQ(runs, std::vector<int>(5, 1));
  }
}

TEST(Cholesky, BadArgumentsThrowNamingTheProblem) {
  Cholesky chol;
  try {
    chol.Factorize(Matrix::Identity(3, 4));
    FAIL() << "a non-square matrix was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("expected a square matrix, got 3 x 4"), std::string::npos)
        << e.what();
  }
  CholeskyOptions options;
  options.min_jitter = -1.0;
  EXPECT_THROW(chol.Factorize(Matrix::Identity(2, 2), options), std::invalid_argument);
  options.min_jitter = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(chol.Factorize(Matrix::Identity(2, 2), options), std::invalid_argument);
  options.min_jitter = 0.0;
  options.num_threads = 0;
  try {
    chol.Factorize(Matrix::Identity(2, 2), options);
    FAIL() << "num_threads = 0 was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("num_threads: expected >= 1, got 0"), std::string::npos)
        << e.what();
  }
  EXPECT_THROW(internal::InverseFromFactor(Matrix::Identity(2, 2), 0), std::invalid_argument);
  // The empty matrix is positive definite.
  EXPECT_EQ(chol.Factorize(Matrix(0, 0)).status, Status::kOk);
}

// The header's promise: after construction for size n, Factorize of an n x n matrix (success,
// the ladder, failure) and SolveInPlace of a vector allocate nothing (n within the sizes for
// which Eigen's blocked LLT needs no workspace of its own).
TEST(Cholesky, FactorizeAndSolveAllocateNothingAfterConstruction) {
  auto rng = SeededRng(16);
  const int n = 64;
  const Matrix good = WithSpectrum(Vector::LinSpaced(n, 1.0, 2.0), &rng);
  const Matrix F = RandomMatrix(n, 8, &rng);
  const Matrix singular = F * F.transpose();
  Vector spectrum = Vector::Ones(n);
  spectrum[0] = -1.0;
  const Matrix indefinite = WithSpectrum(spectrum, &rng);
  Vector x = Vector::Ones(n);
  Cholesky chol(n);
  CholeskyResult results[3];
  {
    testing::AllocationCounter guard;
    results[0] = chol.Factorize(good);
    chol.SolveInPlace(x);
    results[1] = chol.Factorize(singular);
    results[2] = chol.Factorize(indefinite);
    if (testing::CountsEveryAllocation()) {
      EXPECT_EQ(guard.count(), 0u);
    }
  }
  EXPECT_EQ(results[0].status, Status::kOk);
  EXPECT_EQ(results[1].status, Status::kOk);
  EXPECT_GT(results[1].jitter, 0.0);
  EXPECT_EQ(results[2].status, Status::kNotPositiveDefinite);
  EXPECT_TRUE(x.allFinite());
  if (!testing::CountsEveryAllocation()) GTEST_SKIP() << testing::kIncompleteCountReason;
}

}  // namespace
}  // namespace structgp
