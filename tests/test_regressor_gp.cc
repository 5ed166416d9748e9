// RegressorGP against the dense multi-output GP it stands for: the stacked observations y
// (m N) are Gaussian with mean Psi mu and covariance Psi Lambda Psi^T + diag(sigma^2), written
// out and factorised directly; the gradient against central differences.

#include "structgp/model/regressor_gp.h"

#include <cmath>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Cholesky>
#include <gtest/gtest.h>

#include "alloc_counter.h"
#include "structgp/feature/regressor_map.h"
#include "structgp/hyper/marginal_likelihood.h"

namespace structgp {
namespace {

// Psi(x) = a fixed mix of sin/cos of x, with two blocks; a third block of columns that only
// some rows see, and a column that is zero everywhere (not identified by any data).
class TestRegressor final : public RegressorMap {
 public:
  TestRegressor(int input_dim, int num_outputs, int dim, unsigned seed)
      : input_dim_(input_dim), num_outputs_(num_outputs), dim_(dim) {
    std::mt19937 rng(seed);
    std::normal_distribution<double> normal;
    mix_ = Matrix::NullaryExpr(num_outputs * dim, 2 * input_dim, [&]() { return normal(rng); });
    mean_ = Vector::NullaryExpr(dim, [&]() { return normal(rng); });
    std_ = Vector::NullaryExpr(dim, [&]() { return 0.5 + std::abs(normal(rng)); });
  }
  int input_dim() const override { return input_dim_; }
  int num_outputs() const override { return num_outputs_; }
  int dim() const override { return dim_; }
  using RegressorMap::Evaluate;
  void Evaluate(const ConstVectorRef& x, MatrixRef psi, Scratch*) const override {
    for (int r = 0; r < num_outputs_; ++r) {
      for (int c = 0; c < dim_; ++c) {
        double v = 0.0;
        for (int k = 0; k < input_dim_; ++k) {
          v += mix_(r * dim_ + c, 2 * k) * std::sin(x[k] * (1 + c % 3)) +
               mix_(r * dim_ + c, 2 * k + 1) * std::cos(x[k]);
        }
        psi(r, c) = c == dim_ - 1 ? 0.0 : v;
      }
    }
  }
  std::vector<FeatureBlock> blocks() const override {
    return {{"first", 0, dim_ / 2}, {"second", dim_ / 2, dim_ - dim_ / 2}};
  }
  std::vector<std::string> parameter_names() const override {
    std::vector<std::string> names;
    for (int c = 0; c < dim_; ++c) names.push_back("p" + std::to_string(c));
    return names;
  }
  Vector prior_mean() const override { return mean_; }
  Vector prior_std() const override { return std_; }

