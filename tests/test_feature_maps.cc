// Tests of the feature maps: the invariant battery for every map, the dimension bound (38) of
// the paper, the composition (17) of k_pol from its component kernels (7), (8), (18), and the
// split of k_pol into its physical blocks.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "battery_options.h"
#include "structgp/feature/friction_feature_map.h"
#include "structgp/feature/gravity_basis_feature_map.h"
#include "structgp/feature/motor_feature_map.h"
#include "structgp/feature/pol_feature_map.h"
#include "structgp/feature/pol_kernel_formula.h"
#include "structgp/feature/random_feature_map.h"
#include "structgp/feature/sum_feature_map.h"

namespace structgp {
namespace {

using testing::BatteryOptions;
using testing::CountingBatteryOptions;
using testing::RandomStates;
using testing::RunFeatureMapBattery;

constexpr double kEps = 2.220446049250313e-16;

// ---- Component kernels coded independently of the library, straight from the paper. -------

double RefQdd(const Vector& a, const Vector& b, int n) {  // (7)
  return a.segment(2 * n, n).dot(b.segment(2 * n, n)) / n;
}

double RefQdQd(const Vector& a, const Vector& b, int n) {  // (8)
  const double d = a.segment(n, n).dot(b.segment(n, n));
  return d * d / (static_cast<double>(n) * n);
}

double RefPsi(const Vector& a, const Vector& b, int n) {  // (9)
  double k = 1.0;
  for (int j = 0; j < n; ++j) k *= std::cos(a[j] - b[j]) + 1.0;
  return k;
}

double RefCPsi(int n, double sigma) { return std::pow((2.0 + sigma) / (1.0 + sigma), -n); }

double RefPsiSigma(const Vector& a, const Vector& b, int n, double sigma) {  // (18)
  const double theta = 1.0 / (1.0 + sigma);
  double k = RefCPsi(n, sigma);
  for (int j = 0; j < n; ++j) k *= 1.0 + theta * std::cos(a[j] - b[j]);
  return k;
}

double RefPol(const Vector& a, const Vector& b, int n, double sigma) {  // (17)
  const double theta = 1.0 / (1.0 + sigma);
  const double psi = RefPsiSigma(a, b, n, sigma);
  return (RefQdd(a, b, n) + theta * RefQdQd(a, b, n)) * psi * psi + psi - RefCPsi(n, sigma);
}

double RefFriction(const Vector& a, const Vector& b, int n, double sigma_f, bool shared_offset) {
  double k = shared_offset ? 1.0 : n;
  for (int j = 0; j < n; ++j) {
    k += a[n + j] * b[n + j] + std::tanh(a[n + j] / sigma_f) * std::tanh(b[n + j] / sigma_f);
  }
  return k;
}

double RefMotor(const Vector& a, const Vector& b, int n) {
  return a.segment(n, 2 * n).dot(b.segment(n, 2 * n));
}

std::vector<Vector> LogSigmas(std::initializer_list<double> values) {
  std::vector<Vector> shapes;
  for (double v : values) shapes.push_back(Vector::Constant(1, v));
  return shapes;
}

// ---- Battery for every map. --------------------------------------------------------------------

TEST(FeatureMapBattery, Pol) {
  for (int n = 1; n <= 4; ++n) {
    SCOPED_TRACE("N = " + std::to_string(n));
    const PolFeatureMap map(n);
    BatteryOptions opt = CountingBatteryOptions();
    opt.seed = 1000 + static_cast<std::uint64_t>(n);
    opt.num_states = n == 4 ? 12 : 30;  // D = 8830 at N = 4: keep the Gram check small
    opt.shapes = LogSigmas({-2.0, 0.0, 0.8, 3.0});
    opt.reference_kernel = [n](const Vector& a, const Vector& b, const Vector& s) {
      return PolKernel(a, b, n, std::exp(s[0]));
    };
    RunFeatureMapBattery(map, opt);
  }
}

TEST(FeatureMapBattery, PolGravityFree) {
  for (int n = 1; n <= 3; ++n) {
    SCOPED_TRACE("N = " + std::to_string(n));
    PolOptions options;
    options.include_gravity = false;
    const PolFeatureMap map(n, options);
    BatteryOptions opt = CountingBatteryOptions();
    opt.seed = 2000 + static_cast<std::uint64_t>(n);
    opt.shapes = LogSigmas({-1.0, 0.0, 1.5});
    opt.reference_kernel = [n](const Vector& a, const Vector& b, const Vector& s) {
      return PolKernelGravityFree(a, b, n, std::exp(s[0]));
    };
    RunFeatureMapBattery(map, opt);
  }
}

TEST(FeatureMapBattery, GravityBasis) {
  for (int n = 1; n <= 4; ++n) {
    SCOPED_TRACE("N = " + std::to_string(n));
    const GravityBasisFeatureMap broad(n);
    BatteryOptions opt = CountingBatteryOptions();
    opt.seed = 3000 + static_cast<std::uint64_t>(n);
    // Unit weights: sum over alpha != 0 of U_alpha U_alpha = prod_n (1 + cos d_n) - 1.
    opt.reference_kernel = [n](const Vector& a, const Vector& b, const Vector&) {
      return RefPsi(a, b, n) - 1.0;
    };
    RunFeatureMapBattery(broad, opt);

    GravityBasisOptions pol_prior;
    pol_prior.pol_prior = true;
    const GravityBasisFeatureMap weighted(n, pol_prior);
    opt.shapes = LogSigmas({-1.0, 0.0, 2.0});
    opt.reference_kernel = [n](const Vector& a, const Vector& b, const Vector& s) {
      const double sigma = std::exp(s[0]);
      return RefPsiSigma(a, b, n, sigma) - RefCPsi(n, sigma);
    };
    RunFeatureMapBattery(weighted, opt);
  }
}

TEST(FeatureMapBattery, Friction) {
  for (int n : {1, 3}) {
    for (bool shared : {true, false}) {
      SCOPED_TRACE("N = " + std::to_string(n) + (shared ? ", shared offset" : ", offsets"));
      FrictionOptions options;
      options.sigma_f = 0.05;
      options.shared_offset = shared;
      const FrictionFeatureMap map(n, options);
      BatteryOptions opt = CountingBatteryOptions();
      opt.seed = 4000 + static_cast<std::uint64_t>(n);
      opt.reference_kernel = [n, shared](const Vector& a, const Vector& b, const Vector&) {
        return RefFriction(a, b, n, 0.05, shared);
      };
      RunFeatureMapBattery(map, opt);
    }
  }
}

TEST(FeatureMapBattery, Motor) {
  for (int n : {1, 3}) {
    SCOPED_TRACE("N = " + std::to_string(n));
    const MotorFeatureMap map(n);
    BatteryOptions opt = CountingBatteryOptions();
    opt.seed = 5000 + static_cast<std::uint64_t>(n);
    opt.reference_kernel = [n](const Vector& a, const Vector& b, const Vector&) {
      return RefMotor(a, b, n);
    };
    RunFeatureMapBattery(map, opt);
  }
}

TEST(FeatureMapBattery, PolPlusFriction) {
  const int n = 2;
  const SumFeatureMap map(
      {std::make_shared<PolFeatureMap>(n), std::make_shared<FrictionFeatureMap>(n, 0.1)});
  BatteryOptions opt = CountingBatteryOptions();
  opt.seed = 6001;
  opt.shapes = LogSigmas({-0.5, 0.0, 1.0});
  opt.reference_kernel = [](const Vector& a, const Vector& b, const Vector& s) {
    return RefPol(a, b, n, std::exp(s[0])) + RefFriction(a, b, n, 0.1, true);
  };
  RunFeatureMapBattery(map, opt);
}

TEST(FeatureMapBattery, MotorPlusFriction) {
  const int n = 3;
  const SumFeatureMap map(
      {std::make_shared<MotorFeatureMap>(n), std::make_shared<FrictionFeatureMap>(n, 0.02)});
  BatteryOptions opt = CountingBatteryOptions();
  opt.seed = 6002;
  opt.reference_kernel = [](const Vector& a, const Vector& b, const Vector&) {
    return RefMotor(a, b, n) + RefFriction(a, b, n, 0.02, true);
  };
  RunFeatureMapBattery(map, opt);
}

// Gravity-free pol plus the pol-weighted gravity basis is k_pol again when both log_sigma agree
// (eq. 55 + parametric gravity with the prior of eq. 18).
TEST(FeatureMapBattery, GravityFreePolPlusGravityBasis) {
  const int n = 2;
  PolOptions no_gravity;
  no_gravity.include_gravity = false;
  GravityBasisOptions pol_prior;
  pol_prior.pol_prior = true;
  const SumFeatureMap map({std::make_shared<PolFeatureMap>(n, no_gravity),
                           std::make_shared<GravityBasisFeatureMap>(n, pol_prior)});
  EXPECT_EQ(map.dim(), PolFeatureDimension(n));
  ASSERT_EQ(map.shape_parameter_names(), (std::vector<std::string>{"log_sigma.0", "log_sigma.1"}));
  BatteryOptions opt = CountingBatteryOptions();
  opt.seed = 6003;
  opt.shapes = {Vector::Constant(2, 0.3), (Vector(2) << -1.0, 1.2).finished()};
  opt.reference_kernel = [](const Vector& a, const Vector& b, const Vector& s) {
    const double s1 = std::exp(s[1]);
    return PolKernelGravityFree(a, b, n, std::exp(s[0])) + RefPsiSigma(a, b, n, s1) -
           RefCPsi(n, s1);
  };
  RunFeatureMapBattery(map, opt);
}

TEST(FeatureMapBattery, Random) {
  const RandomFeatureMap map(5, 40, 3, 11);
  BatteryOptions opt = CountingBatteryOptions();
  opt.seed = 7001;
  opt.reference_kernel = [&map](const Vector& a, const Vector& b, const Vector& s) {
    double k = 0.0;
    const int d = map.dim();
    for (int i = 0; i < d; ++i) {
      const double w = std::exp(-std::exp(s[0]) * i / d);
      k += w * std::cos(map.frequencies().row(i).dot(a) + map.phases()[i]) *
           std::cos(map.frequencies().row(i).dot(b) + map.phases()[i]);
    }
    return k;
  };
  RunFeatureMapBattery(map, opt);
  // A robot-sized random map, and a sum with colliding block and shape names.
  RunFeatureMapBattery(RandomFeatureMap(6, 100, 7, 12), CountingBatteryOptions());
  const SumFeatureMap twice({std::make_shared<RandomFeatureMap>(3, 10, 2, 1),
                             std::make_shared<RandomFeatureMap>(3, 20, 3, 2)});
  RunFeatureMapBattery(twice, CountingBatteryOptions());
}

// ---- Pol: dimension, composition, block split, explicit values. ------------------------------

TEST(PolFeatureMap, DimensionEqualsBound38) {
  const int expected[] = {12, 133, 1151, 8830, 62742, 422603, 2736561};
  for (int n = 1; n <= kMaxPolJoints; ++n) {
    EXPECT_EQ(PolFeatureDimension(n), expected[n - 1]) << "N = " << n;
    const int bound = (n + n * (n + 1) / 2) * static_cast<int>(std::pow(5, n)) +
                      static_cast<int>(std::pow(3, n)) - 1;
    EXPECT_EQ(PolFeatureDimension(n), bound);
  }
  for (int n = 1; n <= 4; ++n) {
    const PolFeatureMap map(n);
    EXPECT_EQ(map.dim(), expected[n - 1]);
    EXPECT_EQ(map.input_dim(), 3 * n);
    PolOptions no_gravity;
    no_gravity.include_gravity = false;
    EXPECT_EQ(PolFeatureMap(n, no_gravity).dim(), expected[n - 1] - (map.num_u() - 1));
  }
}

TEST(PolFeatureMap, RejectsBadJointCounts) {
  EXPECT_THROW(PolFeatureMap(0), std::invalid_argument);
  EXPECT_THROW(PolFeatureMap(kMaxPolJoints + 1), std::invalid_argument);
  EXPECT_THROW(PolFeatureDimension(0), std::invalid_argument);
  EXPECT_THROW(GravityBasisFeatureMap(0), std::invalid_argument);
}

// k_pol = (k_qdd + theta k_qdqd) k_psisigma^2 + k_psisigma - c_psi, with every component coded
// separately above, against the library's formulas.
TEST(PolKernelFormula, CompositionIdentity) {
  for (int n = 1; n <= 7; ++n) {
    const std::uint64_t seed = 8000 + static_cast<std::uint64_t>(n);
    SCOPED_TRACE("N = " + std::to_string(n) + ", seed " + std::to_string(seed));
    const Matrix X = RandomStates(3 * n, 8, seed);
    for (double sigma : {0.0, 0.3, 1.0, 4.0}) {
      for (int i = 0; i < X.rows(); ++i) {
        for (int j = 0; j < X.rows(); ++j) {
          const Vector a = X.row(i).transpose(), b = X.row(j).transpose();
          const double tol = 1e-13 * (1.0 + std::abs(RefPol(a, b, n, sigma)));
          EXPECT_NEAR(QddKernel(a, b, n), RefQdd(a, b, n), 1e-14);
          EXPECT_NEAR(QdQdKernel(a, b, n), RefQdQd(a, b, n), 1e-14 * (1 + RefQdQd(a, b, n)));
          EXPECT_NEAR(PsiKernel(a, b, n), RefPsi(a, b, n), 1e-13 * std::pow(2.0, n));
          EXPECT_NEAR(PsiSigmaKernel(a, b, n, sigma), RefPsiSigma(a, b, n, sigma), 1e-14);
          EXPECT_NEAR(PolKernel(a, b, n, sigma), RefPol(a, b, n, sigma), tol);
          const double psi = RefPsiSigma(a, b, n, sigma);
          EXPECT_NEAR(PolKernelGravityFree(a, b, n, sigma),
                      RefPol(a, b, n, sigma) - psi + RefCPsi(n, sigma), tol);
        }
        // k_psi_sigma(x, x) = 1, and sigma = 0 gives k_psi scaled by 2^-N.
        const Vector a = X.row(i).transpose();
        EXPECT_NEAR(PsiSigmaKernel(a, a, n, sigma), 1.0, 1e-14);
        EXPECT_NEAR(PsiSigmaKernel(a, X.row(0).transpose(), n, 0.0),
                    std::pow(2.0, -n) * RefPsi(a, X.row(0).transpose(), n), 1e-14);
      }
    }
    // sigma = +inf: theta = 0, c_psi = 1, k_pol = k_qdd.
    const Vector a = X.row(0).transpose(), b = X.row(5).transpose();
    EXPECT_NEAR(PolKernel(a, b, n, HUGE_VAL), RefQdd(a, b, n), 1e-14);
  }
}

TEST(PolKernelFormula, DerivativeMatchesCentralDifference) {
  const double h = 1e-5;
  for (int n = 1; n <= 5; ++n) {
    const std::uint64_t seed = 8100 + static_cast<std::uint64_t>(n);
    SCOPED_TRACE("N = " + std::to_string(n) + ", seed " + std::to_string(seed));
    const Matrix X = RandomStates(3 * n, 6, seed);
    for (double log_sigma : {-3.0, -0.5, 0.0, 1.0, 4.0}) {
      for (int i = 0; i < X.rows(); ++i) {
        const Vector a = X.row(i).transpose(), b = X.row((i + 2) % X.rows()).transpose();
        double d = 0.0, d_free = 0.0;
        PolKernel(a, b, n, std::exp(log_sigma), &d);
        PolKernelGravityFree(a, b, n, std::exp(log_sigma), &d_free);
        const double fd = (PolKernel(a, b, n, std::exp(log_sigma + h)) -
                           PolKernel(a, b, n, std::exp(log_sigma - h))) /
                          (2 * h);
        const double fd_free = (PolKernelGravityFree(a, b, n, std::exp(log_sigma + h)) -
                                PolKernelGravityFree(a, b, n, std::exp(log_sigma - h))) /
                               (2 * h);
        const double scale = 1.0 + std::abs(RefQdd(a, b, n)) + std::abs(RefQdQd(a, b, n));
        EXPECT_NEAR(d, fd, 1e-7 * scale) << "log sigma " << log_sigma;
        EXPECT_NEAR(d_free, fd_free, 1e-7 * scale) << "log sigma " << log_sigma;
      }
    }
    // sigma = 0 is a stationary point in log sigma: d/d log sigma = 0.
    double d0 = 1.0;
    PolKernel(X.row(0).transpose(), X.row(1).transpose(), n, 0.0, &d0);
    EXPECT_EQ(d0, 0.0);
  }
}

TEST(PolKernelFormula, RejectsBadArguments) {
  const Vector a = Vector::Zero(6), b = Vector::Zero(5);
  EXPECT_THROW(PolKernel(a, b, 2, 1.0), std::invalid_argument);
  EXPECT_THROW(PolKernel(a, a, 3, 1.0), std::invalid_argument);
  EXPECT_THROW(PolKernel(a, a, 2, -1.0), std::invalid_argument);
  EXPECT_THROW(PolKernel(a, a, 2, std::nan("")), std::invalid_argument);
  EXPECT_THROW(QddKernel(a, a, 0), std::invalid_argument);
}

// Each block of the map carries one physical term of (17):
//   inertial: k_qdd k_psisigma^2, coriolis: theta k_qdqd k_psisigma^2, gravity: k_psisigma - c.
TEST(PolFeatureMap, BlocksSplitTheKernelIntoItsPhysicalTerms) {
  for (int n = 1; n <= 3; ++n) {
    const std::uint64_t seed = 8200 + static_cast<std::uint64_t>(n);
    SCOPED_TRACE("N = " + std::to_string(n) + ", seed " + std::to_string(seed));
    const PolFeatureMap map(n);
    const auto blocks = map.blocks();
    ASSERT_EQ(blocks.size(), 3u);
    EXPECT_EQ(blocks[0].name, "inertial");
    EXPECT_EQ(blocks[1].name, "coriolis");
    EXPECT_EQ(blocks[2].name, "gravity");
    EXPECT_EQ(blocks[0].size, n * map.num_v());
    EXPECT_EQ(blocks[1].size, n * (n + 1) / 2 * map.num_v());
    EXPECT_EQ(blocks[2].size, map.num_u() - 1);
    const Matrix X = RandomStates(3 * n, 6, seed);
    Vector pa(map.dim()), pb(map.dim()), lambda(map.dim());
    for (double log_sigma : {-1.0, 0.0, 2.0}) {
      const double sigma = std::exp(log_sigma);
      const double theta = 1.0 / (1.0 + sigma);
      map.PriorVariance(Vector::Constant(1, log_sigma), lambda);
      for (int i = 0; i < X.rows(); ++i) {
        const Vector a = X.row(i).transpose(), b = X.row((i + 1) % X.rows()).transpose();
        map.Evaluate(a, pa);
        map.Evaluate(b, pb);
        const double psi = RefPsiSigma(a, b, n, sigma);
        const double expected[3] = {RefQdd(a, b, n) * psi * psi,
                                    theta * RefQdQd(a, b, n) * psi * psi, psi - RefCPsi(n, sigma)};
        for (int k = 0; k < 3; ++k) {
          const auto seg = [&](const Vector& v) {
            return v.segment(blocks[k].begin, blocks[k].size);
          };
          const Vector terms = seg(lambda).cwiseProduct(seg(pa)).cwiseProduct(seg(pb));
          const double tol = 1e-12 * terms.cwiseAbs().sum() + 10 * kEps;
          EXPECT_NEAR(terms.sum(), expected[k], tol) << "block " << blocks[k].name;
        }
      }
    }
  }
}

// The layout of the documentation, checked entry by entry for N = 1 at sigma = 1.
TEST(PolFeatureMap, ExplicitValuesForOneJoint) {
  const PolFeatureMap map(1);
  const double q = 0.3, qd = -0.7, qdd = 1.9;
  const Vector x = (Vector(3) << q, qd, qdd).finished();
  Vector phi(map.dim());
  map.Evaluate(x, phi);
  const double v[5] = {1.0, std::cos(q), std::sin(q), std::cos(2 * q), std::sin(2 * q)};
  for (int k = 0; k < 5; ++k) {
    EXPECT_NEAR(phi[k], qdd * v[k], 1e-15);
    EXPECT_NEAR(phi[5 + k], qd * qd * v[k], 1e-15);
  }
  EXPECT_NEAR(phi[10], std::cos(q), 1e-15);
  EXPECT_NEAR(phi[11], std::sin(q), 1e-15);

  Vector lambda(map.dim());
  map.PriorVariance(Vector::Zero(1), lambda);  // sigma = 1: theta = 1/2, c_psi = 2/3
  const double c = 2.0 / 3.0, th = 0.5;
  const double w[5] = {1 + th * th / 2, 2 * th, 2 * th, th * th / 2, th * th / 2};
  for (int k = 0; k < 5; ++k) {
    EXPECT_NEAR(lambda[k], c * c * w[k], 1e-15);
    EXPECT_NEAR(lambda[5 + k], th * c * c * w[k], 1e-15);
  }
  EXPECT_NEAR(lambda[10], c * th, 1e-15);
  EXPECT_NEAR(lambda[11], c * th, 1e-15);
}

// Joint 1 is the most significant digit of beta: for N = 2, feature beta = (b1, b2) of the
// first inertial sub-block is qdd_1 v_b1(q_1) v_b2(q_2) at index 5 b1 + b2.
TEST(PolFeatureMap, MultiIndexOrderForTwoJoints) {
  const PolFeatureMap map(2);
  const Vector x = (Vector(6) << 0.4, -1.2, 0.5, 0.25, 2.0, -3.0).finished();
  Vector phi(map.dim());
  map.Evaluate(x, phi);
  const auto v = [](double q, int i) {
    const double f[5] = {1.0, std::cos(q), std::sin(q), std::cos(2 * q), std::sin(2 * q)};
    return f[i];
  };
  const auto u = [](double q, int i) {
    const double f[3] = {1.0, std::cos(q), std::sin(q)};
    return f[i];
  };
  for (int b1 = 0; b1 < 5; ++b1) {
    for (int b2 = 0; b2 < 5; ++b2) {
      const double vb = v(0.4, b1) * v(-1.2, b2);
      const int k = 5 * b1 + b2;
      EXPECT_NEAR(phi[k], 2.0 * vb, 1e-14);                // qdd_1 V
      EXPECT_NEAR(phi[25 + k], -3.0 * vb, 1e-14);          // qdd_2 V
      EXPECT_NEAR(phi[50 + k], 0.5 * 0.5 * vb, 1e-14);     // qd_1 qd_1 V
      EXPECT_NEAR(phi[75 + k], 0.5 * 0.25 * vb, 1e-14);    // qd_1 qd_2 V
      EXPECT_NEAR(phi[100 + k], 0.25 * 0.25 * vb, 1e-14);  // qd_2 qd_2 V
    }
  }
  for (int a = 1; a < 9; ++a) {
    EXPECT_NEAR(phi[125 + a - 1], u(0.4, a / 3) * u(-1.2, a % 3), 1e-15);
  }
  const GravityBasisFeatureMap gravity(2);
  EXPECT_EQ(gravity.feature_name(0), "gravity[0,1]");
  EXPECT_EQ(gravity.feature_name(7), "gravity[2,2]");
}

// ---- Friction, motor, sum, random: names, indices and errors. -----------------------------

TEST(FrictionFeatureMap, NamesAndIndices) {
  const FrictionFeatureMap shared(2, 0.05);
  EXPECT_EQ(shared.dim(), 5);
  EXPECT_EQ(shared.feature_names(), (std::vector<std::string>{"viscous@1", "coulomb@1", "viscous@2",
                                                              "coulomb@2", "offset"}));
  EXPECT_EQ(shared.indices(1).viscous, 2);
  EXPECT_EQ(shared.indices(1).coulomb, 3);
  EXPECT_EQ(shared.indices(0).offset, 4);
  EXPECT_EQ(shared.indices(1).offset, 4);
  EXPECT_THROW(shared.indices(2), std::invalid_argument);

  FrictionOptions options;
  options.sigma_f = 0.05;
  options.shared_offset = false;
  const FrictionFeatureMap per_joint(2, options);
  EXPECT_EQ(per_joint.dim(), 6);
  EXPECT_EQ(per_joint.feature_names(),
            (std::vector<std::string>{"viscous@1", "coulomb@1", "offset@1", "viscous@2",
                                      "coulomb@2", "offset@2"}));
  EXPECT_EQ(per_joint.indices(1).offset, 5);

  const Vector x = (Vector(6) << 0.1, 0.2, 0.03, -0.5, 9.0, 9.0).finished();
  Vector phi(5);
  shared.Evaluate(x, phi);
  EXPECT_DOUBLE_EQ(phi[0], 0.03);
  EXPECT_DOUBLE_EQ(phi[1], std::tanh(0.03 / 0.05));
  EXPECT_DOUBLE_EQ(phi[2], -0.5);
  EXPECT_DOUBLE_EQ(phi[3], std::tanh(-0.5 / 0.05));
  EXPECT_DOUBLE_EQ(phi[4], 1.0);

  EXPECT_THROW(FrictionFeatureMap(2, 0.0), std::invalid_argument);
  EXPECT_THROW(FrictionFeatureMap(2, -1.0), std::invalid_argument);
  EXPECT_THROW(FrictionFeatureMap(0, 0.1), std::invalid_argument);
}

TEST(MotorFeatureMap, NamesAndValues) {
  const MotorFeatureMap map(2);
  EXPECT_EQ(map.feature_names(), (std::vector<std::string>{"acceleration@1", "velocity@1",
                                                           "acceleration@2", "velocity@2"}));
  const Vector x = (Vector(6) << 0.1, 0.2, 3.0, 4.0, 5.0, 6.0).finished();
  Vector phi(4);
  map.Evaluate(x, phi);
  EXPECT_EQ(phi, (Vector(4) << 5.0, 3.0, 6.0, 4.0).finished());
  EXPECT_EQ(map.acceleration_index(1), 2);
  EXPECT_EQ(map.velocity_index(1), 3);
  EXPECT_THROW(MotorFeatureMap(0), std::invalid_argument);
}

TEST(SumFeatureMap, ConcatenatesAndRenamesCollisions) {
  const auto pol = std::make_shared<PolFeatureMap>(2);
  const auto fri = std::make_shared<FrictionFeatureMap>(2, 0.1);
  const SumFeatureMap sum({pol, fri});
  EXPECT_EQ(sum.dim(), pol->dim() + fri->dim());
  EXPECT_EQ(sum.part_begin(1), pol->dim());
  const auto blocks = sum.blocks();
  ASSERT_EQ(blocks.size(), 4u);
  EXPECT_EQ(blocks[3].name, "friction");
  EXPECT_EQ(blocks[3].begin, pol->dim());
  EXPECT_EQ(sum.shape_parameter_names(), std::vector<std::string>{"log_sigma"});

  const SumFeatureMap twice({std::make_shared<RandomFeatureMap>(3, 10, 2, 1),
                             std::make_shared<RandomFeatureMap>(3, 20, 1, 2)});
  std::vector<std::string> names;
  for (const auto& b : twice.blocks()) names.push_back(b.name);
  EXPECT_EQ(names, (std::vector<std::string>{"b0.0", "b1", "b0.1"}));
  EXPECT_EQ(twice.shape_parameter_names(),
            (std::vector<std::string>{"log_decay.0", "log_decay.1"}));
  Matrix jacobian;
  Vector lambda(twice.dim());
  twice.PriorVariance(Vector::Constant(2, 0.5), lambda, &jacobian);
  EXPECT_EQ(jacobian.topRightCorner(10, 1).norm(), 0.0);
  EXPECT_EQ(jacobian.bottomLeftCorner(20, 1).norm(), 0.0);

  EXPECT_THROW(SumFeatureMap({}), std::invalid_argument);
  EXPECT_THROW(SumFeatureMap({pol, nullptr}), std::invalid_argument);
  EXPECT_THROW(SumFeatureMap({pol, std::make_shared<MotorFeatureMap>(3)}), std::invalid_argument);
}

TEST(RandomFeatureMap, SeedDeterminesTheMapAndBlocksAreBalanced) {
  const RandomFeatureMap a(4, 17, 3, 99), b(4, 17, 3, 99), c(4, 17, 3, 100);
  EXPECT_EQ(a.frequencies(), b.frequencies());
  EXPECT_EQ(a.phases(), b.phases());
  EXPECT_NE(a.frequencies(), c.frequencies());
  const auto blocks = a.blocks();
  ASSERT_EQ(blocks.size(), 3u);
  EXPECT_EQ(blocks[0].size, 5);
  EXPECT_EQ(blocks[1].size, 6);
  EXPECT_EQ(blocks[2].size, 6);
  EXPECT_GE(a.phases().minCoeff(), 0.0);
  EXPECT_LT(a.phases().maxCoeff(), 6.283185307179586);
  // Frequencies are standard normal: mean near 0, variance near 1 over many draws.
  const RandomFeatureMap big(10, 2000, 1, 5);
  const double mean = big.frequencies().mean();
  const double var = big.frequencies().array().square().mean() - mean * mean;
  EXPECT_NEAR(mean, 0.0, 0.03);
  EXPECT_NEAR(var, 1.0, 0.03);
  EXPECT_THROW(RandomFeatureMap(0, 10, 1, 1), std::invalid_argument);
  EXPECT_THROW(RandomFeatureMap(3, 10, 11, 1), std::invalid_argument);
  EXPECT_THROW(RandomFeatureMap(3, 10, 0, 1), std::invalid_argument);
}

}  // namespace
}  // namespace structgp
