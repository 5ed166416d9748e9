// GaussianProcess picks the cheaper form (weight space when D <= m) and both forms give the
// same posterior through it.

#include <random>

#include <gtest/gtest.h>

#include "structgp/feature/random_feature_map.h"
#include "structgp/model/gaussian_process.h"

namespace structgp {
namespace {

struct Data {
  Matrix X, Y;
};

Data MakeData(int m, int d, int P, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal;
  Data data;
  data.X = Matrix::NullaryExpr(m, d, [&]() { return normal(rng); });
  data.Y = Matrix::NullaryExpr(m, P, [&]() { return normal(rng); });
  return data;
}

TEST(GaussianProcess, AutoFormPicksTheCheaperForm) {
  auto map = std::make_shared<RandomFeatureMap>(4, 30, 3, 7);
  const Hyperparameters h = DefaultHyperparameters(*map, 2);
  const Data many = MakeData(60, 4, 2, 1), few = MakeData(20, 4, 2, 2);
  GaussianProcess a(map, h, 2);
  ASSERT_EQ(a.Fit(many.X, many.Y), Status::kOk);
  EXPECT_EQ(a.form(), Form::kWeightSpace);  // D = 30 <= m = 60
  EXPECT_NE(a.weight_space(), nullptr);
  GaussianProcess b(map, h, 2);
  ASSERT_EQ(b.Fit(few.X, few.Y), Status::kOk);
  EXPECT_EQ(b.form(), Form::kFunctionSpace);  // D = 30 > m = 20
  EXPECT_NE(b.function_space(), nullptr);
}

TEST(GaussianProcess, ForcedFormsAgree) {
  for (unsigned seed : {3u, 4u}) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    auto map = std::make_shared<RandomFeatureMap>(3, 25, 2, seed);
    Hyperparameters h = DefaultHyperparameters(*map, 3);
    h.log_noise_std = -1.5;
    h.log_output_scale << 0.1, -0.2, 0.3;
    const Data train = MakeData(40, 3, 3, seed + 10), test = MakeData(10, 3, 3, seed + 20);
    GaussianProcess ws(map, h, 3, Form::kWeightSpace), fs(map, h, 3, Form::kFunctionSpace);
    ASSERT_EQ(ws.Fit(train.X, train.Y), Status::kOk);
    ASSERT_EQ(fs.Fit(train.X, train.Y), Status::kOk);
    ASSERT_EQ(ws.form(), Form::kWeightSpace);
    ASSERT_EQ(fs.form(), Form::kFunctionSpace);
    EXPECT_NEAR(ws.LogMarginalLikelihood(), fs.LogMarginalLikelihood(),
                1e-8 * std::abs(fs.LogMarginalLikelihood()));
    Vector m1(3), l1(3), n1(3), m2(3), l2(3), n2(3);
    for (int i = 0; i < test.X.rows(); ++i) {
      const Vector x = test.X.row(i).transpose();
      ASSERT_EQ(ws.PredictWithVariance(x, m1, l1, n1), Status::kOk);
      ASSERT_EQ(fs.PredictWithVariance(x, m2, l2, n2), Status::kOk);
      EXPECT_LT((m1 - m2).norm(), 1e-8 * m2.norm());
      EXPECT_LT((l1 - l2).norm(), 1e-8 * l2.norm());
      EXPECT_LT((n1 - n2).norm(), 1e-8 * n2.norm());
    }
    // Online additions keep the forms equal.
    fs.mutable_function_space()->Reserve(60);
    for (int i = 0; i < 5; ++i) {
      ASSERT_EQ(ws.Add(test.X.row(i).transpose(), test.Y.row(i).transpose()), Status::kOk);
      ASSERT_EQ(fs.Add(test.X.row(i).transpose(), test.Y.row(i).transpose()), Status::kOk);
    }
    ws.Predict(test.X.row(7).transpose(), m1);
    fs.Predict(test.X.row(7).transpose(), m2);
    EXPECT_LT((m1 - m2).norm(), 1e-8 * m2.norm());
  }
}

TEST(GaussianProcess, BadInputThrowsOrReportsStatus) {
  auto map = std::make_shared<RandomFeatureMap>(3, 10, 1, 5);
  GaussianProcess gp(map, DefaultHyperparameters(*map, 1), 1);
  Data d = MakeData(20, 3, 1, 6);
  d.X(4, 2) = std::nan("");
  EXPECT_THROW(gp.Fit(d.X, d.Y), std::invalid_argument);
  EXPECT_THROW(gp.Fit(d.X.leftCols(2), d.Y), std::invalid_argument);
  d.X(4, 2) = 0.0;
  ASSERT_EQ(gp.Fit(d.X, d.Y), Status::kOk);
  Vector mean(1);
  EXPECT_EQ(gp.Predict(Vector::Constant(3, HUGE_VAL), mean), Status::kInvalidInput);
  EXPECT_EQ(gp.Predict(Vector::Zero(2), mean), Status::kInvalidInput);
}

}  // namespace
}  // namespace structgp
