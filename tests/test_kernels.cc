// Kernels of the function-space model: one invariant battery run on every kernel (symmetric
// positive semi-definite Gram matrix, parameter round trip, Clone, hyper-parameter gradient
// against central differences, no allocation in Evaluate/Gradient; a new kernel joins it with
// one entry in AllKernels()), plus closed forms:
// rbf by hand, rbfs against the rbf on the explicit (cos q, sin q, qd, qdd), the feature
// kernel against sum_k Lambda_k phi_k(a) phi_k(b).

#include <cmath>
#include <cstdint>
#include <functional>
#include <iostream>
#include <limits>
#include <memory>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Eigenvalues>

#include "alloc_counter.h"
#include "structgp/feature/effect_feature_map.h"
#include "structgp/feature/effects.h"
#include "structgp/feature/friction_feature_map.h"
#include "structgp/feature/random_feature_map.h"
#include "structgp/feature/feature_hyperparameters.h"
#include "structgp/feature/sum_feature_map.h"
#include "structgp/kernel/feature_kernel.h"
#include "structgp/kernel/pol_chain_kernel.h"
#include "structgp/kernel/pol_kernel.h"
#include "structgp/kernel/leading_inputs_kernel.h"
#include "structgp/kernel/rbf_kernel.h"
#include "structgp/kernel/sum_kernel.h"

