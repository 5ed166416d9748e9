// The Lagrangian regressor against KDL: the torques of random serial chains (random joint axes,
// origins, inertias and gravity direction, computed by KDL's recursive Newton-Euler solver) lie
// in its span, term by term, so least squares on it reproduces them and KDL's M(q)qdd, C(q,qd)qd
// and G(q) separately.

#include "structgp/feature/lagrangian_regressor_map.h"

#include <cmath>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/QR>
#include <gtest/gtest.h>

#include "alloc_counter.h"
#include "structgp/model/model_spec.h"
#include "structgp/model/robot_model.h"
#include "structgp/rigid_body/rigid_body_chain.h"
#include "urdf_test_util.h"

namespace structgp {
namespace {

struct Samples {
  Matrix X;                                  // m x 3N states
  Matrix inertial, coriolis, gravity, total;  // m x N, KDL
};

Samples KdlSamples(const RigidBodyChain& chain, int m, unsigned seed) {
  const int N = chain.num_joints();
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-3.0, 3.0);
  Samples s;
  s.X = Matrix::NullaryExpr(m, 3 * N, [&]() { return u(rng); });
  s.inertial.resize(m, N);
  s.coriolis.resize(m, N);
  s.gravity.resize(m, N);
  s.total.resize(m, N);
  for (int i = 0; i < m; ++i) {
    const Vector q = s.X.row(i).head(N).transpose(), qd = s.X.row(i).segment(N, N).transpose(),
                 qdd = s.X.row(i).tail(N).transpose();
    s.inertial.row(i) = (chain.MassMatrix(q) * qdd).transpose();
    s.coriolis.row(i) = chain.Coriolis(q, qd).transpose();
    s.gravity.row(i) = chain.Gravity(q).transpose();
    s.total.row(i) = chain.InverseDynamics(q, qd, qdd).transpose();
  }
  return s;
}

// Stacked least squares of targets (m x N) on component c of the regressor (-1: all).
Vector Solve(const LagrangianRegressorMap& map, const Matrix& X, const Matrix& Y) {
  const int N = map.num_outputs();
  Matrix A(X.rows() * N, map.dim());
  Vector b(X.rows() * N);
  Matrix psi(N, map.dim());
  for (Eigen::Index i = 0; i < X.rows(); ++i) {
    map.Evaluate(X.row(i).transpose(), psi);
    A.middleRows(i * N, N) = psi;
    b.segment(i * N, N) = Y.row(i).transpose();
  }
  return A.colPivHouseholderQr().solve(b);
}

Matrix Predict(const LagrangianRegressorMap& map, const Matrix& X, const Vector& theta, int c) {
  const int N = map.num_outputs();
  Matrix out(X.rows(), N), psi(N, map.dim());
  for (Eigen::Index i = 0; i < X.rows(); ++i) {
    if (c < 0) {
      map.Evaluate(X.row(i).transpose(), psi);
    } else {
      map.EvaluateComponent(c, X.row(i).transpose(), psi, nullptr);
    }
    out.row(i) = (psi * theta).transpose();
  }
  return out;
}

class LagrangianSpan : public ::testing::TestWithParam<int> {};

TEST_P(LagrangianSpan, KdlTorquesOfRandomChainsLieInItsSpanTermByTerm) {
  const int N = GetParam();
  testing::RandomUrdfOptions o;
  o.num_joints = N;
  o.seed = 10 + static_cast<std::uint64_t>(N);
  UrdfOptions urdf;
  urdf.gravity = Eigen::Vector3d(1.0, -2.0, -9.0);  // not along any axis of the chain
  const RigidBodyChain chain = RigidBodyChain::FromUrdfString(testing::RandomUrdf(o), urdf);
  // Some armature too: part of M's constant diagonal.
  Vector pi = chain.parameters();
  for (int j = 0; j < N; ++j) pi[10 * N + j] = 0.05 * (j + 1);
  const RigidBodyChain truth = chain.WithParameters(pi);
  const LagrangianRegressorMap map(N);
  ASSERT_EQ(map.dim(), LagrangianDimension(N));
  const Samples train = KdlSamples(truth, 2 * map.dim() / N + 50, 1);  // twice the unknowns
  const Samples test = KdlSamples(truth, 200, 2);
  const Vector theta = Solve(map, train.X, train.total);
  const double scale = test.total.norm();
  EXPECT_LT((Predict(map, test.X, theta, -1) - test.total).norm(), 1e-9 * scale);
  EXPECT_LT((Predict(map, test.X, theta, 0) - test.inertial).norm(), 1e-9 * scale);
  EXPECT_LT((Predict(map, test.X, theta, 1) - test.coriolis).norm(), 1e-9 * scale);
  EXPECT_LT((Predict(map, test.X, theta, 2) - test.gravity).norm(), 1e-9 * scale);
}

INSTANTIATE_TEST_SUITE_P(Joints, LagrangianSpan, ::testing::Values(1, 2, 3, 4, 5));

TEST(LagrangianRegressorMap, CoriolisTermsComeFromTheInertiaParameters) {
  // Trained on slow motion only (qd ~ 0), the fit still predicts the Coriolis torques of fast
  // motion: they follow from the same parameters as M(q).
  testing::RandomUrdfOptions o;
  o.num_joints = 3;
  o.seed = 3;
  const RigidBodyChain chain = RigidBodyChain::FromUrdfString(testing::RandomUrdf(o));
  const LagrangianRegressorMap map(3);
  Samples slow = KdlSamples(chain, 600, 5);
  slow.X.middleCols(3, 3) *= 1e-3;  // velocities almost zero
  for (Eigen::Index i = 0; i < slow.X.rows(); ++i) {
    slow.total.row(i) = chain
                            .InverseDynamics(slow.X.row(i).head(3).transpose(),
                                             slow.X.row(i).segment(3, 3).transpose(),
                                             slow.X.row(i).tail(3).transpose())
                            .transpose();
  }
  const Vector theta = Solve(map, slow.X, slow.total);
  const Samples fast = KdlSamples(chain, 100, 6);
  EXPECT_LT((Predict(map, fast.X, theta, 1) - fast.coriolis).norm(), 1e-5 * fast.total.norm());
}

TEST(LagrangianRegressorMap, SizesNamesAndErrors) {
  // M_ab (a <= b) with the angles a+1..b at degree 1 and b+1..N at degree 2, plus V's 3^N - 1:
  // N = 2: M_11 5, M_12 3, M_22 1, V 8.
  EXPECT_EQ(LagrangianDimension(1), 3);
  EXPECT_EQ(LagrangianDimension(2), 17);
  EXPECT_EQ(LagrangianDimension(3), 84);
  EXPECT_EQ(LagrangianDimension(4), 410);
  EXPECT_EQ(LagrangianDimension(7), 49374);
  const LagrangianRegressorMap map(2);
  const std::vector<std::string> names = map.parameter_names();
  ASSERT_EQ(names.size(), 17u);
  EXPECT_EQ(names[0], "M1,1[1]");
  EXPECT_EQ(names[1], "M1,1[cos q2]");
  EXPECT_EQ(names[4], "M1,1[sin2 q2]");
  EXPECT_EQ(names[5], "M1,2[1]");
  EXPECT_EQ(names[7], "M1,2[sin q2]");  // no cos2 q2 or sin2 q2 in M_12
  EXPECT_EQ(names[8], "M2,2[1]");
  EXPECT_EQ(names[9], "V[cos q1]");
  // Blocks by the earliest link that can produce a term: M_11's constant needs link 1, any
  // term with q2 or of M_12, M_22 needs link 2.
  const std::vector<FeatureBlock> blocks = map.blocks();
  ASSERT_EQ(blocks.size(), 4u);
  EXPECT_EQ(blocks[0].name, "kinetic 1");
  EXPECT_EQ(blocks[0].size, 1);
  EXPECT_EQ(blocks[1].name, "kinetic 2");
  EXPECT_EQ(blocks[1].size, 8);
  EXPECT_EQ(blocks[2].name, "potential 1");
  EXPECT_EQ(blocks[2].size, 2);  // cos q1, sin q1
  EXPECT_EQ(blocks[3].name, "potential 2");
  EXPECT_THROW(LagrangianRegressorMap(0), std::invalid_argument);
  EXPECT_THROW(LagrangianRegressorMap(kMaxLagrangianJoints + 1), std::invalid_argument);
  Matrix psi(2, map.dim());
  const Vector x = Vector::Constant(6, 0.3);
  testing::AllocationCounter guard;
  map.Evaluate(x, psi, nullptr);
  if (testing::CountsEveryAllocation()) {
    EXPECT_EQ(guard.count(), 0u);
  }
}

// With the serial chain's degrees the weight-space form carries 5 joints within the default
// max_explicit_features (2,013 parameters); at 6 the model is refused naming the limit.
TEST(LagrangianRegressorMap, TheLagModelServesFiveJointsAndNamesTheLimitBeyond) {
  const RobotModel five(ParseModelSpec("lag"), 5);
  ASSERT_NE(five.regressor_map(), nullptr);
  EXPECT_EQ(five.regressor_map()->dim(), LagrangianDimension(5));  // no friction, no effects
  EXPECT_LE(LagrangianDimension(5), RobotModelOptions().max_explicit_features);
  try {
    const RobotModel six(ParseModelSpec("lag"), 6);
    ADD_FAILURE() << "a 6-joint lag model was built";
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("9947 parameters"), std::string::npos) << what;
    EXPECT_NE(what.find("max_explicit_features"), std::string::npos) << what;
  }
}

}  // namespace
}  // namespace structgp
