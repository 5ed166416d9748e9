#ifndef STRUCTGP_TESTING_FEATURE_MAP_BATTERY_H_
#define STRUCTGP_TESTING_FEATURE_MAP_BATTERY_H_

/// @file
/// The invariant battery every FeatureMap must pass: a test utility for your own maps (and
/// effects, through EffectFeatureMap), installed with the library; it needs GoogleTest. Your
/// map gets all of it by one line in a test linked with GTest::gtest_main and
/// structgp::structgp:
///
///   TEST(MyMap, Battery) { structgp::testing::RunFeatureMapBattery(MyMap(...)); }
///
/// (BatteryOptions::reference_kernel adds a comparison with your exact kernel, and
/// BatteryOptions::allocation_count the no-allocation check.)
//
// Checks, with random states from a fixed seed (printed with every failure):
//  1. dimensions: input_dim() and dim() positive; blocks() tile [0, dim()) in order, with
//     unique non-empty names; shape names and defaults sized num_shape_parameters();
//  2. Evaluate writes every entry (phi pre-filled with NaN), gives finite values, is
//     bit-for-bit deterministic, agrees with EvaluateRows, and rejects wrong sizes with
//     std::invalid_argument (as does PriorVariance for a wrong shape size);
//  3. Evaluate performs no heap allocation (when BatteryOptions::allocation_count is given:
//     this project's tests pass the counter of tests/alloc_counter.h), and gives the same
//     bits when called concurrently from several threads;
//  4. at every shape tested: lambda finite and > 0; d lambda / d shape equal to central
//     differences; the Gram matrix K_ij = sum_k lambda_k phi_k(x_i) phi_k(x_j) symmetric and
//     positive semi-definite to rounding; and, when a reference kernel is given, K_ij equal to
//     it.
//
// Tolerances come from the rounding analysis of the sums involved:
//  - a sum of D products s = sum_k t_k is computed with error <= gamma_D sum_k |t_k|,
//    gamma_D ~ D eps, and sum_k lambda_k |phi_ik phi_jk| <= sqrt(K_ii K_jj) by Cauchy-Schwarz,
//    so K_ij - K_ji is bounded by (2 D + 2) eps sqrt(K_ii K_jj);
//  - the reference kernel comparison is relative to S_ij = sum_k |lambda_k phi_ik phi_jk| (the
//    size of the terms that cancel), with a tolerance of 1e-12 by default;
//  - the PSD check demands lambda_min(K) >= -psd_slack * n eps ||K||_2 (psd_slack = 1). A
//    symmetric rounding perturbation E moves eigenvalues by at most ||E||_2 <= n max|E_ij|,
//    and the eigensolver's backward error is of the same order; for every map of
//    test_feature_maps.cc, including rank-deficient Gram matrices (D < n), the observed
//    negative eigenvalues stay below 0.05 n eps ||K||. Raise psd_slack only with a reason.
//  - central differences with step h on a parameter whose prior depends on it through
//    exp / powers of order p have truncation error ~ (p h)^2 / 6 relative, and rounding error
//    ~ eps / h; with h = 1e-5 both are far below the 1e-6 relative tolerance used.

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <limits>
#include <random>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <iostream>
#include <vector>

#include "structgp/core/types.h"
#include "structgp/feature/feature_map.h"

