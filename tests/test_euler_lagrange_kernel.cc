// The Euler-Lagrange kernel against its weight-space twin: the Lagrangian regressor (explicit
// basis functions of M and V, the Euler-Lagrange equations applied to each) with the prior
// variances that the kernel's trigonometric factors imply. Two independent computations of the
// same covariance, for every part, link and number of joints up to 6; and the kernel's own
// invariants (link-local parts, symmetry, positive semi-definiteness, no allocation).

#include "structgp/kernel/euler_lagrange_kernel.h"

#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>

#include <Eigen/Eigenvalues>
#include <gtest/gtest.h>

#include "alloc_counter.h"
#include "structgp/feature/lagrangian_regressor_map.h"

namespace structgp {
namespace {

Vector RandomState(int n, std::mt19937* rng) {
  std::uniform_real_distribution<double> u(-3.0, 3.0);
  return Vector::NullaryExpr(3 * n, [&]() { return u(*rng); });
}

Vector RandomWeights(int parts, std::mt19937* rng) {
  std::uniform_real_distribution<double> u(0.2, 3.0);
  return Vector::NullaryExpr(parts, [&]() { return u(*rng); });
}

// Psi(a) diag(v) Psi(b)^T.
Matrix WeightSpaceCovariance(const LagrangianRegressorMap& map, const Vector& v, const Vector& a,
                             const Vector& b) {
  const int n = map.num_outputs();
  Matrix pa(n, map.dim()), pb(n, map.dim());
  map.Evaluate(a, pa);
  map.Evaluate(b, pb);
  return pa * v.asDiagonal() * pb.transpose();
}

TEST(EulerLagrangeKernel, EqualsTheLagrangianRegressorWithItsPrior) {
  std::mt19937 rng(7);
  for (int n = 1; n <= 6; ++n) {
    const LagrangianRegressorMap map(n);
    for (double sigma : {0.4, 3.0, 40.0}) {
      const EulerLagrangeKernel kernel(n, sigma);
      // Every part weighted at random, then the whole chain's energies alone (link N's parts).
      Vector whole = Vector::Zero(2 * n);
      whole[n - 1] = 1.3;
      whole[2 * n - 1] = 0.7;
      for (const Vector& w : {RandomWeights(2 * n, &rng), whole}) {
        const Vector v = map.KernelPriorVariance(sigma, w);
        for (int pair = 0; pair < 3; ++pair) {
          const Vector a = RandomState(n, &rng);
          const Vector b = pair == 0 ? a : RandomState(n, &rng);
          Matrix K(n, n);
          kernel.Evaluate(a, b, w, K);
          const Matrix R = WeightSpaceCovariance(map, v, a, b);
          const double scale = R.cwiseAbs().maxCoeff();
          ASSERT_GT(scale, 0.0);
          EXPECT_LT((K - R).cwiseAbs().maxCoeff(), 1e-10 * scale)
              << "N = " << n << ", sigma = " << sigma << ", pair " << pair << "\nkernel\n"
              << K << "\nregressor\n"
              << R;
        }
      }
    }
  }
}

TEST(EulerLagrangeKernel, EachPartIsItsLinksWeightSpaceTwin) {
  // One part at a time: a wrong link assignment of a parameter (its earliest link, or the
  // factors of the angles past it) shows in some part even when the sum over parts hides it.
  std::mt19937 rng(11);
  const int n = 4;
  const LagrangianRegressorMap map(n);
  const EulerLagrangeKernel kernel(n, 2.0);
  for (int part = 0; part < kernel.num_parts(); ++part) {
    Vector w = Vector::Zero(2 * n);
    w[part] = 1.0;
    const Vector v = map.KernelPriorVariance(2.0, w);
    const Vector a = RandomState(n, &rng), b = RandomState(n, &rng);
    Matrix kin(n, n), pot(n, n);
    kernel.EvaluateLink(a, b, part % n, kin, pot);
    const Matrix K = part < n ? kin : pot;
    const Matrix R = WeightSpaceCovariance(map, v, a, b);
    EXPECT_LT((K - R).cwiseAbs().maxCoeff(), 1e-10 * R.cwiseAbs().maxCoeff())
        << kernel.part_names()[static_cast<size_t>(part)];
  }
}

TEST(EulerLagrangeKernel, PartsActOnTheirLinksJointsAndSumToTheKernel) {
  std::mt19937 rng(3);
  const int n = 5;
  const EulerLagrangeKernel kernel(n, 5.0);
  const Vector a = RandomState(n, &rng), b = RandomState(n, &rng);
  const Vector w = RandomWeights(2 * n, &rng);
  Matrix sum = Matrix::Zero(n, n), kin(n, n), pot(n, n);
  for (int link = 0; link < n; ++link) {
    kernel.EvaluateLink(a, b, link, kin, pot);
    EXPECT_GT(kin.topLeftCorner(link + 1, link + 1).cwiseAbs().maxCoeff(), 0.0);
    EXPECT_GT(pot.topLeftCorner(link + 1, link + 1).cwiseAbs().maxCoeff(), 0.0);
    const int rest = n - 1 - link;
    if (rest > 0) {
      EXPECT_EQ(kin.bottomRows(rest).cwiseAbs().maxCoeff(), 0.0) << "link " << link;
      EXPECT_EQ(kin.rightCols(rest).cwiseAbs().maxCoeff(), 0.0) << "link " << link;
      EXPECT_EQ(pot.bottomRows(rest).cwiseAbs().maxCoeff(), 0.0) << "link " << link;
      EXPECT_EQ(pot.rightCols(rest).cwiseAbs().maxCoeff(), 0.0) << "link " << link;
    }
    sum += w[link] * kin + w[n + link] * pot;
  }
  Matrix K(n, n);
  kernel.Evaluate(a, b, w, K);
  EXPECT_LT((K - sum).cwiseAbs().maxCoeff(), 1e-12 * sum.cwiseAbs().maxCoeff());
  EXPECT_EQ(kernel.part_names().front(), "kinetic 1");
  EXPECT_EQ(kernel.part_names().back(), "potential 5");
}

TEST(EulerLagrangeKernel, IsSymmetricAndPositiveSemiDefiniteAtSevenJoints) {
  std::mt19937 rng(5);
  const int n = 7, m = 30;
  const EulerLagrangeKernel kernel(n, 10.0);
  const Vector w = RandomWeights(2 * n, &rng);
  Matrix X(m, 3 * n);
  for (int s = 0; s < m; ++s) X.row(s) = RandomState(n, &rng).transpose();
  Matrix G(m * n, m * n), block(n, n), back(n, n);
  for (int s = 0; s < m; ++s) {
    for (int t = 0; t < m; ++t) {
      kernel.Evaluate(X.row(s).transpose(), X.row(t).transpose(), w, block);
      G.block(s * n, t * n, n, n) = block;
      kernel.Evaluate(X.row(t).transpose(), X.row(s).transpose(), w, back);
      ASSERT_LT((block - back.transpose()).cwiseAbs().maxCoeff(),
                1e-12 * block.cwiseAbs().maxCoeff() + 1e-300);
    }
  }
  const Eigen::SelfAdjointEigenSolver<Matrix> eig(G, Eigen::EigenvaluesOnly);
  EXPECT_GT(eig.eigenvalues().maxCoeff(), 0.0);
  EXPECT_GT(eig.eigenvalues().minCoeff(), -1e-10 * eig.eigenvalues().maxCoeff());
}

TEST(EulerLagrangeKernel, EvaluatesWithoutAllocating) {
  std::mt19937 rng(1);
  const int n = 7;
  const EulerLagrangeKernel kernel(n, 1.0);
  const Vector a = RandomState(n, &rng), b = RandomState(n, &rng), w = RandomWeights(2 * n, &rng);
  Matrix K(n, n), kin(n, n), pot(n, n);
  double sum = 0.0;
  {
    testing::AllocationCounter guard;
    for (int r = 0; r < 10; ++r) {
      kernel.Evaluate(a, b, w, K);
      kernel.EvaluateLink(a, b, r % n, kin, pot);
      sum += K(0, 0) + kin(0, 0) + pot(0, 0);
    }
    if (testing::CountsEveryAllocation()) {
      EXPECT_EQ(guard.count(), 0u);
    }
  }
  EXPECT_TRUE(std::isfinite(sum));
}

TEST(EulerLagrangeKernel, RejectsBadArguments) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_THROW(EulerLagrangeKernel(0, 1.0), std::invalid_argument);
  EXPECT_THROW(EulerLagrangeKernel(kMaxEulerLagrangeJoints + 1, 1.0), std::invalid_argument);
  for (double sigma : {0.0, -1.0, nan, inf}) {
    EXPECT_THROW(EulerLagrangeKernel(3, sigma), std::invalid_argument) << sigma;
  }
  const LagrangianRegressorMap map(3);
  EXPECT_THROW(map.KernelPriorVariance(1.0, Vector::Ones(5)), std::invalid_argument);
  EXPECT_THROW(map.KernelPriorVariance(0.0, Vector::Ones(6)), std::invalid_argument);
  Vector w = Vector::Ones(6);
  w[2] = -1.0;
  EXPECT_THROW(map.KernelPriorVariance(1.0, w), std::invalid_argument);
  w[2] = nan;
  EXPECT_THROW(map.KernelPriorVariance(1.0, w), std::invalid_argument);
  try {
    map.KernelPriorVariance(1.0, Vector::Ones(4));
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("expected 6 part weights, got 4"), std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace structgp
