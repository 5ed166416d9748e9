// Replay (online/replay.h): a log streamed through the online learner, predict then learn.
// On a stationary log the one-step-ahead error falls as the model learns (weight space, pol on
// the KDL-simulated two-link arm); after a 2 kg payload appears mid-log, rbd with forgetting
// brings the error back to the noise while rbd without forgetting stays biased; the learned
// model returned equals the learner's last state; bad input is refused by name; the replay's
// report plots each joint's one-step-ahead error over time, sample for sample.

#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <memory>
#include <random>
#include <stdexcept>
#include <string>

#include "structgp/model/robot_model.h"
#include "structgp/online/replay.h"
#include "structgp/report/report.h"
#include "structgp/report/report_data.h"
#include "structgp/rigid_body/rigid_body_chain.h"
#include "structgp/sim/dataset.h"
#include "structgp/sim/robot.h"
#include "structgp/sim/trajectory.h"
#include "structgp/sim/urdf.h"
#include "urdf_test_util.h"

namespace structgp {
namespace {

TEST(Replay, OneStepErrorsFallOnAStationaryLog) {
  const sim::Robot robot = sim::TwoLinkArm();
  sim::SimulationOptions so;
  so.noise_std = 0.01;
  so.seed = 4;
  const sim::Dataset data = sim::Simulate(robot, sim::UniformBox(2, 3000, M_PI, 2.0, 5.0, 5), so);
  const RobotModel model(ParseModelSpec("pol"), 2);
  const ReplaySummary s = Replay(model, data.X, data.Y, data.t, ReplayOptions());
  std::cout << s.Report();
  EXPECT_EQ(s.steps, 3000);
  EXPECT_EQ(s.bad_samples, 0);
  EXPECT_EQ(s.form, "weight_space");
  ASSERT_EQ(s.errors.rows(), 3000);
  for (int j = 0; j < 2; ++j) {
    EXPECT_LT(s.rms_last_fifth[j], 0.2 * s.rms_first_fifth[j]) << "joint " << j + 1;
  }
  EXPECT_GT(s.update_us_p99, 0.0);
  EXPECT_GE(s.update_us_p99, s.update_us_p50);
  // The learned model predicts the next samples as well as the end of the replay did.
  ASSERT_NE(s.model, nullptr);
  ASSERT_TRUE(s.model->fitted());
  const sim::Dataset next =
      sim::Simulate(robot, sim::UniformBox(2, 300, M_PI, 2.0, 5.0, 6), so);
  Matrix mean;
  s.model->PredictRows(next.X, &mean);
  const Vector rms = ((mean - next.Y).colwise().squaredNorm() / 300.0).cwiseSqrt().transpose();
  for (int j = 0; j < 2; ++j) EXPECT_LT(rms[j], 1.5 * s.rms_last_fifth[j] + 1e-3);
}

// rbd+motor from the prior: the URDF (the simulated arm itself) is the prior mean, so the very
// first predictions are already at the noise, the learner learns only what is left (nothing),
// and the learned model, which carries the same mean, predicts new motion at the noise too.
TEST(Replay, APriorMeanIsAddedToPredictionsAndTakenFromTargets) {
  const sim::Robot robot = sim::TwoLinkArm();
  RobotModelOptions ro;
  ro.rigid_body = std::make_shared<const RigidBodyChain>(sim::ToRigidBodyChain(robot));
  sim::SimulationOptions so;
  so.noise_std = 0.01;
  so.seed = 4;
  const sim::Dataset data = sim::Simulate(robot, sim::UniformBox(2, 500, M_PI, 2.0, 5.0, 5), so);
  const RobotModel model(ParseModelSpec("rbd+motor"), 2, ro);
  const ReplaySummary s = Replay(model, data.X, data.Y, data.t, ReplayOptions());
  EXPECT_EQ(s.bad_samples, 0);
  for (int j = 0; j < 2; ++j) {
    EXPECT_LT(s.rms_first_fifth[j], 1.5 * so.noise_std) << "joint " << j + 1;
    EXPECT_LT(s.rms_last_fifth[j], 1.5 * so.noise_std) << "joint " << j + 1;
  }
  ASSERT_NE(s.model, nullptr);
  const sim::Dataset next = sim::Simulate(robot, sim::UniformBox(2, 200, M_PI, 2.0, 5.0, 6), so);
  Matrix mean;
  s.model->PredictRows(next.X, &mean);
  EXPECT_LT(std::sqrt((mean - next.Y).squaredNorm() / mean.size()), 1.5 * so.noise_std);
  // Without the mean the same replay starts far from the torques.
  const ReplaySummary plain = Replay(RobotModel(ParseModelSpec("motor"), 2), data.X, data.Y,
                                     data.t, ReplayOptions());
  EXPECT_GT(plain.rms_first_fifth[0], 10 * so.noise_std);
}

// A 3-joint random URDF chain; the log picks up 2 kg on the last link half way through.
struct PayloadLog {
  std::shared_ptr<const RigidBodyChain> nominal, loaded;
  Matrix X, Y;
  Vector t;
};

PayloadLog MakePayloadLog(int m, double noise) {
  testing::RandomUrdfOptions u;
  u.num_joints = 3;
  u.seed = 5;
  PayloadLog log;
  log.nominal = std::make_shared<const RigidBodyChain>(
      RigidBodyChain::FromUrdfString(testing::RandomUrdf(u)));
  Vector pi = log.nominal->parameters();
  pi[10 * 2] += 2.0;  // mass of link 3 (a point mass at its origin)
  log.loaded = std::make_shared<const RigidBodyChain>(log.nominal->WithParameters(pi));
  const RigidBodyChain& loaded = *log.loaded;
  const sim::Trajectory tr = sim::UniformBox(3, m, M_PI, 2.0, 5.0, 7, 0.001);
  std::mt19937_64 rng(8);
  std::normal_distribution<double> normal(0.0, noise);
  log.X.resize(m, 9);
  log.X << tr.q, tr.qd, tr.qdd;
  log.Y.resize(m, 3);
  log.t = tr.t;
  for (int i = 0; i < m; ++i) {
    const RigidBodyChain& chain = i < m / 2 ? *log.nominal : loaded;
    const Vector tau = chain.InverseDynamics(tr.q.row(i).transpose(), tr.qd.row(i).transpose(),
                                             tr.qdd.row(i).transpose());
    for (int j = 0; j < 3; ++j) log.Y(i, j) = tau[j] + normal(rng);
  }
  return log;
}

TEST(Replay, PayloadChangeIsRecoveredWithForgetting) {
  const double noise = 0.05;
  const PayloadLog log = MakePayloadLog(4000, noise);
  RobotModelOptions ro;
  ro.rigid_body = log.nominal;
  const RobotModel model(ParseModelSpec("rbd"), 3, ro);
  ReplayOptions o;
  o.hyperparameters = model.DefaultHyperparameters(log.Y);
  o.hyperparameters.log_noise_std = std::log(noise);
  o.hyperparameters.log_output_scale.setZero();
  ReplaySummary keep = Replay(model, log.X, log.Y, log.t, o);
  o.forgetting = 0.99;
  ReplaySummary forget = Replay(model, log.X, log.Y, log.t, o);
  std::cout << "without forgetting:\n" << keep.Report() << "with forgetting 0.99:\n"
            << forget.Report();
  EXPECT_EQ(forget.form, "regressor");
  EXPECT_EQ(forget.num_features, 33);
  for (int j = 0; j < 3; ++j) {
    // The URDF model is right in the first half: errors at the noise from the start.
    EXPECT_LT(forget.rms_first_fifth[j], 1.3 * noise) << "joint " << j + 1;
    // After the payload: back to the noise with forgetting; without, the old samples hold
    // the estimate back.
    EXPECT_LT(forget.rms_last_fifth[j], 1.3 * noise) << "joint " << j + 1;
  }
  EXPECT_GT(keep.rms_last_fifth.maxCoeff(), 1.5 * forget.rms_last_fifth.maxCoeff());
  // The learned model (the regressor posterior) predicts the loaded arm's torques on new
  // states within the noise (the payload's mass alone is not identifiable apart from
  // the other links' parameters, its torques are).
  ASSERT_NE(forget.model, nullptr);
  ASSERT_NE(forget.model->gp().regressor(), nullptr);
  const sim::Trajectory tr = sim::UniformBox(3, 200, M_PI, 2.0, 5.0, 9, 0.001);
  Matrix X(200, 9), truth(200, 3), mean;
  X << tr.q, tr.qd, tr.qdd;
  for (int i = 0; i < 200; ++i) {
    truth.row(i) = log.loaded
                       ->InverseDynamics(tr.q.row(i).transpose(), tr.qd.row(i).transpose(),
                                         tr.qdd.row(i).transpose())
                       .transpose();
  }
  forget.model->PredictRows(X, &mean);
  // A memory of ~100 samples (forgetting 0.99) for 33 parameters: RMS well below the noise.
  const double rms = std::sqrt((mean - truth).squaredNorm() / 600.0);
  std::cout << "RMS against the loaded arm's torques: " << rms << " N m\n";
  EXPECT_LT(rms, 0.6 * noise);
}

TEST(Replay, TrajectoryRestartsAreSegments) {
  const PayloadLog log = MakePayloadLog(600, 0.05);
  Vector t = log.t;
  t.segment(200, 200) = log.t.head(200);  // the time starts again at rows 200 and 400
  t.segment(400, 200) = log.t.head(200);
  RobotModelOptions ro;
  ro.rigid_body = log.nominal;
  const RobotModel model(ParseModelSpec("rbd"), 3, ro);
  const ReplaySummary s = Replay(model, log.X, log.Y, t, ReplayOptions());
  ASSERT_EQ(s.segment_starts.size(), 3u);
  EXPECT_EQ(s.segment_starts[1], 200);
  EXPECT_EQ(s.segment_starts[2], 400);
  EXPECT_EQ(s.steps, 600);
}

// The report of a replay: per joint a plot "one-step-ahead error over time" whose values are
// the replay's errors (the data are under the thinning limit, so every sample is drawn), the
// prediction series = measured - error, the first/last fifth errors; a summary that does not
// belong to the data is refused.
TEST(Replay, ReportPlotsTheOneStepErrorOverTime) {
  const PayloadLog log = MakePayloadLog(600, 0.05);
  RobotModelOptions ro;
  ro.rigid_body = log.nominal;
  const RobotModel model(ParseModelSpec("rbd"), 3, ro);
  ReplayOptions o;
  o.forgetting = 0.99;
  const ReplaySummary s = Replay(model, log.X, log.Y, log.t, o);
  RobotData data;
  data.num_joints = 3;
  data.X = log.X;
  data.Y = log.Y;
  data.t = log.t;
  data.source = "payload.csv";
  const report::ReportData r = report::ReplayReportData(s, data, "rbd from zero");
  ASSERT_EQ(r.joints.size(), 3u);
  ASSERT_EQ(r.errors.size(), 2u);
  for (int j = 0; j < 3; ++j) {
    const report::JointData& jd = r.joints[static_cast<size_t>(j)];
    ASSERT_EQ(jd.signal_plots.size(), 1u);
    ASSERT_EQ(jd.signal_plots[0].series.size(), 1u);
    const std::vector<double>& e = jd.signal_plots[0].series[0].values;
    ASSERT_EQ(e.size(), 600u);
    ASSERT_EQ(jd.predictions.size(), 1u);
    for (int i = 0; i < 600; ++i) {
      ASSERT_EQ(e[static_cast<size_t>(i)], s.errors(i, j)) << "joint " << j + 1 << " row " << i;
      // The plotted prediction is the measured torque less the replay's error (exactly; adding
      // the error back is not exact where the torque is small next to the prediction).
      EXPECT_EQ(jd.predictions[0].mean[static_cast<size_t>(i)],
                log.Y(i, j) - e[static_cast<size_t>(i)]);
    }
    // The report's last-fifth RMS is the replay's.
    EXPECT_NEAR(r.errors[1].rms[static_cast<size_t>(j)], s.rms_last_fifth[j],
                1e-12 * s.rms_last_fifth[j]);
  }
  const std::string html = report::RenderHtml(r);
  for (int j = 1; j <= 3; ++j) {
    const std::string title =
        "\"title\":\"Joint " + std::to_string(j) + ": one-step-ahead error over time\"";
    EXPECT_NE(html.find(title), std::string::npos) << title;
  }
  EXPECT_NE(html.find("last fifth of the steps"), std::string::npos);
  EXPECT_EQ(html.find("http://"), std::string::npos);
  EXPECT_EQ(html.find("https://"), std::string::npos);
  // A summary of another log is refused.
  RobotData shorter = data.Rows(0, 500);
  try {
    report::ReplayReportData(s, shorter, "rbd");
    ADD_FAILURE() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("expected 500 x 3"), std::string::npos) << e.what();
  }
}

TEST(Replay, BadInputIsRefusedByName) {
  const RobotModel model(ParseModelSpec("pol"), 2);
  const Matrix X = Matrix::Zero(10, 6), Y = Matrix::Zero(10, 2);
  const auto message = [&](const Matrix& x, const Matrix& y, const ReplayOptions& o,
                           const RobotModel& m) {
    try {
      Replay(m, x, y, Vector(), o);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no exception");
  };
  EXPECT_NE(message(Matrix::Zero(10, 5), Y, ReplayOptions(), model).find("columns"),
            std::string::npos);
  EXPECT_NE(message(X, Matrix::Zero(10, 3), ReplayOptions(), model).find("joints"),
            std::string::npos);
  ReplayOptions bad;
  bad.forgetting = 1.5;
  EXPECT_NE(message(X, Y, bad, model).find("forgetting"), std::string::npos);
  bad = ReplayOptions();
  bad.window_length = -1;
  EXPECT_NE(message(X, Y, bad, model).find("window_length"), std::string::npos);
  const RobotModel rbf(ParseModelSpec("rbf"), 2);
  EXPECT_NE(message(X, Y, ReplayOptions(), rbf).find("function space"), std::string::npos);
}

}  // namespace
}  // namespace structgp