 private:
  int input_dim_, num_outputs_, dim_;
  Matrix mix_;
  Vector mean_, std_;
};

struct Data {
  Matrix X, Y;
};

Data MakeData(const RegressorMap& map, int m, const Vector& noise_std, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> normal;
  Data d;
  d.X = Matrix::NullaryExpr(m, map.input_dim(), [&]() { return normal(rng); });
  d.Y.resize(m, map.num_outputs());
  const Vector theta = Vector::NullaryExpr(map.dim(), [&]() { return normal(rng); });
  Matrix psi(map.num_outputs(), map.dim());
  for (int i = 0; i < m; ++i) {
    map.Evaluate(d.X.row(i).transpose(), psi);
    d.Y.row(i) = (psi * theta).transpose();
    for (int j = 0; j < map.num_outputs(); ++j) d.Y(i, j) += noise_std[j] * normal(rng);
  }
  return d;
}

// The stacked regressor (m N x P) and targets (m N), row i N + j.
void Stack(const RegressorMap& map, const Data& d, Matrix* Psi, Vector* y) {
  const int N = map.num_outputs();
  const Eigen::Index m = d.X.rows();
  Psi->resize(m * N, map.dim());
  y->resize(m * N);
  Matrix psi(N, map.dim());
  for (Eigen::Index i = 0; i < m; ++i) {
    map.Evaluate(d.X.row(i).transpose(), psi);
    Psi->middleRows(i * N, N) = psi;
    y->segment(i * N, N) = d.Y.row(i).transpose();
  }
}

double DenseLogEvidence(const RegressorMap& map, const Data& d, const Vector& lambda,
                        const Vector& noise) {
  Matrix Psi;
  Vector y;
  Stack(map, d, &Psi, &y);
  const int N = map.num_outputs();
  Matrix K = Psi * lambda.asDiagonal() * Psi.transpose();
  for (Eigen::Index r = 0; r < K.rows(); ++r) K(r, r) += noise[r % N];
  const Eigen::LLT<Matrix> llt(K);
  const Vector r = y - Psi * map.prior_mean();
  const double logdet = 2.0 * llt.matrixLLT().diagonal().array().log().sum();
  return -0.5 * (r.dot(llt.solve(r)) + logdet + static_cast<double>(K.rows()) * std::log(2 * M_PI));
}

RegressorGP FitModel(const RegressorMap& map, const Data& d, const Vector& lambda,
                     const Vector& noise) {
  RegressorStatistics stats(map.dim(), map.num_outputs());
  stats.Accumulate(map, d.X, d.Y, 7);  // several chunks
  RegressorGP gp(map.prior_mean(), lambda, noise);
  EXPECT_EQ(gp.Fit(stats), Status::kOk);
  return gp;
}

class RegressorGPTest : public ::testing::Test {
 protected:
  RegressorGPTest() : map_(3, 3, 8, 11), noise_std_(3) {
    noise_std_ << 0.05, 0.2, 0.5;
    data_ = MakeData(map_, 40, noise_std_, 3);
    lambda_ = RegressorPriorVariance(map_, Vector::Constant(2, 0.3));
    noise_ = noise_std_.array().square();
  }
  TestRegressor map_;
  Vector noise_std_, lambda_, noise_;
  Data data_;
};

TEST_F(RegressorGPTest, EvidenceEqualsTheDenseMultiOutputGP) {
  const RegressorGP gp = FitModel(map_, data_, lambda_, noise_);
  const double dense = DenseLogEvidence(map_, data_, lambda_, noise_);
  EXPECT_NEAR(gp.LogMarginalLikelihood(), dense, 1e-8 * std::abs(dense));
}

TEST_F(RegressorGPTest, PosteriorEqualsTheDenseMultiOutputGP) {
  const RegressorGP gp = FitModel(map_, data_, lambda_, noise_);
  Matrix Psi;
  Vector y;
  Stack(map_, data_, &Psi, &y);
  const int N = map_.num_outputs();
  Matrix K = Psi * lambda_.asDiagonal() * Psi.transpose();
  for (Eigen::Index r = 0; r < K.rows(); ++r) K(r, r) += noise_[r % N];
  const Eigen::LLT<Matrix> llt(K);
  const Matrix LPt = lambda_.asDiagonal() * Psi.transpose();
  const Vector theta = map_.prior_mean() + LPt * llt.solve(y - Psi * map_.prior_mean());
  const Matrix cov = Matrix(lambda_.asDiagonal()) - LPt * llt.solve(LPt.transpose());
  EXPECT_LT((gp.parameters() - theta).norm(), 1e-8 * theta.norm());
  EXPECT_LT((gp.ParameterCovariance() - cov).norm(), 1e-8 * cov.norm());

  Matrix psi(N, map_.dim());
  map_.Evaluate(Vector::Constant(3, 0.7), psi);
  Vector mean(N), latent(N), noisy(N);
  RegressorGP::Workspace ws = gp.MakeWorkspace();
  ASSERT_EQ(gp.PredictWithVariance(psi, mean, latent, noisy, ws), Status::kOk);
  const Matrix pred_cov = psi * cov * psi.transpose();
  for (int j = 0; j < N; ++j) {
    EXPECT_NEAR(mean[j], psi.row(j).dot(theta), 1e-8);
    EXPECT_NEAR(latent[j], pred_cov(j, j), 1e-8 * pred_cov(j, j) + 1e-14);
    EXPECT_NEAR(noisy[j], pred_cov(j, j) + noise_[j], 1e-8 * noisy[j]);
  }
}

TEST_F(RegressorGPTest, GradientMatchesCentralDifferences) {
  RegressorGP gp = FitModel(map_, data_, lambda_, noise_);
  RegressorEvidenceGradient g;
  gp.LogMarginalLikelihood(&g);
  RegressorStatistics stats = gp.statistics();
  const double h = 1e-5;
  auto evidence = [&](const Vector& lam, const Vector& noise) {
    RegressorGP other(map_.prior_mean(), lam, noise);
    EXPECT_EQ(other.Fit(stats, false), Status::kOk);
    return other.LogMarginalLikelihood();
  };
  for (int k = 0; k < map_.dim(); ++k) {
    Vector up = lambda_, down = lambda_;
    up[k] *= std::exp(h);
    down[k] *= std::exp(-h);
    const double fd = (evidence(up, noise_) - evidence(down, noise_)) / (2 * h);
    EXPECT_NEAR(g.d_log_prior_variance[k], fd, 1e-5 * (1 + std::abs(fd))) << "parameter " << k;
  }
  for (int j = 0; j < map_.num_outputs(); ++j) {
    Vector up = noise_, down = noise_;
    up[j] *= std::exp(h);
    down[j] *= std::exp(-h);
    const double fd = (evidence(lambda_, up) - evidence(lambda_, down)) / (2 * h);
    EXPECT_NEAR(g.d_log_noise_variance[j], fd, 1e-5 * (1 + std::abs(fd))) << "output " << j;
  }
}

TEST_F(RegressorGPTest, StatisticsAddUpOverChunksAndHalves) {
  RegressorStatistics whole(map_.dim(), map_.num_outputs());
  whole.Accumulate(map_, data_.X, data_.Y);
  RegressorStatistics halves(map_.dim(), map_.num_outputs());
  halves.Accumulate(map_, data_.X.topRows(17), data_.Y.topRows(17), 3);
  halves.Accumulate(map_, data_.X.bottomRows(23), data_.Y.bottomRows(23), 5);
  EXPECT_EQ(halves.count, whole.count);
  for (int j = 0; j < map_.num_outputs(); ++j) {
    EXPECT_LT((halves.gram[j] - whole.gram[j]).norm(), 1e-12 * whole.gram[j].norm());
    EXPECT_TRUE(whole.gram[j].isApprox(whole.gram[j].transpose(), 0.0)) << "symmetric";
  }
  EXPECT_LT((halves.cross - whole.cross).norm(), 1e-12 * whole.cross.norm());
  EXPECT_LT((halves.y_squared - whole.y_squared).norm(), 1e-12 * whole.y_squared.norm());
}

TEST_F(RegressorGPTest, PriorHoldsWhatTheDataCannotSee) {
  const RegressorGP gp = FitModel(map_, data_, lambda_, noise_);
  // The last column is zero on every row: its posterior is its prior.
  const int last = map_.dim() - 1;
  EXPECT_NEAR(gp.parameters()[last], map_.prior_mean()[last], 1e-10);
  EXPECT_NEAR(gp.ParameterStd()[last], std::sqrt(lambda_[last]), 1e-10);
  EXPECT_EQ(gp.IdentifiedDirections(), map_.dim() - 1);
}

TEST_F(RegressorGPTest, StateRestoresTheSamePredictions) {
  const RegressorGP gp = FitModel(map_, data_, lambda_, noise_);
  const RegressorGP copy = RegressorGP::FromState(gp.State());
  EXPECT_EQ(copy.parameters(), gp.parameters());
  EXPECT_EQ(copy.LogMarginalLikelihood(), gp.LogMarginalLikelihood());
  RegressorGPState bad = gp.State();
  bad.statistics.gram.pop_back();
  EXPECT_THROW(RegressorGP::FromState(bad), std::invalid_argument);
}

TEST_F(RegressorGPTest, PredictionAllocatesNothingAndRefusesBadInput) {
  const RegressorGP gp = FitModel(map_, data_, lambda_, noise_);
  const int N = map_.num_outputs();
  Matrix psi(N, map_.dim());
  map_.Evaluate(Vector::Constant(3, 0.1), psi);
  Vector mean(N), latent(N), noisy(N);
  RegressorGP::Workspace ws = gp.MakeWorkspace();
  {
    testing::AllocationCounter guard;
    for (int k = 0; k < 10; ++k) {
      ASSERT_EQ(gp.PredictWithVariance(psi, mean, latent, noisy, ws), Status::kOk);
      ASSERT_EQ(gp.Predict(psi, mean), Status::kOk);
    }
    if (testing::CountsEveryAllocation()) {
      EXPECT_EQ(guard.count(), 0u);
    }
  }
  const Vector before = mean;
  psi(1, 2) = std::nan("");
  EXPECT_EQ(gp.PredictWithVariance(psi, mean, latent, noisy, ws), Status::kInvalidInput);
  EXPECT_EQ(mean, before);
  EXPECT_EQ(gp.Predict(Matrix::Zero(N, 2), mean), Status::kInvalidInput);
}

TEST_F(RegressorGPTest, TypeTwoMaximumLikelihoodFindsEachOutputsNoise) {
  const Data big = MakeData(map_, 3000, noise_std_, 9);
  RegressorStatistics stats(map_.dim(), map_.num_outputs());
  stats.Accumulate(map_, big.X, big.Y);
  Hyperparameters hyper;
  hyper.log_block_scale = Vector::Zero(2);
  hyper.log_noise_std = std::log(0.1);
  hyper.log_output_scale = Vector::Zero(3);  // every output starts at noise 0.1
  MaximumLikelihoodOptions options;
  // The objective's gradient against central differences at the start.
  const RegressorEvidenceObjective objective(map_, stats, options, hyper);
  ASSERT_EQ(objective.names().size(), 5u);
  Vector x = objective.Flatten(hyper), g(5);
  double f = 0.0;
  ASSERT_TRUE(objective.Evaluate(x.data(), &f, g.data()));
  for (int i = 0; i < 5; ++i) {
    Vector up = x, down = x;
    up[i] += 1e-6;
    down[i] -= 1e-6;
    double fu = 0.0, fd = 0.0;
    ASSERT_TRUE(objective.Evaluate(up.data(), &fu, nullptr));
    ASSERT_TRUE(objective.Evaluate(down.data(), &fd, nullptr));
    EXPECT_NEAR(g[i], (fu - fd) / 2e-6, 1e-6 * (1 + std::abs(g[i]))) << objective.names()[i];
  }
  const MaximumLikelihoodSummary summary = FitRegressorHyperparameters(map_, stats, options, &hyper);
  ASSERT_TRUE(summary.usable()) << summary.BriefReport();
  EXPECT_LT(summary.final_negative_log_likelihood, summary.initial_negative_log_likelihood);
  for (int j = 0; j < 3; ++j) {
    const double sigma = std::exp(hyper.log_noise_std + hyper.log_output_scale[j]);
    EXPECT_NEAR(sigma / noise_std_[j], 1.0, 0.06) << "output " << j + 1;
  }
}

TEST(RegressorGP, RefusesBadPriorsAndStatistics) {
  EXPECT_THROW(RegressorGP(Vector::Zero(2), Vector::Ones(3), Vector::Ones(1)),
               std::invalid_argument);
  EXPECT_THROW(RegressorGP(Vector::Zero(2), Vector::Constant(2, -1.0), Vector::Ones(1)),
               std::invalid_argument);
  EXPECT_THROW(RegressorGP(Vector::Zero(2), Vector::Ones(2), Vector::Zero(1)),
               std::invalid_argument);
  RegressorGP gp(Vector::Zero(2), Vector::Ones(2), Vector::Ones(2));
  EXPECT_THROW(gp.Fit(RegressorStatistics(3, 2)), std::invalid_argument);
  EXPECT_THROW(gp.LogMarginalLikelihood(), std::logic_error);
  TestRegressor map(2, 2, 4, 1);
  RegressorStatistics stats(4, 2);
  Matrix X = Matrix::Zero(3, 2), Y = Matrix::Zero(3, 2);
  X(1, 1) = std::nan("");
  EXPECT_THROW(stats.Accumulate(map, X, Y), std::invalid_argument);
  EXPECT_EQ(stats.count, 0.0);
}

TEST(RegressorMap, DefaultComponentsAreTheBlocksAndAddUp) {
  TestRegressor map(2, 2, 6, 5);
  const Vector x = Vector::Constant(2, 0.4);
  Matrix full(2, 6), sum = Matrix::Zero(2, 6), part(2, 6);
  map.Evaluate(x, full);
  ASSERT_EQ(map.component_names(), (std::vector<std::string>{"first", "second"}));
  for (int c = 0; c < 2; ++c) {
    map.EvaluateComponent(c, x, part, nullptr);
    sum += part;
  }
  EXPECT_EQ(sum, full);
  const Vector lambda = RegressorPriorVariance(map, Vector::Constant(2, 0.5));
  EXPECT_NEAR(lambda[0], map.prior_std()[0] * map.prior_std()[0] * std::exp(1.0), 1e-14);
  EXPECT_THROW(RegressorPriorVariance(map, Vector::Zero(3)), std::invalid_argument);
}

}  // namespace
}  // namespace structgp
