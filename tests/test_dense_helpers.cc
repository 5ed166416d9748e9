// The library's one Gram routine (internal/gram.h) against direct Kernel::Evaluate calls, the
// public Kernel::Gram on rows against it, and the summation orders of internal/simd.h.

#include <cstdint>
#include <iostream>
#include <random>
#include <stdexcept>

#include <gtest/gtest.h>

#include "structgp/internal/gram.h"
#include "structgp/internal/simd.h"
#include "structgp/kernel/rbf_kernel.h"

namespace structgp {
namespace {

Matrix RandomPoints(int input_dim, int n, std::uint64_t seed) {
  std::cout << "[ seed     ] " << seed << std::endl;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  return Matrix::NullaryExpr(input_dim, n, [&]() { return normal(rng); });
}

// Every entry is exactly one Evaluate call with the documented argument order, and the
// symmetric form equals the rectangular one (the kernel is symmetric in IEEE arithmetic).
TEST(KernelGram, EqualsDirectEvaluationsInBothForms) {
  const RbfKernel kernel(3, /*ard=*/true, 0.7, 1.3);
  const Matrix A = RandomPoints(3, 9, 21);
  const Matrix B = RandomPoints(3, 5, 22);
  Matrix K;
  internal::KernelGram(kernel, A, B, &K);
  ASSERT_EQ(K.rows(), 9);
  ASSERT_EQ(K.cols(), 5);
  for (int i = 0; i < 9; ++i) {
    for (int j = 0; j < 5; ++j) {
      ASSERT_EQ(K(i, j), kernel.Evaluate(A.col(i), B.col(j))) << "(" << i << ", " << j << ")";
    }
  }
  Matrix S;
  internal::KernelGram(kernel, A, &S);
  ASSERT_EQ(S.rows(), 9);
  ASSERT_EQ(S.cols(), 9);
  for (int i = 0; i < 9; ++i) {
    for (int j = i; j < 9; ++j) {
      ASSERT_EQ(S(i, j), kernel.Evaluate(A.col(i), A.col(j))) << "(" << i << ", " << j << ")";
      ASSERT_EQ(S(j, i), S(i, j));
    }
  }
  Matrix full;
  internal::KernelGram(kernel, A, A, &full);
  EXPECT_TRUE(full == S);
  // The public form takes points as rows and gives the same matrix.
  Matrix from_rows;
  kernel.Gram(A.transpose(), B.transpose(), &from_rows);
  EXPECT_TRUE(from_rows == K);
}

TEST(KernelGram, WrongInputDimensionThrows) {
  const RbfKernel kernel(3);
  Matrix K;
  EXPECT_THROW(internal::KernelGram(kernel, Matrix::Zero(2, 4), &K), std::invalid_argument);
  EXPECT_THROW(internal::KernelGram(kernel, Matrix::Zero(3, 4), Matrix::Zero(4, 2), &K),
               std::invalid_argument);
}

#if defined(STRUCTGP_HAVE_PACKET4)
// The two horizontal sums are different orders, chosen on purpose: values whose sum depends on
// the order tell them apart (1e16 + 1 rounds to 1e16).
TEST(Simd, HorizontalSumsHaveTheirDocumentedOrder) {
  const double values[4] = {1e16, 1.0, -1e16, 1.0};
  const internal::simd::Packet4 v = internal::simd::Load4(values);
  EXPECT_EQ(internal::simd::SumPairs(v), (1e16 + 1.0) + (-1e16 + 1.0));
  EXPECT_EQ(internal::simd::SumPairs(v), 0.0);
  EXPECT_EQ(internal::simd::SumHalves(v), (1e16 + -1e16) + (1.0 + 1.0));
  EXPECT_EQ(internal::simd::SumHalves(v), 2.0);
  double out[4];
  internal::simd::Store4(out, v + internal::simd::Splat4(1.0));
  EXPECT_EQ(out[1], 2.0);
  EXPECT_EQ(out[3], 2.0);
}
#endif

}  // namespace
}  // namespace structgp
