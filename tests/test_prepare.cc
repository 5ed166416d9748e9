// Raw-log preparation: the Butterworth design against its closed-form magnitude response,
// zero phase and unit DC gain of the forward-backward filter, exact three-point differences,
// and derived qd, qdd on noisy KDL-simulated trajectories at 1 kHz against the analytic ones
// (and the torques KDL computes from them); errors for bad time columns and bad files.

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>

#include "structgp/io/data_error.h"
#include "structgp/prepare/butterworth.h"
#include "structgp/prepare/prepare.h"
#include "structgp/prepare/raw_log.h"
#include "structgp/sim/robot.h"
#include "structgp/sim/trajectory.h"

namespace structgp {
namespace {

constexpr double kPi = 3.14159265358979323846;

// The closed form of the design (bilinear transform with pre-warping):
// |H|^2 = 1 / (1 + (tan(w/2) / tan(wc/2))^(2n)).
double AnalyticMagnitude(int order, double f, double fc, double fs) {
  const double ratio = std::tan(kPi * f / fs) / std::tan(kPi * fc / fs);
  return 1.0 / std::sqrt(1.0 + std::pow(ratio, 2.0 * order));
}

TEST(Butterworth, MagnitudeMatchesTheClosedForm) {
  for (int order = 1; order <= kMaxButterworthOrder; ++order) {
    for (const double fc : {1.0, 10.0, 50.0, 400.0}) {
      const double fs = 1000.0;
      const ButterworthLowPass filter(order, fc, fs);
      EXPECT_EQ(static_cast<int>(filter.sections().size()), (order + 1) / 2);
      for (const double f : {0.0, 0.1 * fc, 0.5 * fc, fc, 1.5 * fc, 3.0 * fc, 0.49 * fs}) {
        if (f > 0.5 * fs) continue;
        EXPECT_NEAR(filter.Magnitude(f), AnalyticMagnitude(order, f, fc, fs), 1e-10)
            << "order " << order << ", fc " << fc << ", f " << f;
      }
      // -3 dB exactly at the cut-off.
      EXPECT_NEAR(filter.Magnitude(fc), std::sqrt(0.5), 1e-10);
    }
  }
}

TEST(Butterworth, DcGainIsOne) {
  const ButterworthLowPass filter(3, 5.0, 1000.0);
  EXPECT_NEAR(filter.Magnitude(0.0), 1.0, 1e-14);
  const Vector x = Vector::Constant(3000, 1.234);
  Vector y;
  filter.FiltFilt(x, &y);
  EXPECT_LT((y - x).cwiseAbs().maxCoeff(), 1e-12);
  filter.Filter(x, &y);
  EXPECT_LT((y - x).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(Butterworth, ForwardBackwardHasZeroPhaseAndSquaredMagnitude) {
  const double fs = 1000.0, fc = 10.0;
  const ButterworthLowPass filter(3, fc, fs);
  const Eigen::Index m = 5000;
  const Eigen::Index edge = 500;  // Compare away from the ends (5 cut-off periods).
  for (const double f : {2.0, 5.0, 10.0, 15.0}) {
    Vector x(m), expected(m);
    const double gain = std::pow(AnalyticMagnitude(3, f, fc, fs), 2.0);
    for (Eigen::Index i = 0; i < m; ++i) {
      const double phase = 2.0 * kPi * f * static_cast<double>(i) / fs + 0.3;
      x[i] = std::sin(phase);
      expected[i] = gain * std::sin(phase);
    }
    Vector y;
    filter.FiltFilt(x, &y);
    const double error = (y - expected).segment(edge, m - 2 * edge).cwiseAbs().maxCoeff();
    EXPECT_LT(error, 1e-6) << "f = " << f << " Hz";
    // A causal pass lags: its output is far from the zero-phase expectation.
    Vector causal;
    filter.Filter(x, &causal);
    const double lag_error = (causal - expected).segment(edge, m - 2 * edge).cwiseAbs().maxCoeff();
    EXPECT_GT(lag_error, 0.1) << "f = " << f << " Hz";
    EXPECT_GT(std::abs(filter.Phase(f)), 0.1);
  }
}

TEST(Butterworth, RejectsBadDesigns) {
  EXPECT_THROW(ButterworthLowPass(0, 10.0, 1000.0), std::invalid_argument);
  EXPECT_THROW(ButterworthLowPass(kMaxButterworthOrder + 1, 10.0, 1000.0), std::invalid_argument);
  EXPECT_THROW(ButterworthLowPass(3, 500.0, 1000.0), std::invalid_argument);
  EXPECT_THROW(ButterworthLowPass(3, 0.0, 1000.0), std::invalid_argument);
  EXPECT_THROW(ButterworthLowPass(3, 10.0, -1.0), std::invalid_argument);
}

TEST(Differences, ExactForQuadraticsOnUnevenTimes) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> step(0.8e-3, 1.2e-3);
  const Eigen::Index m = 50;
  Eigen::VectorXd t(m);
  t[0] = 0.3;
  for (Eigen::Index i = 1; i < m; ++i) t[i] = t[i - 1] + step(rng);
  Eigen::MatrixXd x(m, 2), dx_true(m, 2);
  for (Eigen::Index i = 0; i < m; ++i) {
    x(i, 0) = 2.0 - 3.0 * t[i] + 4.0 * t[i] * t[i];
    dx_true(i, 0) = -3.0 + 8.0 * t[i];
    x(i, 1) = -1.5 * t[i] * t[i];
    dx_true(i, 1) = -3.0 * t[i];
  }
  Eigen::MatrixXd dx, ddx;
  Differentiate(t, x, &dx);
  SecondDifference(t, x, &ddx);
  EXPECT_LT((dx - dx_true).cwiseAbs().maxCoeff(), 1e-8);
  EXPECT_LT((ddx.col(0).array() - 8.0).abs().maxCoeff(), 1e-5);
  EXPECT_LT((ddx.col(1).array() + 3.0).abs().maxCoeff(), 1e-5);
}

// A 1 kHz log of the two-link arm on a sum-of-sines trajectory (harmonics up to 1.5 Hz),
// positions with Gaussian noise of noise_std rad (about a 16-bit encoder), exact torques.
struct SimulatedLog {
  sim::Trajectory truth;
  Eigen::MatrixXd tau;
  RawLog log;
};

SimulatedLog MakeLog(double noise_std, std::uint64_t seed) {
  SimulatedLog s;
  s.truth = sim::SumOfSines(2, 12.0, 1e-3, 6, 0.25, 1.2, seed);
  const sim::Robot robot = sim::TwoLinkArm();
  const Eigen::Index m = s.truth.num_samples();
  s.tau.resize(m, 2);
  for (Eigen::Index i = 0; i < m; ++i) {
    s.tau.row(i) = robot
                       .InverseDynamics(s.truth.q.row(i).transpose(), s.truth.qd.row(i).transpose(),
                                        s.truth.qdd.row(i).transpose())
                       .transpose();
  }
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, noise_std);
  s.log.num_joints = 2;
  s.log.t = s.truth.t;
  s.log.q = s.truth.q;
  for (Eigen::Index i = 0; i < s.log.q.size(); ++i) s.log.q.data()[i] += noise(rng);
  s.log.tau = s.tau;
  s.log.current.resize(m, 0);
  return s;
}

double Rms(const Eigen::MatrixXd& a) { return std::sqrt(a.squaredNorm() / a.size()); }

// Expected errors (interior, noise sigma = 1e-4 rad, f_c = 10 Hz, f_s = 1 kHz): the filtered
// noise differentiated has an RMS of about sigma 2 pi sqrt(2 f_c^3 / (3 f_s)) = 5e-4 rad/s in
// qd and sigma (2 pi)^2 sqrt(2 f_c^5 / (5 f_s)) = 0.025 rad/s^2 in qdd; the signal itself
// (below 1.5 Hz) passes with |H|^2 > 1 - 1e-5. Tolerances are 3x those figures.
TEST(Prepare, DerivativesOfANoisySimulatedLogMatchTheTruth) {
  const sim::Robot robot = sim::TwoLinkArm();
  for (const std::uint64_t seed : {11u, 12u, 13u}) {
    std::printf("[ seed     ] %llu\n", static_cast<unsigned long long>(seed));
    const SimulatedLog s = MakeLog(1e-4, seed);
    PrepareOptions options;
    options.cutoff_hz = 10.0;
    PrepareSummary summary;
    const RobotData data = PrepareRawLog(s.log, options, &summary);
    ASSERT_EQ(data.size(), s.log.size());
    EXPECT_NEAR(summary.sample_rate_hz, 1000.0, 1e-6);
    EXPECT_EQ(summary.edge_samples, 100);
    const Eigen::Index m = data.size();
    const Eigen::Index e = summary.edge_samples;
    const Eigen::Index k = m - 2 * e;
    const double qd_rms =
        Rms(data.X.middleCols(2, 2).middleRows(e, k) - s.truth.qd.middleRows(e, k));
    const double qdd_rms =
        Rms(data.X.middleCols(4, 2).middleRows(e, k) - s.truth.qdd.middleRows(e, k));
    const double q_rms = Rms(data.X.leftCols(2).middleRows(e, k) - s.truth.q.middleRows(e, k));
    std::printf(
        "  interior RMS error: q %.2e rad, qd %.2e rad/s, qdd %.2e rad/s^2 "
        "(qdd RMS %.1f rad/s^2)\n",
        q_rms, qd_rms, qdd_rms, Rms(s.truth.qdd));
    EXPECT_LT(q_rms, 1e-4);
    EXPECT_LT(qd_rms, 1.5e-3);
    EXPECT_LT(qdd_rms, 0.075);
    // Torques from KDL at the derived states against the true torques.
    Eigen::MatrixXd tau(k, 2);
    for (Eigen::Index i = 0; i < k; ++i) {
      const auto row = data.X.row(e + i);
      tau.row(i) =
          robot
              .InverseDynamics(row.segment(0, 2).transpose(), row.segment(2, 2).transpose(),
                               row.segment(4, 2).transpose())
              .transpose();
    }
    const double tau_rms = Rms(tau - s.tau.middleRows(e, k));
    std::printf("  torque RMS error from derived states: %.2e N m (torque RMS %.2f)\n", tau_rms,
                Rms(s.tau));
    // qdd error 0.025 rad/s^2 times inertias of ~0.1-0.3 kg m^2: a few 1e-3 N m.
    EXPECT_LT(tau_rms, 3e-3 * Rms(s.tau));
    // The torque column passes through unchanged; t is the log's.
    EXPECT_EQ(data.Y, s.tau);
    EXPECT_EQ(data.t, s.log.t);
    // At the edges the error is larger but bounded: the odd reflection keeps value and slope
    // but flips the curvature, so qd is off by up to about |qdd| / (2 pi f_c) there
    // (|qdd| <= 25 rad/s^2 here: 0.4 rad/s).
    const double edge_qd = (data.X.middleCols(2, 2) - s.truth.qd).cwiseAbs().maxCoeff();
    std::printf("  max |qd error| including the edges: %.2e rad/s (max |qd| %.2f rad/s)\n", edge_qd,
                s.truth.qd.cwiseAbs().maxCoeff());
    EXPECT_LT(edge_qd, 0.4);
  }
}

TEST(Prepare, TrimsEdgesAndConvertsCurrents) {
  SimulatedLog s = MakeLog(1e-4, 21);
  s.log.current = s.tau.array().rowwise() / Eigen::Array2d(0.5, 2.0).transpose();
  s.log.tau.resize(s.log.size(), 0);
  PrepareOptions options;
  options.current_gains = {0.5, 2.0};
  options.trim_edges = true;
  PrepareSummary summary;
  const RobotData data = PrepareRawLog(s.log, options, &summary);
  EXPECT_TRUE(summary.torque_from_current);
  EXPECT_EQ(summary.cutoff_hz, kDefaultCutoffHz);
  ASSERT_EQ(data.size(), s.log.size() - 2 * summary.edge_samples);
  EXPECT_LT((data.Y - s.tau.middleRows(summary.edge_samples, data.size())).cwiseAbs().maxCoeff(),
            1e-12);
  EXPECT_EQ(data.t[0], s.log.t[summary.edge_samples]);
  // Gains of the wrong count name the option.
  options.current_gains = {1.0};
  try {
    PrepareRawLog(s.log, options);
    FAIL() << "expected an error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("current_gains: expected 2 gains"), std::string::npos)
        << e.what();
  }
  // No tau and no gains.
  options.current_gains.clear();
  EXPECT_THROW(PrepareRawLog(s.log, options), std::invalid_argument);
}

TEST(Prepare, SamplingRateFromOptionsWhenThereIsNoTime) {
  SimulatedLog s = MakeLog(0.0, 5);
  RawLog log = s.log;
  log.t.resize(0);
  PrepareOptions options;
  EXPECT_THROW(PrepareRawLog(log, options), std::invalid_argument);  // no rate
  options.sample_rate_hz = 1000.0;
  const RobotData data = PrepareRawLog(log, options);
  EXPECT_NEAR(data.t[10], 0.01, 1e-15);
  const RobotData with_time = PrepareRawLog(s.log, options);
  EXPECT_LT((data.X - with_time.X).cwiseAbs().maxCoeff(), 1e-6);
  // A rate that disagrees with t is refused.
  options.sample_rate_hz = 500.0;
  EXPECT_THROW(PrepareRawLog(s.log, options), std::invalid_argument);
  // A cut-off at or above half the rate too.
  options.sample_rate_hz = 0.0;
  options.cutoff_hz = 600.0;
  EXPECT_THROW(PrepareRawLog(s.log, options), std::invalid_argument);
}

RawLog SmallLog(const std::vector<double>& t) {
  RawLog log;
  log.num_joints = 1;
  const Eigen::Index m = static_cast<Eigen::Index>(t.size());
  log.t = Eigen::Map<const Eigen::VectorXd>(t.data(), m);
  log.q = Eigen::MatrixXd::Zero(m, 1);
  log.tau = Eigen::MatrixXd::Zero(m, 1);
  log.source = "log.csv";
  log.line = Eigen::VectorXi::LinSpaced(m, 2, static_cast<int>(m) + 1);
  log.time_column = Eigen::VectorXi::Constant(m, 1);
  return log;
}

TEST(Prepare, TimeErrorsNameLineAndColumn) {
  try {
    MeasureSampling(SmallLog({0.0, 0.01, 0.02, 0.015, 0.04}));
    FAIL();
  } catch (const DataError& e) {
    EXPECT_EQ(e.line(), 5);
    EXPECT_EQ(e.column(), 1);
    EXPECT_NE(e.message().find("time goes backwards"), std::string::npos) << e.what();
  }
  try {
    MeasureSampling(SmallLog({0.0, 0.01, 0.02, 0.02, 0.04}));
    FAIL();
  } catch (const DataError& e) {
    EXPECT_EQ(e.line(), 5);
    EXPECT_NE(e.message().find("does not advance"), std::string::npos) << e.what();
  }
  try {
    MeasureSampling(SmallLog({0.0, 0.01, 0.02, 0.03, 0.05, 0.06}));
    FAIL();
  } catch (const DataError& e) {
    EXPECT_EQ(e.line(), 6);
    EXPECT_NE(e.message().find("sampling is not uniform"), std::string::npos) << e.what();
  }
  const Sampling ok = MeasureSampling(SmallLog({0.0, 0.0101, 0.02, 0.0299, 0.04}));
  EXPECT_NEAR(ok.rate_hz, 100.0, 1.1);
  EXPECT_NEAR(ok.max_jitter, 0.0002 / 0.0101, 1e-9);  // median step 0.0101 s
}

class RawFile : public ::testing::Test {
 protected:
  void SetUp() override {
    path_ = (std::filesystem::temp_directory_path() /
             ("structgp_test_prepare_" + std::to_string(::getpid()) + ".csv"))
                .string();
  }
  void TearDown() override { std::filesystem::remove(path_); }
  void Write(const std::string& text) { std::ofstream(path_) << text; }
  // Reads the file and returns "line:column: message" of the error, or "" when it reads.
  std::string Error() {
    try {
      ReadRawLogCsv(path_);
    } catch (const DataError& e) {
      return std::to_string(e.line()) + ":" + std::to_string(e.column()) + ": " + e.message();
    }
    return "";
  }
  std::string path_;
};

TEST_F(RawFile, ReadsColumnsInAnyOrderAndIgnoresOthers) {
  Write("note,tau2,t,q2,q1,tau1,qd1,i1,i2\nx,4,0.5,2,1,3,9,5,6\ny,8,0.6,6,5,7,9,1,2\n");
  const RawLog log = ReadRawLogCsv(path_);
  EXPECT_EQ(log.num_joints, 2);
  EXPECT_EQ(log.q(0, 0), 1.0);
  EXPECT_EQ(log.q(1, 1), 6.0);
  EXPECT_EQ(log.tau(0, 1), 4.0);
  EXPECT_EQ(log.current(1, 0), 1.0);
  EXPECT_EQ(log.t[1], 0.6);
  EXPECT_EQ(log.line[1], 3);
  EXPECT_EQ(log.time_column[0], 5);
}

TEST_F(RawFile, ErrorsNameLineAndColumn) {
  Write("t,q1,q2,tau1\n0,1,2,3\n");
  EXPECT_EQ(Error().substr(0, 25), "1:0: missing column tau2 ");
  Write("t,q1,tau1\n");
  EXPECT_EQ(Error(), "1:0: no data rows: the header is not followed by any data");
  Write("t,q1\n0,1\n");
  EXPECT_EQ(Error(), "1:0: no torque or current columns: expected tau1..tau1 or i1..i1");
  Write("t,q1,tau1\n0,1,2\n0.1, abc,2\n");
  EXPECT_EQ(Error(), "3:6: CSV column 2 (q1): expected a number, got 'abc'");
  Write("t,q1,tau1\n0,1,2\n0.1,1\n");
  EXPECT_EQ(Error(), "3:6: expected 3 cells (as in the header), got 2");
  Write("t,q1,tau1\n0,1,nan\n");
  EXPECT_EQ(Error(), "2:5: CSV column 3 (tau1): expected a finite number, got 'nan'");
  Write("t,q1,tau1,q1\n0,1,2,3\n");
  EXPECT_EQ(Error(), "1:11: duplicated column 'q1': CSV columns 2 and 4");
  Write("t,qd1,tau1\n0,1,2\n");
  EXPECT_EQ(Error().substr(0, 32), "1:0: no joint position columns: ");
}

}  // namespace
}  // namespace structgp