namespace structgp {
namespace {

constexpr double kEps = 2.220446049250313e-16;

// Seeds are fixed; each test prints the seeds it uses so a failure can be replayed.
std::mt19937_64 SeededRng(std::uint64_t seed) {
  std::cout << "[ seed     ] " << seed << std::endl;
  return std::mt19937_64(seed);
}

Matrix RandomMatrix(int rows, int cols, double scale, std::mt19937_64* rng) {
  std::normal_distribution<double> normal(0.0, scale);
  return Matrix::NullaryExpr(rows, cols, [&]() { return normal(*rng); });
}

Vector RandomVector(int size, double scale, std::mt19937_64* rng) {
  std::normal_distribution<double> normal(0.0, scale);
  return Vector::NullaryExpr(size, [&]() { return normal(*rng); });
}

struct KernelCase {
  std::string name;
  std::function<std::unique_ptr<Kernel>()> make;
};

std::shared_ptr<const FeatureMap> MakeRandomMap(int input_dim, int dim, int blocks,
                                                std::uint64_t seed) {
  return std::make_shared<RandomFeatureMap>(input_dim, dim, blocks, seed);
}

std::vector<KernelCase> AllKernels() {
  std::vector<KernelCase> cases;
  cases.push_back({"rbf_iso", [] {
                     auto k = std::make_unique<RbfKernel>(4, false, 0.8, 1.3);
                     return std::unique_ptr<Kernel>(std::move(k));
                   }});
  cases.push_back({"rbf_ard", [] {
                     auto k = std::make_unique<RbfKernel>(5, true, 1.0, 0.7);
                     Vector theta(6);
                     theta << -0.3, 0.2, 0.5, -0.1, 0.0, 0.4;
                     return k->WithParameters(theta);
                   }});
  cases.push_back(
      {"rbfs_iso",
       [] { return std::unique_ptr<Kernel>(std::make_unique<RbfsKernel>(2, false, 1.1, 0.9)); }});
  cases.push_back({"rbfs_ard", [] {
                     auto k = std::make_unique<RbfsKernel>(2, true);
                     Vector theta(7);
                     theta << 0.1, -0.2, 0.3, 0.0, -0.4, 0.25, 0.15;
                     return k->WithParameters(theta);
                   }});
  cases.push_back({"feature_random", [] {
                     auto map = MakeRandomMap(3, 40, 3, 77);
                     Hyperparameters h = DefaultHyperparameters(*map, 2);
                     h.shape << 0.3;
                     h.log_block_scale << 0.2, -0.5, 0.4;
                     return std::unique_ptr<Kernel>(std::make_unique<FeatureKernel>(map, h));
                   }});
  cases.push_back({"leading_inputs_rbf", [] {
                     RbfKernel inner(3, true);
                     Vector theta(4);
                     theta << 0.2, -0.3, 0.1, 0.4;
                     return std::unique_ptr<Kernel>(
                         std::make_unique<LeadingInputsKernel>(*inner.WithParameters(theta), 5));
                   }});
  cases.push_back({"pol_formula_2", [] {
                     auto k = std::make_unique<PolFormulaKernel>(2);
                     Vector theta(4);
                     theta << -0.5, 0.3, -0.2, 0.1;
                     return k->WithParameters(theta);
                   }});
  cases.push_back({"pol_formula_5_gravity_free", [] {
                     auto k = std::make_unique<PolFormulaKernel>(5, PolOptions{false});
                     Vector theta(3);
                     theta << 0.4, -0.3, 0.2;
                     return k->WithParameters(theta);
                   }});
  for (const auto& [n, joint] : std::vector<std::pair<int, int>>{{1, 1}, {4, 1}, {4, 3}, {5, 5}}) {
    cases.push_back({"pol_chain_" + std::to_string(n) + "_joint" + std::to_string(joint),
                     [n = n, joint = joint] {
                       Vector theta(4);
                       theta << 0.3 - 0.2 * joint, -0.2, 0.4, 0.1;
                       return PolChainKernel(n, joint).WithParameters(theta);
                     }});
  }
  // What RobotModel builds for "rbf+fri" with an effect in function space: the base kernel
  // plus the friction and effect features as a kernel.
  cases.push_back({"sum_rbf_friction_cogging", [] {
                     const RbfKernel rbf(6, /*ard=*/true, 0.9, 1.2);
                     auto extras = std::make_shared<SumFeatureMap>(
                         std::vector<std::shared_ptr<const FeatureMap>>{
                             std::make_shared<FrictionFeatureMap>(2, 0.05),
                             std::make_shared<EffectFeatureMap>(
                                 2, MakeEffect("cogging", {{"period", 0.7}}),
                                 std::vector<int>{1})});
                     Hyperparameters h = DefaultHyperparameters(*extras, 2);
                     h.log_block_scale << 0.3, -0.4;
                     const FeatureKernel features(extras, h);
                     return std::unique_ptr<Kernel>(
                         std::make_unique<SumKernel>(std::vector<const Kernel*>{&rbf, &features}));
                   }});
  return cases;
}

class KernelBattery : public ::testing::TestWithParam<int> {
 protected:
  std::unique_ptr<Kernel> MakeKernel() const { return AllKernels()[GetParam()].make(); }
};

// Gram matrix of random points: exactly symmetric (every kernel here is symmetric term by
// term in IEEE arithmetic) and PSD up to rounding: the smallest eigenvalue of the computed
// Gram matrix is >= -n eps ||K||_2 (each entry carries an error of a few eps times the
// signal variance, and the eigenvalues of a symmetric perturbation E move by ||E||_2 <=
// n max|E_ij|).
TEST_P(KernelBattery, GramIsSymmetricPositiveSemiDefinite) {
  const auto kernel = MakeKernel();
  SCOPED_TRACE(AllKernels()[GetParam()].name);
  auto rng = SeededRng(1000 + GetParam());
  const int n = 40;
  // Half the points near-duplicates of the other half: the hard, nearly singular case.
  Matrix X = RandomMatrix(n, kernel->input_dim(), 1.0, &rng);
  X.bottomRows(n / 2) = X.topRows(n / 2) + RandomMatrix(n / 2, kernel->input_dim(), 1e-6, &rng);
  Matrix K;
  kernel->Gram(X, X, &K);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) ASSERT_EQ(K(i, j), K(j, i)) << "i = " << i << ", j = " << j;
  }
  Eigen::SelfAdjointEigenSolver<Matrix> eig(K, Eigen::EigenvaluesOnly);
  const double norm = eig.eigenvalues().cwiseAbs().maxCoeff();
  EXPECT_GT(norm, 0.0);
  EXPECT_GE(eig.eigenvalues().minCoeff(), -n * kEps * norm);
}

