// Tests of the Nystrom feature map and the choice of inducing states: the feature-map battery
// (against an independently computed Nystrom kernel), the approximation's defining properties
// (never above the exact kernel, exact at the inducing states, exact for a finite-rank kernel
// once M reaches the rank), and agreement of a weight-space model on Nystrom features with the
// exact kernel-form model in that case.

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <iostream>
#include <limits>
#include <memory>
#include <set>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "battery_options.h"
#include "structgp/kernel/nystrom_feature_map.h"
#include "structgp/feature/pol_feature_map.h"
#include "structgp/feature/feature_hyperparameters.h"
#include "structgp/kernel/feature_kernel.h"
#include "structgp/kernel/pol_kernel.h"
#include "structgp/kernel/rbf_kernel.h"
#include "structgp/model/kernel_gp.h"
#include "structgp/model/weight_space_gp.h"

namespace structgp {
namespace {

using testing::BatteryOptions;
using testing::CountingBatteryOptions;
using testing::RandomStates;
using testing::RunFeatureMapBattery;

constexpr std::uint64_t kCandidateSeed = 31;
constexpr std::uint64_t kTestSeed = 32;

void PrintSeeds() {
  std::cout << "[ seeds    ] candidates " << kCandidateSeed << ", test states " << kTestSeed
            << "\n";
}

// k_Z(a)^T (K_ZZ + jitter I)^{-1} k_Z(b), computed without the map's factor.
double NystromKernel(const Kernel& kernel, const Matrix& Z, double jitter, const Vector& a,
                     const Vector& b) {
  const Eigen::Index M = Z.rows();
  Matrix K(M, M);
  Vector ka(M), kb(M);
  for (Eigen::Index i = 0; i < M; ++i) {
    const Vector zi = Z.row(i).transpose();
    ka[i] = kernel.Evaluate(zi, a);
    kb[i] = kernel.Evaluate(zi, b);
    for (Eigen::Index j = 0; j < M; ++j) K(i, j) = kernel.Evaluate(zi, Z.row(j).transpose());
  }
  K.diagonal().array() += jitter;
  return ka.dot(K.ldlt().solve(kb));
}

TEST(NystromFeatureMap, BatteryWithPolKernel) {
  PrintSeeds();
  const PolFormulaKernel kernel(2);
  const Matrix candidates = RandomStates(6, 300, kCandidateSeed);
  const Matrix Z = SelectInducingStates(kernel, candidates, 40);
  ASSERT_EQ(Z.rows(), 40);
  const NystromFeatureMap map(kernel, Z);
  EXPECT_EQ(map.dim(), 40);
  EXPECT_EQ(map.input_dim(), 6);
  EXPECT_EQ(map.jitter_steps(), 0);
  BatteryOptions options = CountingBatteryOptions();
  options.reference_kernel = [&](const Vector& a, const Vector& b, const Vector&) {
    return NystromKernel(kernel, Z, map.jitter(), a, b);
  };
  // The reference solves with K_ZZ + jitter I (condition number up to ~1/kNystromRelativeJitter)
  // by another factorisation: the two agree to cond * eps ~ 1e-8 relative.
  options.kernel_tolerance = 1e-7;
  RunFeatureMapBattery(map, options);
}

TEST(NystromFeatureMap, BatteryWithRbfKernelAndRandomSubset) {
  const RbfKernel kernel(4, /*ard=*/false, /*length_scale=*/1.5);
  InducingOptions io;
  io.selection = InducingSelection::kRandomSubset;
  io.seed = 3;
  const Matrix Z = SelectInducingStates(kernel, RandomStates(4, 200, kCandidateSeed), 30, io);
  const NystromFeatureMap map(kernel, Z);
  BatteryOptions options = CountingBatteryOptions();
  options.reference_kernel = [&](const Vector& a, const Vector& b, const Vector&) {
    return NystromKernel(kernel, Z, map.jitter(), a, b);
  };
  options.kernel_tolerance = 1e-7;
  RunFeatureMapBattery(map, options);
}

// FeatureKernel keeps scratch vectors, so its Nystrom map is not thread-safe through the
// FeatureMap interface: everything but the concurrency check applies, and the overload with a
// per-thread kernel copy gives the same features.
TEST(NystromFeatureMap, BatteryWithFeatureKernelAndPerThreadKernels) {
  auto pol = std::make_shared<PolFeatureMap>(2);
  const FeatureKernel kernel(pol, DefaultHyperparameters(*pol, 1));
  InducingOptions io;
  io.selection = InducingSelection::kFarthestPoint;
  const Matrix Z = SelectInducingStates(kernel, RandomStates(6, 200, kCandidateSeed), 30, io);
  const NystromFeatureMap map(kernel, Z);
  BatteryOptions options = CountingBatteryOptions();
  options.num_threads = 0;
  options.reference_kernel = [&](const Vector& a, const Vector& b, const Vector&) {
    return NystromKernel(kernel, Z, map.jitter(), a, b);
  };
  options.kernel_tolerance = 1e-7;
  RunFeatureMapBattery(map, options);

  const Matrix X = RandomStates(6, 20, kTestSeed);
  std::vector<std::unique_ptr<Kernel>> copies;
  for (int t = 0; t < 3; ++t) copies.push_back(map.kernel().Clone());
  std::vector<std::thread> threads;
  std::vector<int> mismatches(3, 0);
  for (int t = 0; t < 3; ++t) {
    threads.emplace_back([&, t]() {
      Vector phi(map.dim()), ref(map.dim());
      for (int rep = 0; rep < 5; ++rep) {
        for (int i = 0; i < X.rows(); ++i) {
          const Vector x = X.row(i).transpose();
          map.Evaluate(x, phi, *copies[t]);
          map.Evaluate(x, ref, *copies[t]);
          mismatches[t] += !(phi.array() == ref.array()).all();
        }
      }
    });
  }
  for (std::thread& th : threads) th.join();
  for (int t = 0; t < 3; ++t) EXPECT_EQ(mismatches[t], 0);
  Vector phi(map.dim()), ref(map.dim());
  const Vector x = X.row(0).transpose();
  map.Evaluate(x, phi);
  map.Evaluate(x, ref, *copies[0]);
  EXPECT_TRUE((phi.array() == ref.array()).all());
}

// The specialised k_pol kernel column equals the generic one (kernel.Evaluate per inducing
// state) to rounding: cos(a - b) is formed as cos a cos b + sin a sin b, an O(eps) change.
TEST(NystromFeatureMap, PolFastPathEqualsGenericPath) {
  PrintSeeds();
  double worst = 0.0;
  for (const int n : {1, 2, 6, 7}) {
    for (const bool gravity : {true, false}) {
      SCOPED_TRACE("N = " + std::to_string(n) + (gravity ? ", with gravity" : ", gravity-free"));
      PolOptions po;
      po.include_gravity = gravity;
      PolFormulaKernel kernel(n, po);
      Vector p = Vector::LinSpaced(kernel.num_parameters(), -0.4, 0.3);  // not the defaults
      kernel = Reparameterized(kernel, p);
      const Matrix Z = RandomStates(3 * n, 50, kCandidateSeed);
      const NystromFeatureMap map(kernel, Z);
      ASSERT_TRUE(map.uses_pol_fast_path());
      const Matrix X = RandomStates(3 * n, 30, kTestSeed);
      Vector fast(map.dim()), generic(map.dim());
      for (int i = 0; i < X.rows(); ++i) {
        const Vector x = X.row(i).transpose();
        map.Evaluate(x, fast);
        map.Evaluate(x, generic, map.kernel());
        // |phi|^2 <= k(x, x): compare relative to sqrt(k(x, x)), with the solve's amplification
        // of the O(eps) column difference (cond(L) <= 1 / sqrt(kNystromRelativeJitter));
        // observed: below 4e-12.
        const double scale = std::sqrt(kernel.Evaluate(x, x));
        EXPECT_LT((fast - generic).cwiseAbs().maxCoeff(), 1e-10 * scale) << "state " << i;
        worst = std::max(worst, (fast - generic).cwiseAbs().maxCoeff() / scale);
      }
    }
  }
  std::cout << "[ figures  ] largest |fast - generic| / sqrt(k(x,x)): " << worst << "\n";
  // Other kernels take the generic path.
  const RbfKernel rbf(6);
  EXPECT_FALSE(NystromFeatureMap(rbf, RandomStates(6, 5, kCandidateSeed)).uses_pol_fast_path());
}

TEST(NystromFeatureMap, NeverAboveTheExactKernelAndExactAtInducingStates) {
  PrintSeeds();
  const PolFormulaKernel kernel(3);
  const Matrix Z = SelectInducingStates(kernel, RandomStates(9, 400, kCandidateSeed), 60);
  const NystromFeatureMap map(kernel, Z);
  const double eps = std::numeric_limits<double>::epsilon();
  Vector phi(map.dim());
  const Matrix X = RandomStates(9, 50, kTestSeed);
  for (int i = 0; i < X.rows(); ++i) {
    const Vector x = X.row(i).transpose();
    map.Evaluate(x, phi);
    const double kxx = kernel.Evaluate(x, x);
    EXPECT_GE(kxx - phi.squaredNorm(), -100 * map.dim() * eps * kxx) << "state " << i;
  }
  // At z_i: k_Z(z_i) = K_ZZ e_i, and |phi|^2 = e_i^T K (K + jI)^{-1} K e_i = K_ii - O(jitter).
  for (int i = 0; i < Z.rows(); ++i) {
    const Vector z = Z.row(i).transpose();
    map.Evaluate(z, phi);
    const double kzz = kernel.Evaluate(z, z);
    EXPECT_NEAR(phi.squaredNorm(), kzz, 1e-6 * kzz) << "inducing state " << i;
  }
}

TEST(NystromFeatureMap, GreedySelectionErrorDecreasesWithM) {
  const PolFormulaKernel kernel(3);
  const Matrix candidates = RandomStates(9, 400, kCandidateSeed);
  const Matrix X = RandomStates(9, 100, kTestSeed);
  double previous = std::numeric_limits<double>::infinity();
  for (int M : {10, 20, 40, 80, 160}) {
    const NystromFeatureMap map(kernel, SelectInducingStates(kernel, candidates, M));
    Vector phi(map.dim());
    double residual = 0.0;
    for (int i = 0; i < X.rows(); ++i) {
      const Vector x = X.row(i).transpose();
      map.Evaluate(x, phi);
      residual += kernel.Evaluate(x, x) - phi.squaredNorm();
    }
    residual /= X.rows();
    std::cout << "[ figures  ] M = " << M << ": mean k(x,x) - |phi(x)|^2 = " << residual << "\n";
    EXPECT_LT(residual, previous);
    previous = residual;
  }
}

// k_pol of one joint has rank 12 (docs/feature_maps.md): greedy selection stops at 12 states,
// the Nystrom kernel is then k_pol itself, and a WeightSpaceGP on the 12 features predicts as
// the exact kernel-form GP.
TEST(NystromFeatureMap, ExactForFiniteRankKernel) {
  PrintSeeds();
  const PolFormulaKernel kernel(1);
  const Matrix candidates = RandomStates(3, 200, kCandidateSeed);
  const Matrix Z = SelectInducingStates(kernel, candidates, 50);
  EXPECT_EQ(Z.rows(), PolFeatureDimension(1)) << "greedy selection should stop at the rank";
  const NystromFeatureMap map(kernel, Z);
  const Matrix X = RandomStates(3, 40, kTestSeed);
  Vector pa(map.dim()), pb(map.dim());
  for (int i = 0; i < X.rows(); ++i) {
    for (int j = 0; j < X.rows(); ++j) {
      const Vector a = X.row(i).transpose(), b = X.row(j).transpose();
      map.Evaluate(a, pa);
      map.Evaluate(b, pb);
      const double scale = std::sqrt(kernel.Evaluate(a, a) * kernel.Evaluate(b, b));
      EXPECT_NEAR(pa.dot(pb), kernel.Evaluate(a, b), 1e-5 * scale) << i << ", " << j;
    }
  }
  // Same predictions as the exact GP (data: a smooth function of the state).
  const Matrix Xtrain = RandomStates(3, 80, kCandidateSeed + 7);
  Matrix Y(80, 1);
  for (int i = 0; i < 80; ++i) {
    Y(i, 0) = std::sin(Xtrain(i, 0)) + 0.5 * Xtrain(i, 2) * std::cos(Xtrain(i, 0)) +
              0.1 * Xtrain(i, 1) * Xtrain(i, 1);
  }
  const double noise = 1e-2;
  KernelGP exact(kernel, noise, 1);
  ASSERT_EQ(exact.Fit(Xtrain, Y), Status::kOk);
  Matrix Phi;
  map.EvaluateRows(Xtrain, &Phi);
  WeightSpaceGP approx(Vector::Ones(map.dim()), noise, 1);
  ASSERT_EQ(approx.Fit(Phi, Y), Status::kOk);
  Vector m_exact(1), v_exact(1), n_exact(1), m_approx(1), v_approx(1), n_approx(1), phi(map.dim());
  for (int i = 0; i < X.rows(); ++i) {
    const Vector x = X.row(i).transpose();
    map.Evaluate(x, phi);
    ASSERT_EQ(exact.PredictWithVariance(x, m_exact, v_exact, n_exact), Status::kOk);
    ASSERT_EQ(approx.PredictWithVariance(phi, m_approx, v_approx, n_approx), Status::kOk);
    EXPECT_NEAR(m_approx[0], m_exact[0], 1e-4 * (1.0 + std::abs(m_exact[0]))) << i;
    EXPECT_NEAR(v_approx[0], v_exact[0], 1e-4 * kernel.Evaluate(x, x)) << i;
  }
}

TEST(SelectInducingStates, MethodsGiveDistinctCandidateRows) {
  const PolFormulaKernel kernel(2);
  // Without RandomStates' duplicated row 0, so that every candidate is distinct.
  const Matrix X = RandomStates(6, 151, kCandidateSeed).bottomRows(150);
  for (InducingSelection s : {InducingSelection::kRandomSubset, InducingSelection::kFarthestPoint,
                              InducingSelection::kGreedyVariance}) {
    SCOPED_TRACE(ToString(s));
    InducingOptions io;
    io.selection = s;
    io.seed = 9;
    const Matrix Z = SelectInducingStates(kernel, X, 25, io);
    ASSERT_EQ(Z.rows(), 25);
    std::set<int> rows;
    for (int i = 0; i < Z.rows(); ++i) {
      int found = -1;
      for (int r = 0; r < X.rows(); ++r) {
        if ((X.row(r).array() == Z.row(i).array()).all()) {
          found = r;
          break;
        }
      }
      ASSERT_GE(found, 0) << "inducing state " << i << " is not a candidate";
      rows.insert(found);
    }
    EXPECT_EQ(static_cast<int>(rows.size()), 25);
    EXPECT_TRUE((SelectInducingStates(kernel, X, 25, io).array() == Z.array()).all())
        << "not deterministic";
  }
  InducingOptions a, b;
  a.selection = b.selection = InducingSelection::kRandomSubset;
  a.seed = 1;
  b.seed = 2;
  EXPECT_FALSE((SelectInducingStates(kernel, X, 25, a).array() ==
                SelectInducingStates(kernel, X, 25, b).array())
                   .all());
  // M larger than the candidate set: all of them (random subset).
  EXPECT_EQ(SelectInducingStates(kernel, X.topRows(10), 25, a).rows(), 10);
  EXPECT_THROW(SelectInducingStates(kernel, X, 0), std::invalid_argument);
  EXPECT_THROW(SelectInducingStates(kernel, X.leftCols(5), 5), std::invalid_argument);
  Matrix bad = X;
  bad(3, 2) = std::nan("");
  EXPECT_THROW(SelectInducingStates(kernel, bad, 5), std::invalid_argument);
}

TEST(NystromFeatureMap, RejectsBadInputAndSurvivesDuplicates) {
  const PolFormulaKernel kernel(2);
  EXPECT_THROW(NystromFeatureMap(kernel, Matrix(0, 6)), std::invalid_argument);
  EXPECT_THROW(NystromFeatureMap(kernel, Matrix::Zero(3, 5)), std::invalid_argument);
  Matrix Z = RandomStates(6, 10, kCandidateSeed);
  Z.row(5) = Z.row(4);  // a duplicate: K_ZZ singular, the jitter keeps it factorisable
  const NystromFeatureMap map(kernel, Z);
  EXPECT_GT(map.jitter(), 0.0);
  Vector phi(map.dim());
  const Vector x = RandomStates(6, 1, kTestSeed).row(0).transpose();
  map.Evaluate(x, phi);
  EXPECT_TRUE(phi.allFinite());
  EXPECT_LE(phi.squaredNorm(), kernel.Evaluate(x, x) * (1.0 + 1e-10));
}

}  // namespace
}  // namespace structgp
