// Model apart from workspace: one const model (WeightSpaceGP, KernelGP, RobotModel in weight
// and function space) serves several threads at once, each with its own workspace, and every
// thread gets bit for bit the predictions of a single-threaded pass; RobotModel::PredictRows
// shares a log's rows among threads with the same result. Run under ThreadSanitizer
// by scripts/run-tests.sh: a data race in a const path fails there even when the numbers agree.

#include <gtest/gtest.h>

#include <cstring>
#include <functional>
#include <memory>
#include <random>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "structgp/kernel/rbf_kernel.h"
#include "structgp/model/kernel_gp.h"
#include "structgp/model/robot_model.h"
#include "structgp/model/weight_space_gp.h"

namespace structgp {
namespace {

constexpr int kThreads = 4;
constexpr unsigned kSeed = 909;

bool BitEqual(const Matrix& a, const Matrix& b) {
  return a.rows() == b.rows() && a.cols() == b.cols() &&
         (a.size() == 0 ||
          std::memcmp(a.data(), b.data(), sizeof(double) * static_cast<size_t>(a.size())) == 0);
}

Matrix Random(Eigen::Index rows, Eigen::Index cols, std::mt19937_64* rng, double scale = 1.0) {
  std::normal_distribution<double> normal(0.0, scale);
  return Matrix::NullaryExpr(rows, cols, [&]() { return normal(*rng); });
}

// predict(thread, out) writes one result matrix; every thread runs it at the same time, after
// a single-threaded reference run, and must reproduce the reference exactly.
void ExpectConcurrentEqualsSerial(const std::function<void(Matrix*)>& predict) {
  Matrix reference;
  predict(&reference);
  std::vector<Matrix> results(kThreads);
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t) threads.emplace_back([&, t] { predict(&results[t]); });
  for (std::thread& thread : threads) thread.join();
  for (int t = 0; t < kThreads; ++t) {
    EXPECT_TRUE(BitEqual(results[t], reference)) << "thread " << t << " (seed " << kSeed << ")";
  }
}

TEST(ConcurrentPredict, WeightSpaceGPWithAStagedUpdate) {
  std::mt19937_64 rng(kSeed);
  const int D = 40, P = 3, m = 120;
  const Matrix Phi = Random(m, D, &rng);
  const Matrix Y = Random(m, P, &rng);
  WeightSpaceGP model(Vector::Constant(D, 0.5), 0.04, P);
  ASSERT_EQ(model.Fit(Phi.topRows(100), Y.topRows(100)), Status::kOk);
  Vector mean(P), latent(P), noisy(P);
  // Leave an update staged: the const readers must read through it without applying it.
  ASSERT_EQ(model.UpdateAndPredict(Phi.row(100).transpose(), Y.row(100).transpose(),
                                   Phi.row(101).transpose(), mean, latent, noisy, 0.99),
            Status::kOk);
  ASSERT_TRUE(model.has_staged_update());
  const WeightSpaceGP& shared = model;
  const Matrix queries = Random(50, D, &rng);
  ExpectConcurrentEqualsSerial([&](Matrix* out) {
    WeightSpaceGP::Workspace workspace = shared.MakeWorkspace();
    out->resize(queries.rows(), 3 * P);
    Vector mu(P), l(P), n(P), mean_only(P);
    for (Eigen::Index i = 0; i < queries.rows(); ++i) {
      ASSERT_EQ(shared.PredictWithVariance(queries.row(i).transpose(), mu, l, n, workspace),
                Status::kOk);
      ASSERT_EQ(shared.Predict(queries.row(i).transpose(), mean_only, workspace), Status::kOk);
      out->row(i) << mu.transpose(), l.transpose(), n.transpose();
    }
  });
  EXPECT_TRUE(model.has_staged_update());  // no const call applied it
  // The staged reads are the posterior after the update (Sherman-Morrison against applying
  // it: equal to rounding).
  WeightSpaceGP::Workspace workspace = shared.MakeWorkspace();
  WeightSpaceGP applied = model;
  applied.ApplyStagedUpdate();
  for (Eigen::Index i = 0; i < queries.rows(); ++i) {
    Vector m1(P), l1(P), n1(P), m2(P), l2(P), n2(P);
    ASSERT_EQ(shared.PredictWithVariance(queries.row(i).transpose(), m1, l1, n1, workspace),
              Status::kOk);
    ASSERT_EQ(applied.PredictWithVariance(queries.row(i).transpose(), m2, l2, n2), Status::kOk);
    EXPECT_LT((m1 - m2).cwiseAbs().maxCoeff(), 1e-10 * (1.0 + m2.cwiseAbs().maxCoeff()));
    EXPECT_LT((l1 - l2).cwiseAbs().maxCoeff(), 1e-9 * (1.0 + l2.cwiseAbs().maxCoeff()));
  }
  EXPECT_THROW(shared.weights(), std::logic_error);
}

TEST(ConcurrentPredict, KernelGP) {
  std::mt19937_64 rng(kSeed + 1);
  const int d = 5, P = 2, m = 150;
  const Matrix X = Random(m, d, &rng);
  const Matrix Y = Random(m, P, &rng);
  KernelGP fitted(RbfKernel(d, /*ard=*/true, 1.3, 0.9), 0.05, P);
  ASSERT_EQ(fitted.Fit(X, Y), Status::kOk);
  const KernelGP& shared = fitted;
  const Matrix queries = Random(40, d, &rng);
  ExpectConcurrentEqualsSerial([&](Matrix* out) {
    KernelGP::Workspace workspace = shared.MakeWorkspace();
    out->resize(queries.rows(), 3 * P);
    Vector mean(P), latent(P), noisy(P);
    for (Eigen::Index i = 0; i < queries.rows(); ++i) {
      ASSERT_EQ(shared.PredictWithVariance(queries.row(i).transpose(), mean, latent, noisy,
                                           workspace),
                Status::kOk);
      out->row(i) << mean.transpose(), latent.transpose(), noisy.transpose();
    }
  });
}

// A two-joint model of the spec fitted on m random states and torques (null, with a failure
// recorded, when the fit fails), and `queries` random states to predict at.
struct RandomFit {
  std::unique_ptr<RobotModel> model;
  Matrix queries;
};
RandomFit FitOnRandomData(const std::string& spec_text, Form form, int m, int queries,
                          unsigned seed) {
  const int N = 2;
  std::mt19937_64 rng(seed);
  RobotModelOptions options;
  options.form = form;
  auto model = std::make_unique<RobotModel>(ParseModelSpec(spec_text), N, options);
  const Matrix X = Random(m, 3 * N, &rng);
  const Matrix Y = Random(m, N, &rng, 2.0);
  const Status status = model->Fit(X, Y);
  EXPECT_EQ(status, Status::kOk);
  if (status != Status::kOk) model.reset();
  return {std::move(model), Random(queries, 3 * N, &rng)};
}

void ExpectRobotModelConcurrent(const std::string& spec_text, Form form) {
  SCOPED_TRACE(spec_text);
  const int N = 2;
  const RandomFit fit = FitOnRandomData(spec_text, form, 300, 40, kSeed + 2);
  ASSERT_TRUE(fit.model);
  const RobotModel& shared = *fit.model;
  const Matrix& queries = fit.queries;
  ExpectConcurrentEqualsSerial([&](Matrix* out) {
    RobotModel::Workspace workspace = shared.MakeWorkspace();
    out->resize(queries.rows(), 2 * N);
    Vector mean(N), latent(N), noisy(N);
    for (Eigen::Index i = 0; i < queries.rows(); ++i) {
      ASSERT_EQ(shared.PredictWithVariance(queries.row(i).transpose(), mean, latent, noisy,
                                           workspace),
                Status::kOk);
      out->row(i) << mean.transpose(), latent.transpose();
    }
  });
}

TEST(ConcurrentPredict, RobotModelInWeightSpace) {
  ExpectRobotModelConcurrent("pol", Form::kWeightSpace);
}

TEST(ConcurrentPredict, RobotModelInFunctionSpace) {
  ExpectRobotModelConcurrent("rbf", Form::kAuto);
}

// Kernels holding a FeatureKernel: rbf with the friction bases (a sum), and pol in function
// space (k_pol through its explicit map).
TEST(ConcurrentPredict, RobotModelWithAFeatureKernel) {
  ExpectRobotModelConcurrent("rbf+fri", Form::kAuto);
  ExpectRobotModelConcurrent("pol", Form::kFunctionSpace);
}

// RobotModel::PredictRows on several threads (contiguous ranges of rows, a workspace each):
// bit for bit the one-thread result, with fewer rows than threads too, for a weight-space, a
// function-space and an Euler-Lagrange model.
TEST(ConcurrentPredict, PredictRowsOnThreadsEqualsOneThread) {
  for (const auto& [spec_text, form] : std::vector<std::pair<std::string, Form>>{
           {"pol", Form::kWeightSpace}, {"rbf+fri", Form::kAuto}, {"lagk+fri", Form::kAuto}}) {
    SCOPED_TRACE(spec_text);
    const RandomFit fit = FitOnRandomData(spec_text, form, 200, 41, kSeed + 3);
    ASSERT_TRUE(fit.model);
    const RobotModel& model = *fit.model;
    const Matrix& queries = fit.queries;
    Matrix mean_one, std_one;
    model.PredictRows(queries, &mean_one, &std_one);
    ASSERT_TRUE(mean_one.allFinite() && std_one.allFinite());
    for (int threads : {2, 3, kThreads}) {
      Matrix mean, std;
      model.PredictRows(queries, &mean, &std, threads);
      EXPECT_TRUE(BitEqual(mean, mean_one) && BitEqual(std, std_one)) << threads << " threads";
    }
    Matrix mean_few, mean_only;
    model.PredictRows(queries.topRows(3), &mean_few, nullptr, 8);
    EXPECT_TRUE(BitEqual(mean_few, mean_one.topRows(3)));
    EXPECT_THROW(model.PredictRows(queries, &mean_only, nullptr, 0), std::invalid_argument);
  }
}

// A row whose prediction fails (finite inputs whose features overflow) is named as on one
// thread: the first failing row of the log, not the first that a worker reached. Rows 7 and
// 30 fail, in the first range and a later one for every thread count from 2 on.
TEST(ConcurrentPredict, PredictRowsNamesTheFirstFailingRowOnAnyThreads) {
  const RandomFit fit = FitOnRandomData("pol", Form::kWeightSpace, 200, 41, kSeed + 5);
  ASSERT_TRUE(fit.model);
  Matrix queries = fit.queries;
  const int N = fit.model->num_joints();
  queries(30, N) = 1e200;  // q-dot of joint 1: the map's products of velocities overflow
  queries(7, N) = 1e200;
  for (int threads : {1, 2, 3, kThreads}) {
    SCOPED_TRACE(threads);
    Matrix mean, std;
    try {
      fit.model->PredictRows(queries, &mean, &std, threads);
      ADD_FAILURE() << "no error for rows 7 and 30";
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find("row 7:"), std::string::npos) << e.what();
    }
    queries(7, N) = 0.1;  // now row 30 is the first
    try {
      fit.model->PredictRows(queries, &mean, nullptr, threads);
      ADD_FAILURE() << "no error for row 30";
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find("row 30:"), std::string::npos) << e.what();
    }
    queries(7, N) = 1e200;
  }
}

}  // namespace
}  // namespace structgp