TEST_P(KernelBattery, ParametersRoundTripAndClone) {
  const auto kernel = MakeKernel();
  SCOPED_TRACE(AllKernels()[GetParam()].name);
  const Vector theta = kernel->parameters();
  ASSERT_EQ(theta.size(), kernel->num_parameters());
  ASSERT_EQ(static_cast<int>(kernel->parameter_names().size()), kernel->num_parameters());
  auto rng = SeededRng(2000 + GetParam());
  const Vector a = RandomVector(kernel->input_dim(), 1.0, &rng);
  const Vector b = RandomVector(kernel->input_dim(), 1.0, &rng);
  const auto clone = kernel->Clone();
  EXPECT_EQ(clone->Evaluate(a, b), kernel->Evaluate(a, b));

  const Vector changed = theta + RandomVector(kernel->num_parameters(), 0.2, &rng);
  const auto moved = kernel->WithParameters(changed);
  EXPECT_TRUE(moved->parameters().isApprox(changed, 1e-15));
  const Kernel& moved_kernel = *moved;
  const Kernel& original_kernel = *kernel;
  EXPECT_EQ(typeid(moved_kernel), typeid(original_kernel));
  EXPECT_NE(moved->Evaluate(a, b), kernel->Evaluate(a, b));
  // The kernel itself is unchanged, and WithParameters at its own parameters is a copy.
  EXPECT_TRUE(kernel->parameters() == theta);
  EXPECT_EQ(kernel->Evaluate(a, b), clone->Evaluate(a, b));
  EXPECT_EQ(kernel->WithParameters(theta)->Evaluate(a, b), kernel->Evaluate(a, b));

  EXPECT_THROW(kernel->WithParameters(Vector::Zero(kernel->num_parameters() + 1)),
               std::invalid_argument);
  Vector bad = changed;
  bad[0] = std::nan("");
  EXPECT_THROW(kernel->WithParameters(bad), std::invalid_argument);
}

// Central differences with step h on the log parameters: truncation error h^2 |k'''| / 6 and
// rounding error ~ eps |k| / h; with h = 1e-5 and k, k''' of order sf^2 both are below
// 1e-9 sf^2, so a tolerance of 1e-7 sf^2 (+ relative 1e-7) only fails on a wrong gradient.
TEST_P(KernelBattery, GradientMatchesCentralDifferences) {
  const auto kernel = MakeKernel();
  SCOPED_TRACE(AllKernels()[GetParam()].name);
  auto rng = SeededRng(3000 + GetParam());
  const Vector theta = kernel->parameters();
  const int np = kernel->num_parameters();
  const double h = 1e-5;
  for (int trial = 0; trial < 5; ++trial) {
    const Vector a = RandomVector(kernel->input_dim(), 1.0, &rng);
    // Close and far pairs, and a == b (where length-scale derivatives vanish).
    const Vector b =
        trial == 0 ? a : Vector(a + RandomVector(kernel->input_dim(), 0.3 * trial, &rng));
    Vector dk(np);
    kernel->Gradient(a, b, dk);
    const double scale = std::abs(kernel->Evaluate(a, a)) + std::abs(kernel->Evaluate(b, b));
    for (int p = 0; p < np; ++p) {
      Vector tp = theta, tm = theta;
      tp[p] += h;
      tm[p] -= h;
      const double kp = kernel->WithParameters(tp)->Evaluate(a, b);
      const double km = kernel->WithParameters(tm)->Evaluate(a, b);
      const double fd = (kp - km) / (2 * h);
      EXPECT_NEAR(dk[p], fd, 1e-7 * (scale + std::abs(fd)))
          << "parameter " << kernel->parameter_names()[p] << ", trial " << trial;
    }
  }
}

TEST_P(KernelBattery, EvaluateAndGradientDoNotAllocate) {
  const auto kernel = MakeKernel();
  SCOPED_TRACE(AllKernels()[GetParam()].name);
  auto rng = SeededRng(4000 + GetParam());
  const Vector a = RandomVector(kernel->input_dim(), 1.0, &rng);
  const Vector b = RandomVector(kernel->input_dim(), 1.0, &rng);
  Vector dk(kernel->num_parameters());
  double sum = 0.0;
  testing::AllocationCounter guard;
  for (int i = 0; i < 10; ++i) {
    sum += kernel->Evaluate(a, b);
    kernel->Gradient(a, b, dk);
    sum += dk.sum();
  }
  EXPECT_TRUE(std::isfinite(sum));
  if (!testing::CountsEveryAllocation()) GTEST_SKIP() << testing::kIncompleteCountReason;
  EXPECT_EQ(guard.count(), 0u);
}

INSTANTIATE_TEST_SUITE_P(AllKernels, KernelBattery,
                         ::testing::Range(0, static_cast<int>(AllKernels().size())),
                         [](const ::testing::TestParamInfo<int>& param_info) {
                           return AllKernels()[param_info.param].name;
                         });

