// PolChainKernel, k_pol restricted to what a serial chain can produce on one joint's torque:
// equal to a brute-force sum over its explicit features (the trig factors expanded in
// 1, cos q, sin q, cos 2q, sin 2q; every (k, l) pair enumerated); equal to k_pol term by term
// at x = x'; the torques of random KDL chains lie in each joint's span (a GP with almost no
// noise reproduces held-out torques), while a function k_pol spans and a chain cannot produce
// (joint N's torque in qdd_N cos q_1) does not; argument errors. Gradient, symmetry,
// positive semi-definiteness and allocation come from the kernel battery (test_kernels.cc).

#include "structgp/kernel/pol_chain_kernel.h"

#include <cmath>
#include <random>
#include <stdexcept>
#include <vector>

#include <gtest/gtest.h>

#include "structgp/kernel/pol_kernel.h"
#include "structgp/model/kernel_gp.h"
#include "structgp/rigid_body/rigid_body_chain.h"
#include "urdf_test_util.h"

namespace structgp {
namespace {

Vector RandomState(int n, std::mt19937_64* rng) {
  std::uniform_real_distribution<double> u(-3.0, 3.0);
  Vector x(3 * n);
  for (int i = 0; i < 3 * n; ++i) x[i] = u(*rng);
  return x;
}

// The explicit features of (1 + theta cos(q - q'))^2 / (1 + theta)^2 at angle q: weights
// 1 + theta^2/2, 2 theta, 2 theta, theta^2/2, theta^2/2 on 1, cos, sin, cos 2q, sin 2q.
Eigen::Matrix<double, 5, 1> SquaredTrigFeatures(double q, double theta) {
  Eigen::Matrix<double, 5, 1> v;
  const double h = 0.5 * theta * theta;
  v << std::sqrt(1.0 + h), std::sqrt(2.0 * theta) * std::cos(q),
      std::sqrt(2.0 * theta) * std::sin(q), std::sqrt(h) * std::cos(2.0 * q),
      std::sqrt(h) * std::sin(2.0 * q);
  return v / (1.0 + theta);
}

// The kernel of the header, term by term, from the features and every index pair.
PolKernelTerms BruteForce(int n, int J, const Vector& a, const Vector& b, const Vector& p) {
  const double theta = 1.0 / (1.0 + std::exp(p[0]));
  // S(m): prod over 1-based l >= m of the squared-trig feature products.
  auto S = [&](int m) {
    double s = 1.0;
    for (int l = m; l <= n; ++l) {
      s *= SquaredTrigFeatures(a[l - 1], theta).dot(SquaredTrigFeatures(b[l - 1], theta));
    }
    return s;
  };
  PolKernelTerms t;
  for (int k = 1; k <= n; ++k) {
    t.inertial += a[2 * n + k - 1] * b[2 * n + k - 1] * S(std::min(J, k) + 1);
    for (int l = 1; l <= n; ++l) {
      t.coriolis += a[n + k - 1] * b[n + k - 1] * a[n + l - 1] * b[n + l - 1] *
                    S(std::min(J, std::min(k, l)) + 1);
    }
  }
  t.inertial *= std::exp(2.0 * p[1]) / n;
  t.coriolis *= std::exp(2.0 * p[2]) * theta / (n * n);
  // Gravity: prod (1 + theta cos d) / (1 + theta)^N minus its constant term.
  double r = 1.0;
  for (int l = 0; l < n; ++l) r *= 1.0 + theta * std::cos(a[l] - b[l]);
  t.gravity = std::exp(2.0 * p[3]) * (r - 1.0) / std::pow(1.0 + theta, n);
  return t;
}

TEST(PolChainKernel, EqualsTheSumOverItsExplicitFeatures) {
  std::mt19937_64 rng(3);
  for (int n = 1; n <= 5; ++n) {
    for (int J = 1; J <= n; ++J) {
      Vector p(4);
      p << 0.3 * n - 0.6, 0.2, -0.4, 0.1 * J;
      const auto kernel = PolChainKernel(n, J).WithParameters(p);
      const auto* chain = static_cast<const PolChainKernel*>(kernel.get());
      for (int i = 0; i < 5; ++i) {
        const Vector a = RandomState(n, &rng), b = i == 0 ? a : RandomState(n, &rng);
        const PolKernelTerms want = BruteForce(n, J, a, b, p);
        const PolKernelTerms got = chain->EvaluateTerms(a, b);
        EXPECT_NEAR(got.inertial, want.inertial, 1e-12 * (1.0 + std::abs(want.inertial)));
        EXPECT_NEAR(got.coriolis, want.coriolis, 1e-12 * (1.0 + std::abs(want.coriolis)));
        EXPECT_NEAR(got.gravity, want.gravity, 1e-12 * (1.0 + std::abs(want.gravity)));
        EXPECT_NEAR(kernel->Evaluate(a, b), want.inertial + want.coriolis + want.gravity,
                    1e-12 * (1.0 + std::abs(want.inertial + want.coriolis + want.gravity)));
      }
    }
  }
}

TEST(PolChainKernel, EqualsPolTermByTermAtTheSameState) {
  std::mt19937_64 rng(4);
  const int n = 4;
  Vector p(4);
  p << -0.2, 0.5, 0.1, -0.3;
  const auto pol = PolFormulaKernel(n).WithParameters(p);
  for (int J = 1; J <= n; ++J) {
    const auto chain = PolChainKernel(n, J).WithParameters(p);
    const Vector x = RandomState(n, &rng);
    const PolKernelTerms a = static_cast<const PolChainKernel&>(*chain).EvaluateTerms(x, x);
    const PolKernelTerms b = static_cast<const PolFormulaKernel&>(*pol).EvaluateTerms(x, x);
    EXPECT_NEAR(a.inertial, b.inertial, 1e-12 * b.inertial);
    EXPECT_NEAR(a.coriolis, b.coriolis, 1e-12 * b.coriolis);
    EXPECT_NEAR(a.gravity, b.gravity, 1e-12 * b.gravity);
    // Away from x = x' the chain kernel drops proximal factors (each <= 1): for the last joint
    // the inertial term of qdd_N alone is no longer damped by the angles.
    const Vector y = RandomState(n, &rng);
    Vector ya = x, yb = y;
    ya.segment(n, 2 * n).setZero();
    yb.segment(n, 2 * n).setZero();
    ya[3 * n - 1] = yb[3 * n - 1] = 1.0;
    if (J == n) {
      EXPECT_NEAR(static_cast<const PolChainKernel&>(*chain).EvaluateTerms(ya, yb).inertial,
                  std::exp(2.0 * p[1]) / n, 1e-14);
    }
  }
}

// Rows of torques of a random KDL chain (random axes, origins, inertias, gravity direction).
struct Torques {
  Matrix X, Y;
};
Torques KdlTorques(const RigidBodyChain& chain, int m, std::uint64_t seed) {
  const int n = chain.num_joints();
  std::mt19937_64 rng(seed);
  Torques t{Matrix(m, 3 * n), Matrix(m, n)};
  for (int i = 0; i < m; ++i) {
    const Vector x = RandomState(n, &rng);
    t.X.row(i) = x.transpose();
    t.Y.row(i) =
        chain.InverseDynamics(x.head(n), x.segment(n, n), x.tail(n)).transpose();
  }
  return t;
}

// Relative RMS error of a GP with kernel k and almost no noise, fitted on (X, y), on (Xt, yt).
double HeldOutError(const Kernel& k, const Matrix& X, const Vector& y, const Matrix& Xt,
                    const Vector& yt) {
  const double scale = std::sqrt(y.squaredNorm() / y.size());
  KernelGP gp(k, 1e-10, 1, Vector::Constant(1, scale));
  EXPECT_EQ(gp.Fit(X, y / scale), Status::kOk);
  Vector mean(1);
  double err = 0.0;
  for (Eigen::Index i = 0; i < Xt.rows(); ++i) {
    EXPECT_EQ(gp.Predict(Xt.row(i).transpose(), mean), Status::kOk);
    err += std::pow(mean[0] * scale - yt[i], 2);
  }
  return std::sqrt(err / yt.squaredNorm());
}

TEST(PolChainKernel, SpansTheTorqueOfEachJointOfRandomChains) {
  const int n = 3;
  for (std::uint64_t seed : {21u, 22u}) {
    testing::RandomUrdfOptions o;
    o.num_joints = n;
    o.seed = seed;
    UrdfOptions urdf;
    urdf.gravity = Eigen::Vector3d(1.0, -2.0, -9.0);
    const RigidBodyChain chain = RigidBodyChain::FromUrdfString(testing::RandomUrdf(o), urdf);
    const Torques train = KdlTorques(chain, 700, seed), test = KdlTorques(chain, 200, seed + 100);
    for (int J = 1; J <= n; ++J) {
      const PolChainKernel k(n, J);
      const double err = HeldOutError(k, train.X, train.Y.col(J - 1), test.X, test.Y.col(J - 1));
      EXPECT_LT(err, 1e-4) << "seed " << seed << ", joint " << J;
    }
  }
}

TEST(PolChainKernel, DoesNotSpanWhatNoChainProducesOnItsJoint) {
  // qdd_N cos q_1 on the last joint: in k_pol's span (every M entry may depend on every angle
  // there), impossible for a chain (M_NN is constant). The two kernels see the same data.
  const int n = 3;
  std::mt19937_64 rng(5);
  auto make = [&](int m) {
    Torques t{Matrix(m, 3 * n), Matrix(m, 1)};
    for (int i = 0; i < m; ++i) {
      const Vector x = RandomState(n, &rng);
      t.X.row(i) = x.transpose();
      t.Y(i, 0) = x[3 * n - 1] * std::cos(x[0]);
    }
    return t;
  };
  const Torques train = make(1600), test = make(200);  // k_pol spans 1,100+ functions at N = 3
  const double chain_err =
      HeldOutError(PolChainKernel(n, n), train.X, train.Y.col(0), test.X, test.Y.col(0));
  const double pol_err =
      HeldOutError(PolFormulaKernel(n), train.X, train.Y.col(0), test.X, test.Y.col(0));
  EXPECT_LT(pol_err, 1e-4);
  EXPECT_GT(chain_err, 0.3);
}

TEST(PolChainKernel, RejectsBadArguments) {
  EXPECT_THROW(PolChainKernel(0, 1), std::invalid_argument);
  EXPECT_THROW(PolChainKernel(3, 0), std::invalid_argument);
  EXPECT_THROW(PolChainKernel(3, 4), std::invalid_argument);
  const PolChainKernel k(3, 2);
  EXPECT_THROW(k.WithParameters(Vector::Zero(3)), std::invalid_argument);
  Vector bad = Vector::Zero(4);
  bad[1] = std::nan("");
  EXPECT_THROW(k.WithParameters(bad), std::invalid_argument);
  EXPECT_EQ(k.parameter_names(),
            (std::vector<std::string>{"log_sigma", "log_scale_inertial", "log_scale_coriolis",
                                      "log_scale_gravity"}));
}

}  // namespace
}  // namespace structgp
