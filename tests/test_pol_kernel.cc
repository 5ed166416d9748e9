// PolFormulaKernel, the O(N) kernel form of k_pol: equal, value and gradient, to the kernel of
// the explicit map (FeatureKernel(PolFeatureMap)) for N = 1..4, with and without the gravity
// block; its terms equal the blocks of the map; gradient against central differences up to
// N = 7; parameter handling; and the same marginal likelihood and gradient in a KernelGP as the
// feature kernel. The generic invariants come from the kernel battery in test_kernels.cc.

#include <cmath>
#include <cstdint>
#include <iostream>
#include <memory>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Eigenvalues>

#include "alloc_counter.h"
#include "structgp/feature/pol_feature_map.h"
#include "structgp/feature/pol_kernel_formula.h"
#include "structgp/feature/feature_hyperparameters.h"
#include "structgp/kernel/feature_kernel.h"
#include "structgp/kernel/pol_kernel.h"
#include "structgp/model/kernel_gp.h"

namespace structgp {
namespace {

constexpr double kPi = 3.141592653589793;

std::mt19937_64 SeededRng(std::uint64_t seed) {
  std::cout << "[ seed     ] " << seed << std::endl;
  return std::mt19937_64(seed);
}

// A robot state: q uniform in [-pi, pi], qd and qdd standard normal.
Vector RandomState(int n, std::mt19937_64* rng) {
  std::uniform_real_distribution<double> angle(-kPi, kPi);
  std::normal_distribution<double> normal(0.0, 1.0);
  Vector x(3 * n);
  for (int j = 0; j < n; ++j) x[j] = angle(*rng);
  for (int j = n; j < 3 * n; ++j) x[j] = normal(*rng);
  return x;
}

// The same parameters for the feature kernel: shape (log sigma), block scales.
Hyperparameters ToHyper(const PolFeatureMap& map, const Vector& theta) {
  Hyperparameters h = DefaultHyperparameters(map, 1);
  h.shape[0] = theta[0];
  h.log_block_scale = theta.tail(theta.size() - 1);
  return h;
}

// Pairs that exercise the formula: random, a == b, a near-duplicate, and every angle
// difference pi (where 1 + theta cos d -> 0 as sigma -> 0).
std::vector<std::pair<Vector, Vector>> TestPairs(int n, std::mt19937_64* rng) {
  std::vector<std::pair<Vector, Vector>> pairs;
  for (int i = 0; i < 4; ++i) pairs.emplace_back(RandomState(n, rng), RandomState(n, rng));
  const Vector a = RandomState(n, rng);
  pairs.emplace_back(a, a);
  Vector near = a;
  near[0] += 1e-7;
  pairs.emplace_back(a, near);
  Vector opposite = RandomState(n, rng);
  opposite.head(n) = a.head(n).array() + kPi;
  pairs.emplace_back(a, opposite);
  return pairs;
}

// Parameter vectors: the default, small and large sigma, mixed block scales.
std::vector<Vector> TestParameters(int num_parameters, std::mt19937_64* rng) {
  std::vector<Vector> out;
  out.push_back(Vector::Zero(num_parameters));
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (double log_sigma : {-6.0, -1.3, 0.7, 4.0}) {
    Vector theta(num_parameters);
    theta[0] = log_sigma;
    for (int i = 1; i < num_parameters; ++i) theta[i] = u(*rng);
    out.push_back(theta);
  }
  return out;
}

// sum_k Lambda_k phi_k(a) phi_k(b) cancels: the rounding of both evaluations is bounded by
// a few eps times sum_k |Lambda_k phi_k(a) phi_k(b)| (D terms, but pairwise-like error growth
// in practice). 1e-12 of that sum is the required tolerance; observed errors are
// ~1e-15.
struct Reference {
  double value = 0.0;
  double magnitude = 0.0;     // sum |Lambda phi phi|
  Vector gradient;            // FeatureKernel::Gradient
  Vector gradient_magnitude;  // per parameter, sum of |terms|
  Vector block_value;         // per block, sum over the block
  Vector block_magnitude;
};

Reference FeatureReference(const std::shared_ptr<const PolFeatureMap>& map, const Vector& theta,
                           const Vector& a, const Vector& b) {
  const Hyperparameters h = ToHyper(*map, theta);
  FeatureKernel kernel(map, h);
  Matrix d_lambda;
  const Vector lambda = PriorVariance(*map, h, &d_lambda);
  Vector phi_a(map->dim()), phi_b(map->dim());
  map->Evaluate(a, phi_a);
  map->Evaluate(b, phi_b);
  const Vector product = phi_a.cwiseProduct(phi_b);
  const auto blocks = map->blocks();
  Reference r;
  r.value = kernel.Evaluate(a, b);
  r.magnitude = lambda.cwiseProduct(product).cwiseAbs().sum();
  r.gradient.resize(kernel.num_parameters());
  kernel.Gradient(a, b, r.gradient);
  r.gradient_magnitude.resize(kernel.num_parameters());
  r.gradient_magnitude[0] = d_lambda.col(0).cwiseProduct(product).cwiseAbs().sum();
  r.block_value.resize(static_cast<Eigen::Index>(blocks.size()));
  r.block_magnitude.resize(static_cast<Eigen::Index>(blocks.size()));
  for (size_t k = 0; k < blocks.size(); ++k) {
    const auto l = lambda.segment(blocks[k].begin, blocks[k].size);
    const auto p = product.segment(blocks[k].begin, blocks[k].size);
    r.block_value[static_cast<Eigen::Index>(k)] = l.dot(p);
    r.block_magnitude[static_cast<Eigen::Index>(k)] = l.cwiseProduct(p).cwiseAbs().sum();
    r.gradient_magnitude[static_cast<Eigen::Index>(k) + 1] =
        2.0 * r.block_magnitude[static_cast<Eigen::Index>(k)];
  }
  return r;
}

void CheckAgainstFeatureKernel(int n, bool with_gravity, std::uint64_t seed) {
  SCOPED_TRACE("N = " + std::to_string(n) + (with_gravity ? ", gravity" : ", no gravity"));
  PolOptions options;
  options.include_gravity = with_gravity;
  const auto map = std::make_shared<PolFeatureMap>(n, options);
  PolFormulaKernel kernel(n, options);
  ASSERT_EQ(kernel.num_parameters(), 1 + static_cast<int>(map->blocks().size()));
  auto rng = SeededRng(seed);
  const auto pairs = TestPairs(n, &rng);
  double worst = 0.0;
  for (const Vector& theta : TestParameters(kernel.num_parameters(), &rng)) {
    kernel = Reparameterized(kernel, theta);
    for (size_t p = 0; p < pairs.size(); ++p) {
      SCOPED_TRACE("pair " + std::to_string(p) + ", log sigma " + std::to_string(theta[0]));
      const Vector& a = pairs[p].first;
      const Vector& b = pairs[p].second;
      const Reference ref = FeatureReference(map, theta, a, b);
      const double value = kernel.Evaluate(a, b);
      EXPECT_NEAR(value, ref.value, 1e-12 * ref.magnitude);
      worst = std::max(worst, std::abs(value - ref.value) / ref.magnitude);

      Vector dk(kernel.num_parameters());
      kernel.Gradient(a, b, dk);
      for (int i = 0; i < kernel.num_parameters(); ++i) {
        EXPECT_NEAR(dk[i], ref.gradient[i], 1e-12 * ref.gradient_magnitude[i] + 1e-300)
            << kernel.parameter_names()[static_cast<size_t>(i)];
      }

      const PolKernelTerms terms = kernel.EvaluateTerms(a, b);
      EXPECT_NEAR(terms.inertial, ref.block_value[0], 1e-12 * ref.block_magnitude[0]);
      EXPECT_NEAR(terms.coriolis, ref.block_value[1], 1e-12 * ref.block_magnitude[1]);
      if (with_gravity) {
        EXPECT_NEAR(terms.gravity, ref.block_value[2], 1e-12 * ref.block_magnitude[2]);
      } else {
        EXPECT_EQ(terms.gravity, 0.0);
      }
    }
  }
  std::cout << "[ info     ] N = " << n << ": worst |k - k_map| / sum|terms| = " << worst
            << std::endl;
}

TEST(PolFormulaKernel, EqualsFeatureKernelOfPolMap) {
  for (int n = 1; n <= 4; ++n) CheckAgainstFeatureKernel(n, true, 100 + n);
}

TEST(PolFormulaKernel, EqualsFeatureKernelOfGravityFreeMap) {
  for (int n = 1; n <= 3; ++n) CheckAgainstFeatureKernel(n, false, 200 + n);
}

// At unit block scales the kernel is the formula of eq. 17 (and eq. 55 without gravity), for
// any N, including N beyond the explicit map's kMaxPolJoints.
TEST(PolFormulaKernel, EqualsFormulaAtUnitScales) {
  auto rng = SeededRng(301);
  for (int n : {1, 3, 6, 7, 10}) {
    PolFormulaKernel kernel(n);
    PolFormulaKernel gravity_free(n, PolOptions{false});
    for (double log_sigma : {-3.0, 0.0, 2.5}) {
      Vector theta = Vector::Zero(4);
      theta[0] = log_sigma;
      kernel = Reparameterized(kernel, theta);
      gravity_free = Reparameterized(gravity_free, theta.head(3));
      for (int trial = 0; trial < 5; ++trial) {
        const Vector a = RandomState(n, &rng);
        const Vector b = RandomState(n, &rng);
        double d_ref = 0.0;
        const double ref = PolKernel(a, b, n, std::exp(log_sigma), &d_ref);
        // Both are O(N) products of terms of order one; relative rounding ~ N eps.
        const double scale = PolKernel(a, a, n, std::exp(log_sigma)) +
                             PolKernel(b, b, n, std::exp(log_sigma));
        EXPECT_NEAR(kernel.Evaluate(a, b), ref, 1e-13 * scale) << "N = " << n;
        Vector dk(4);
        kernel.Gradient(a, b, dk);
        EXPECT_NEAR(dk[0], d_ref, 1e-13 * scale) << "N = " << n;
        double d_free = 0.0;
        EXPECT_NEAR(gravity_free.Evaluate(a, b),
                    PolKernelGravityFree(a, b, n, std::exp(log_sigma), &d_free), 1e-13 * scale);
      }
    }
  }
}

// Central differences, h = 1e-5 on log parameters: truncation h^2 |k'''| / 6 and rounding
// eps |k| / h are both ~1e-10 |k| for k of order one; 1e-7 relative only fails on a wrong
// derivative.
TEST(PolFormulaKernel, GradientMatchesCentralDifferences) {
  auto rng = SeededRng(401);
  const double h = 1e-5;
  for (int n = 1; n <= 7; ++n) {
    for (bool gravity : {true, false}) {
      PolFormulaKernel kernel(n, PolOptions{gravity});
      for (const Vector& theta : TestParameters(kernel.num_parameters(), &rng)) {
        for (const auto& [a, b] : TestPairs(n, &rng)) {
          kernel = Reparameterized(kernel, theta);
          Vector dk(kernel.num_parameters());
          kernel.Gradient(a, b, dk);
          const double scale = std::abs(kernel.Evaluate(a, a)) + std::abs(kernel.Evaluate(b, b));
          for (int i = 0; i < kernel.num_parameters(); ++i) {
            Vector tp = theta, tm = theta;
            tp[i] += h;
            tm[i] -= h;
            kernel = Reparameterized(kernel, tp);
            const double kp = kernel.Evaluate(a, b);
            kernel = Reparameterized(kernel, tm);
            const double km = kernel.Evaluate(a, b);
            const double fd = (kp - km) / (2.0 * h);
            EXPECT_NEAR(dk[i], fd, 1e-7 * (scale + std::abs(fd)))
                << "N = " << n << ", " << kernel.parameter_names()[static_cast<size_t>(i)]
                << ", log sigma " << theta[0];
          }
          kernel = Reparameterized(kernel, theta);
        }
      }
    }
  }
}

// The generic invariants (symmetric PSD Gram matrix with near-duplicates, no allocation in
// Evaluate/Gradient, parameter round trip) come from the kernel battery in test_kernels.cc.

TEST(PolFormulaKernel, ParametersNamesAndClone) {
  PolFormulaKernel kernel(3);
  EXPECT_EQ(kernel.input_dim(), 9);
  const std::vector<std::string> expected = {"log_sigma", "log_scale_inertial",
                                             "log_scale_coriolis", "log_scale_gravity"};
  EXPECT_EQ(kernel.parameter_names(), expected);
  // The same names, in the same order, as the feature kernel of the map.
  const auto map = std::make_shared<PolFeatureMap>(3);
  FeatureKernel feature(map, DefaultHyperparameters(*map, 1));
  EXPECT_EQ(kernel.parameter_names(), feature.parameter_names());
  EXPECT_TRUE(kernel.parameters() == feature.parameters());

  PolFormulaKernel gravity_free(3, PolOptions{false});
  EXPECT_EQ(gravity_free.num_parameters(), 3);
  EXPECT_EQ(gravity_free.parameter_names().back(), "log_scale_coriolis");

  auto rng = SeededRng(701);
  const Vector a = RandomState(3, &rng);
  const Vector b = RandomState(3, &rng);
  const auto clone = kernel.Clone();
  EXPECT_NE(dynamic_cast<PolFormulaKernel*>(clone.get()), nullptr);
  EXPECT_EQ(clone->Evaluate(a, b), kernel.Evaluate(a, b));
  Vector theta(4);
  theta << 0.4, -0.1, 0.2, 0.3;
  kernel = Reparameterized(kernel, theta);
  EXPECT_TRUE(kernel.parameters() == theta);
  EXPECT_NE(clone->Evaluate(a, b), kernel.Evaluate(a, b));
  EXPECT_TRUE(clone->parameters() == Vector::Zero(4));

  EXPECT_THROW(PolFormulaKernel(0), std::invalid_argument);
  EXPECT_THROW(kernel.WithParameters(Vector::Zero(3)), std::invalid_argument);
  theta[2] = std::nan("");
  EXPECT_THROW(kernel.WithParameters(theta), std::invalid_argument);
}

// In a function-space model the two kernels are the same model: equal log marginal
// likelihood and gradient (the gradient sums m^2 kernel derivatives, each equal to ~1e-15
// relative, so 1e-9 relative is ample).
TEST(PolFormulaKernel, SameEvidenceAsFeatureKernelInKernelGP) {
  const int n = 3;
  const int m = 80;
  auto rng = SeededRng(801);
  Matrix X(m, 3 * n);
  for (int i = 0; i < m; ++i) X.row(i) = RandomState(n, &rng).transpose();
  std::normal_distribution<double> normal(0.0, 1.0);
  const Matrix Y = Matrix::NullaryExpr(m, n, [&]() { return normal(rng); });
  Vector theta(4);
  theta << 0.3, -0.2, 0.1, 0.4;
  PolFormulaKernel formula(n);
  formula = Reparameterized(formula, theta);
  const auto map = std::make_shared<PolFeatureMap>(n);
  FeatureKernel feature(map, ToHyper(*map, theta));

  KernelGP gp_formula(formula, 0.04, n);
  KernelGP gp_feature(feature, 0.04, n);
  ASSERT_EQ(gp_formula.Fit(X, Y), Status::kOk);
  ASSERT_EQ(gp_feature.Fit(X, Y), Status::kOk);
  Vector g1, g2, s1, s2;
  double n1 = 0.0, n2 = 0.0;
  const double l1 = gp_formula.LogMarginalLikelihood(&g1, &n1, &s1);
  const double l2 = gp_feature.LogMarginalLikelihood(&g2, &n2, &s2);
  EXPECT_NEAR(l1, l2, 1e-10 * std::abs(l2));
  for (int i = 0; i < 4; ++i) EXPECT_NEAR(g1[i], g2[i], 1e-9 * g2.cwiseAbs().maxCoeff());
  EXPECT_NEAR(n1, n2, 1e-9 * std::abs(n2));
}

}  // namespace
}  // namespace structgp