TEST(RbfKernel, ClosedForm) {
  RbfKernel kernel(2, false, 2.0, 3.0);
  Vector a(2), b(2);
  a << 1.0, -1.0;
  b << 2.0, 1.0;
  // ||a - b||^2 = 5, l^2 = 4: k = 9 exp(-5 / 8).
  EXPECT_NEAR(kernel.Evaluate(a, b), 9.0 * std::exp(-5.0 / 8.0), 1e-15 * 9.0);
  EXPECT_NEAR(kernel.Evaluate(a, a), 9.0, 4e-15 * 9.0);  // sf^2 = exp(2 log 3)
  EXPECT_NEAR(kernel.signal_std(), 3.0, 1e-15);
  EXPECT_TRUE(kernel.length_scales().isApprox(Vector::Constant(2, 2.0), 1e-15));
  ASSERT_EQ(kernel.parameter_names().size(), 2u);
  EXPECT_EQ(kernel.parameter_names()[0], "log_length_scale");
  EXPECT_EQ(kernel.parameter_names()[1], "log_signal_std");

  RbfKernel ard(2, true, 1.0, 1.0);
  Vector theta(3);
  theta << std::log(0.5), std::log(4.0), 0.0;
  ard = Reparameterized(ard, theta);
  // r^2 = 1 / 0.25 + 4 / 16 = 4.25.
  EXPECT_NEAR(ard.Evaluate(a, b), std::exp(-0.5 * 4.25), 1e-15);
  EXPECT_EQ(ard.parameter_names()[1], "log_length_scale_2");

  EXPECT_THROW(RbfKernel(0), std::invalid_argument);
  EXPECT_THROW(RbfKernel(2, false, -1.0), std::invalid_argument);
  EXPECT_THROW(RbfKernel(2, false, 1.0, 0.0), std::invalid_argument);
}

// rbfs is the rbf on z = (cos q, sin q, qd, qdd); checked against that explicit transform
// with an RbfKernel on 4N inputs. The two evaluate r^2 in different but accurate forms, so
// they agree to a few eps relative.
TEST(RbfsKernel, EqualsRbfOnTrigonometricTransform) {
  const int N = 3;
  auto rng = SeededRng(5001);
  auto transform = [&](const Vector& x) {
    Vector z(4 * N);
    z << x.head(N).array().cos().matrix(), x.head(N).array().sin().matrix(), x.segment(N, N),
        x.tail(N);
    return z;
  };
  // Isotropic.
  RbfsKernel rbfs(N, false, 1.4, 0.8);
  RbfKernel rbf(4 * N, false, 1.4, 0.8);
  // ARD: the angle's length scale is shared by its cos and sin.
  RbfsKernel rbfs_ard(N, true);
  Vector theta = RandomVector(3 * N + 1, 0.3, &rng);
  rbfs_ard = Reparameterized(rbfs_ard, theta);
  RbfKernel rbf_ard(4 * N, true);
  Vector theta_z(4 * N + 1);
  theta_z << theta.head(N), theta.head(N), theta.segment(N, 2 * N), theta[3 * N];
  rbf_ard = Reparameterized(rbf_ard, theta_z);

  for (int trial = 0; trial < 20; ++trial) {
    const Vector a = RandomVector(3 * N, 2.0, &rng);
    const Vector b = a + RandomVector(3 * N, 0.5, &rng);
    EXPECT_NEAR(rbfs.Evaluate(a, b), rbf.Evaluate(transform(a), transform(b)),
                1e-13 * rbf.Evaluate(transform(a), transform(b)));
    EXPECT_NEAR(rbfs_ard.Evaluate(a, b), rbf_ard.Evaluate(transform(a), transform(b)),
                1e-13 * rbf_ard.Evaluate(transform(a), transform(b)));
  }
  // Periodic in every angle.
  const Vector a = RandomVector(3 * N, 1.0, &rng);
  Vector b = RandomVector(3 * N, 1.0, &rng);
  const double k = rbfs.Evaluate(a, b);
  b[1] += 6.283185307179586;  // 2 pi
  EXPECT_NEAR(rbfs.Evaluate(a, b), k, 1e-14);

  EXPECT_EQ(rbfs.input_dim(), 3 * N);
  const auto names = rbfs_ard.parameter_names();
  ASSERT_EQ(static_cast<int>(names.size()), 3 * N + 1);
  EXPECT_EQ(names[0], "log_length_scale_q1");
  EXPECT_EQ(names[N], "log_length_scale_qd1");
  EXPECT_EQ(names[3 * N - 1], "log_length_scale_qdd3");
  EXPECT_EQ(names[3 * N], "log_signal_std");
  EXPECT_THROW(RbfsKernel(0), std::invalid_argument);
  // Clone keeps the type.
  EXPECT_NE(dynamic_cast<RbfsKernel*>(rbfs_ard.Clone().get()), nullptr);
}