namespace structgp {
namespace testing {

/// Exact kernel k(a, b) at shape parameters `shape`, the reference for sum lambda phi phi.
using ReferenceKernel =
    std::function<double(const Vector& a, const Vector& b, const Vector& shape)>;

struct BatteryOptions {
  /// Seed of the random states; printed with every failure.
  std::uint64_t seed = 20240601;
  /// Number of random states in the Gram matrix (some of them are hard cases: an exact
  /// duplicate, a near duplicate, a state at rest).
  int num_states = 30;
  /// Shape vectors at which prior, derivatives, Gram matrix and reference are checked. Empty:
  /// the map's defaults plus two perturbations (each parameter +0.7 and -1.1).
  std::vector<Vector> shapes;
  /// Optional exact kernel.
  ReferenceKernel reference_kernel;
  /// Relative tolerance of the reference comparison (relative to sum_k |lambda phi phi|).
  double kernel_tolerance = 1e-12;
  /// Step and relative tolerance of the central-difference check of d lambda / d shape.
  double fd_step = 1e-5;
  double fd_tolerance = 1e-6;
  /// Multiplier of n eps ||K|| in the PSD check.
  double psd_slack = 1.0;
  /// Threads of the concurrency check (0 to skip it).
  int num_threads = 4;
  /// Whether Evaluate / PriorVariance must throw std::invalid_argument on wrong sizes.
  bool check_size_errors = true;
  /// Number of heap allocations of the process so far (e.g. from a replaced global
  /// operator new); when given, Evaluate must not allocate. Empty: that check is skipped, with
  /// a note.
  std::function<std::size_t()> allocation_count;
  /// Printed instead of the default note when allocation_count is empty.
  std::string allocation_note =
      "allocations of Evaluate not checked (BatteryOptions::allocation_count not given)";
};

/// m random inputs for `map`, one per row. When input_dim is a multiple of 3 they are robot
/// states (q, qd, qdd): q in [-pi, pi), qd in [-2, 2), qdd in [-4, 4); otherwise every entry
/// is in [-2, 2). Row 1 duplicates row 0, row 3 is row 2 moved by 1e-7, row 4 has qd = 0
/// (robot states) when m allows.
inline Matrix RandomStates(int input_dim, int m, std::uint64_t seed) {
  constexpr double kPi = 3.14159265358979323846;
  std::mt19937_64 engine(seed);
  const auto uniform = [&engine](double lo, double hi) {
    return lo + (hi - lo) * static_cast<double>(engine() >> 11) * 0x1.0p-53;
  };
  const bool robot = input_dim % 3 == 0;
  const int n = input_dim / 3;
  Matrix X(m, input_dim);
  for (int i = 0; i < m; ++i) {
    for (int c = 0; c < input_dim; ++c) {
      if (!robot) {
        X(i, c) = uniform(-2.0, 2.0);
      } else if (c < n) {
        X(i, c) = uniform(-kPi, kPi);
      } else if (c < 2 * n) {
        X(i, c) = uniform(-2.0, 2.0);
      } else {
        X(i, c) = uniform(-4.0, 4.0);
      }
    }
  }
  if (m > 1) X.row(1) = X.row(0);
  if (m > 3) {
    X.row(3) = X.row(2);
    for (int c = 0; c < input_dim; ++c) X(3, c) += 1e-7 * uniform(-1.0, 1.0);
  }
  if (m > 4 && robot) X.row(4).segment(n, n).setZero();
  return X;
}

namespace internal_battery {

inline std::string Describe(const FeatureMap& map, const BatteryOptions& options) {
  std::ostringstream os;
  os << "feature map with input_dim " << map.input_dim() << ", dim " << map.dim()
     << "; battery seed " << options.seed << " (RandomStates(input_dim, " << options.num_states
     << ", seed))";
  return os.str();
}

inline void CheckDimensions(const FeatureMap& map) {
  ASSERT_GT(map.input_dim(), 0);
  ASSERT_GT(map.dim(), 0);
  const std::vector<FeatureBlock> blocks = map.blocks();
  ASSERT_FALSE(blocks.empty());
  int next = 0;
  std::set<std::string> names;
  for (const FeatureBlock& b : blocks) {
    EXPECT_FALSE(b.name.empty());
    EXPECT_TRUE(names.insert(b.name).second) << "duplicate block name " << b.name;
    EXPECT_EQ(b.begin, next) << "block " << b.name << " does not start where the last ended";
    EXPECT_GT(b.size, 0) << "empty block " << b.name;
    next = b.begin + b.size;
  }
  EXPECT_EQ(next, map.dim()) << "blocks do not cover [0, dim())";
  const int ns = map.num_shape_parameters();
  ASSERT_GE(ns, 0);
  EXPECT_EQ(static_cast<int>(map.shape_parameter_names().size()), ns);
  std::set<std::string> shape_names;
  for (const std::string& s : map.shape_parameter_names()) {
    EXPECT_FALSE(s.empty());
    EXPECT_TRUE(shape_names.insert(s).second) << "duplicate shape parameter name " << s;
  }
  const Vector shape0 = map.default_shape_parameters();
  EXPECT_EQ(shape0.size(), ns);
  EXPECT_TRUE(shape0.allFinite());
}

// Phi by single evaluations into NaN-filled vectors; checks determinism and EvaluateRows.
inline Matrix CheckEvaluate(const FeatureMap& map, const Matrix& X, const BatteryOptions& options) {
  const int m = static_cast<int>(X.rows());
  Matrix Phi(m, map.dim());
  Vector x(map.input_dim());
  Vector phi(map.dim());
  Vector again(map.dim());
  for (int i = 0; i < m; ++i) {
    x = X.row(i).transpose();
    phi.setConstant(std::numeric_limits<double>::quiet_NaN());
    map.Evaluate(x, phi);
    EXPECT_TRUE(phi.allFinite()) << "state " << i << ": Evaluate left a non-finite entry";
    again.setConstant(-1.0);
    map.Evaluate(x, again);
    EXPECT_TRUE((phi.array() == again.array()).all()) << "state " << i << ": not deterministic";
    Phi.row(i) = phi.transpose();
  }
  Matrix Phi_rows;
  map.EvaluateRows(X, &Phi_rows);
  EXPECT_TRUE(Phi_rows.rows() == m && Phi_rows.cols() == map.dim() &&
              (Phi_rows.array() == Phi.array()).all())
      << "EvaluateRows differs from Evaluate";

  if (options.check_size_errors) {
    Vector bad_x(map.input_dim() + 1);
    bad_x.setZero();
    EXPECT_THROW(map.Evaluate(bad_x, phi), std::invalid_argument);
    Vector bad_phi(map.dim() + 1);
    EXPECT_THROW(map.Evaluate(x, bad_phi), std::invalid_argument);
    Vector bad_shape(map.num_shape_parameters() + 1);
    bad_shape.setZero();
    Vector lambda(map.dim());
    EXPECT_THROW(map.PriorVariance(bad_shape, lambda), std::invalid_argument);
  }
  return Phi;
}

inline void CheckNoAllocation(const FeatureMap& map, const Matrix& X,
                              const BatteryOptions& options) {
  if (!options.allocation_count) {
    std::cout << "[   NOTE   ] " << options.allocation_note << "\n";
    return;
  }
  std::vector<Vector> xs;
  for (Eigen::Index i = 0; i < X.rows(); ++i) xs.emplace_back(X.row(i).transpose());
  Vector phi(map.dim());
  const std::size_t before = options.allocation_count();
  for (const Vector& x : xs) map.Evaluate(x, phi);
  const std::size_t count = options.allocation_count() - before;
  EXPECT_EQ(count, 0u) << "Evaluate allocated " << count << " times for " << xs.size() << " states";
}

inline void CheckConcurrent(const FeatureMap& map, const Matrix& X, const Matrix& Phi,
                            int num_threads) {
  if (num_threads <= 0) return;
  std::atomic<int> mismatches{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < num_threads; ++t) {
    threads.emplace_back([&map, &X, &Phi, &mismatches, t]() {
      Vector x(map.input_dim());
      Vector phi(map.dim());
      for (int rep = 0; rep < 3; ++rep) {
        for (Eigen::Index i = 0; i < X.rows(); ++i) {
          const Eigen::Index row = (i + t) % X.rows();
          x = X.row(row).transpose();
          map.Evaluate(x, phi);
          if (!(phi.transpose().array() == Phi.row(row).array()).all()) ++mismatches;
        }
      }
    });
  }
  for (std::thread& th : threads) th.join();
  EXPECT_EQ(mismatches.load(), 0) << "concurrent Evaluate calls gave different features";
}

inline void CheckPriorDerivative(const FeatureMap& map, const Vector& shape,
                                 const BatteryOptions& options) {
  const int d = map.dim();
  const int ns = map.num_shape_parameters();
  Vector lambda(d);
  Matrix jacobian;
  map.PriorVariance(shape, lambda, &jacobian);
  ASSERT_EQ(jacobian.rows(), d);
  ASSERT_EQ(jacobian.cols(), ns);
  EXPECT_TRUE(jacobian.allFinite());
  // Without a Jacobian the prior must be the same.
  Vector lambda_only(d);
  map.PriorVariance(shape, lambda_only);
  EXPECT_TRUE((lambda_only.array() == lambda.array()).all());
  const double h = options.fd_step;
  Vector plus(d), minus(d);
  for (int p = 0; p < ns; ++p) {
    Vector sp = shape, sm = shape;
    sp[p] += h;
    sm[p] -= h;
    map.PriorVariance(sp, plus);
    map.PriorVariance(sm, minus);
    int reported = 0;
    for (int k = 0; k < d; ++k) {
      const double fd = (plus[k] - minus[k]) / (2.0 * h);
      const double scale = std::abs(lambda[k]) + std::abs(jacobian(k, p));
      if (!(std::abs(fd - jacobian(k, p)) <= options.fd_tolerance * scale) && reported < 5) {
        ++reported;
        ADD_FAILURE() << "d lambda_" << k << " / d " << map.shape_parameter_names()[p]
                      << ": analytic " << jacobian(k, p) << ", central difference " << fd
                      << " (lambda " << lambda[k] << ")";
      }
    }
  }
}

inline void CheckGram(const FeatureMap& map, const Matrix& X, const Matrix& Phi,
                      const Vector& shape, const BatteryOptions& options) {
  const int m = static_cast<int>(Phi.rows());
  const int d = map.dim();
  Vector lambda(d);
  map.PriorVariance(shape, lambda);
  ASSERT_TRUE(lambda.allFinite());
  EXPECT_GT(lambda.minCoeff(), 0.0) << "prior variances must be positive";

  Matrix K(m, m);
  Matrix S(m, m);  // sum_k |lambda_k phi_ik phi_jk|
  for (int i = 0; i < m; ++i) {
    for (int j = 0; j < m; ++j) {
      double s = 0.0, a = 0.0;
      for (int k = 0; k < d; ++k) {
        const double t = lambda[k] * Phi(i, k) * Phi(j, k);
        s += t;
        a += std::abs(t);
      }
      K(i, j) = s;
      S(i, j) = a;
    }
  }
  const double eps = std::numeric_limits<double>::epsilon();
  for (int i = 0; i < m; ++i) {
    for (int j = 0; j < i; ++j) {
      const double tol = (2.0 * d + 2.0) * eps * std::sqrt(K(i, i) * K(j, j));
      EXPECT_LE(std::abs(K(i, j) - K(j, i)), tol)
          << "K not symmetric at (" << i << ", " << j << ")";
    }
  }
  const Matrix Ks = 0.5 * (K + K.transpose());
  Eigen::SelfAdjointEigenSolver<Matrix> eig(Ks, Eigen::EigenvaluesOnly);
  ASSERT_EQ(eig.info(), Eigen::Success);
  const double norm = eig.eigenvalues().cwiseAbs().maxCoeff();
  const double min_eig = eig.eigenvalues().minCoeff();
  EXPECT_GE(min_eig, -options.psd_slack * m * eps * norm)
      << "Gram matrix not PSD: smallest eigenvalue " << min_eig << ", ||K|| " << norm;

  if (options.reference_kernel) {
    Vector a(map.input_dim()), b(map.input_dim());
    int reported = 0;
    for (int i = 0; i < m; ++i) {
      a = X.row(i).transpose();
      for (int j = 0; j < m; ++j) {
        b = X.row(j).transpose();
        const double ref = options.reference_kernel(a, b, shape);
        const double tol = options.kernel_tolerance * std::max(S(i, j), std::abs(ref));
        if (!(std::abs(K(i, j) - ref) <= tol) && reported < 5) {
          ++reported;
          ADD_FAILURE() << "sum lambda phi phi = " << K(i, j) << " but reference kernel = " << ref
                        << " for states " << i << ", " << j << " (difference " << K(i, j) - ref
                        << ", tolerance " << tol << ")";
        }
      }
    }
  }
}

}  // namespace internal_battery

/// Runs the whole battery on `map` (see the top of this file).
inline void RunFeatureMapBattery(const FeatureMap& map,
                                 const BatteryOptions& options = BatteryOptions()) {
  namespace ib = internal_battery;
  SCOPED_TRACE(ib::Describe(map, options));
  ib::CheckDimensions(map);
  if (::testing::Test::HasFatalFailure()) return;

  const Matrix X = RandomStates(map.input_dim(), options.num_states, options.seed);
  const Matrix Phi = ib::CheckEvaluate(map, X, options);
  ib::CheckNoAllocation(map, X, options);
  ib::CheckConcurrent(map, X, Phi, options.num_threads);

  std::vector<Vector> shapes = options.shapes;
  if (shapes.empty()) {
    const Vector s0 = map.default_shape_parameters();
    shapes = {s0, (s0.array() + 0.7).matrix(), (s0.array() - 1.1).matrix()};
    if (map.num_shape_parameters() == 0) shapes.resize(1);
  }
  for (const Vector& shape : shapes) {
    std::ostringstream os;
    os << "shape = [" << shape.transpose() << "]";
    SCOPED_TRACE(os.str());
    ASSERT_EQ(shape.size(), map.num_shape_parameters());
    ib::CheckPriorDerivative(map, shape, options);
    ib::CheckGram(map, X, Phi, shape, options);
  }
}

}  // namespace testing
}  // namespace structgp

#endif  // STRUCTGP_TESTING_FEATURE_MAP_BATTERY_H_