// The sum is its parts' values added, and its gradient their gradients side by side.
TEST(SumKernel, EqualsItsPartsAdded) {
  const RbfKernel rbf(4, /*ard=*/false, 0.8, 1.3);
  auto map = MakeRandomMap(4, 12, 2, 92);
  const FeatureKernel features(map, DefaultHyperparameters(*map, 1));
  const SumKernel sum(std::vector<const Kernel*>{&rbf, &features});
  ASSERT_EQ(sum.num_parameters(), rbf.num_parameters() + features.num_parameters());
  auto rng = SeededRng(6101);
  Vector d_sum(sum.num_parameters()), d_rbf(rbf.num_parameters()),
      d_features(features.num_parameters());
  for (int trial = 0; trial < 5; ++trial) {
    const Vector a = RandomVector(4, 1.0, &rng);
    const Vector b = RandomVector(4, 1.0, &rng);
    EXPECT_EQ(sum.Evaluate(a, b), rbf.Evaluate(a, b) + features.Evaluate(a, b));
    sum.Gradient(a, b, d_sum);
    rbf.Gradient(a, b, d_rbf);
    features.Gradient(a, b, d_features);
    EXPECT_TRUE(d_sum.head(rbf.num_parameters()) == d_rbf);
    EXPECT_TRUE(d_sum.tail(features.num_parameters()) == d_features);
  }
  const RbfKernel other(5, false);
  EXPECT_THROW(SumKernel(std::vector<const Kernel*>{&rbf, &other}), std::invalid_argument);
  EXPECT_THROW(SumKernel(std::vector<const Kernel*>{}), std::invalid_argument);
}

TEST(FeatureKernel, EqualsWeightedFeatureProduct) {
  const std::uint64_t map_seed = 91;
  std::cout << "[ seed     ] map " << map_seed << std::endl;
  auto map = MakeRandomMap(4, 30, 3, map_seed);
  Hyperparameters h = DefaultHyperparameters(*map, 1);
  h.shape << -0.4;
  h.log_block_scale << 0.3, 0.0, -0.7;
  FeatureKernel kernel(map, h);
  const Vector lambda = PriorVariance(*map, h);
  EXPECT_TRUE(kernel.prior_variance().isApprox(lambda, 1e-15));

  auto rng = SeededRng(6001);
  Vector phi_a(30), phi_b(30);
  for (int trial = 0; trial < 10; ++trial) {
    const Vector a = RandomVector(4, 1.0, &rng);
    const Vector b = RandomVector(4, 1.0, &rng);
    map->Evaluate(a, phi_a);
    map->Evaluate(b, phi_b);
    double expected = 0.0;
    for (int k = 0; k < 30; ++k) expected += lambda[k] * phi_a[k] * phi_b[k];
    EXPECT_NEAR(kernel.Evaluate(a, b), expected, 30 * kEps * lambda.sum());
  }

  const auto names = kernel.parameter_names();
  ASSERT_EQ(names.size(), 4u);
  EXPECT_EQ(names[0], "log_decay");
  EXPECT_EQ(names[1], "log_scale_b0");
  EXPECT_EQ(names[3], "log_scale_b2");
  Vector expected_theta(4);
  expected_theta << -0.4, 0.3, 0.0, -0.7;
  EXPECT_TRUE(kernel.parameters() == expected_theta);

  // WithParameters changes Lambda as PriorVariance would.
  Vector theta(4);
  theta << 0.2, -0.1, 0.5, 0.0;
  kernel = Reparameterized(kernel, theta);
  h.shape << 0.2;
  h.log_block_scale << -0.1, 0.5, 0.0;
  EXPECT_TRUE(kernel.prior_variance().isApprox(PriorVariance(*map, h), 1e-15));

  EXPECT_THROW(FeatureKernel(nullptr, h), std::invalid_argument);
  Hyperparameters wrong = h;
  wrong.log_block_scale = Vector::Zero(2);
  EXPECT_THROW(FeatureKernel(map, wrong), std::invalid_argument);
}

}  // namespace
}  // namespace structgp
