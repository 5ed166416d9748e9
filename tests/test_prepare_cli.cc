// structgp prepare (and fit's options for large data), run as users run it: a raw log of a
// simulated two-link arm (t, q, motor currents) becomes a data file whose qd and qdd match the
// analytic ones and which 'fit' reads; bad input gives exit code 2, a message naming the flag or
// the file with line and column, and leaves an existing output file byte for byte as it was.

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <vector>

#include "structgp/io/csv.h"
#include "structgp/sim/robot.h"
#include "structgp/sim/trajectory.h"

#include "cli_runner.h"
#include "temp_files.h"

namespace structgp {
namespace {

namespace fs = std::filesystem;
using testing::Contains;
using testing::ReadFile;
using testing::RunCli;
using testing::WriteFile;
using Result = testing::CliResult;

struct TempDir : testing::TempDir {
  TempDir() : testing::TempDir("test_prepare_cli") {}
};

// 6 s of the two-link arm at 1 kHz; currents i = tau / gain, positions with 1e-4 rad noise.
struct Log {
  sim::Trajectory truth;
  std::string csv;
};

Log MakeLog() {
  Log log;
  log.truth = sim::SumOfSines(2, 6.0, 1e-3, 5, 0.3, 1.0, 3);
  const sim::Robot robot = sim::TwoLinkArm();
  std::mt19937_64 rng(3);
  std::normal_distribution<double> noise(0.0, 1e-4);
  const double gain[2] = {0.5, 2.0};
  log.csv = "t,q1,q2,i1,i2\n";
  char buffer[256];
  for (Eigen::Index i = 0; i < log.truth.num_samples(); ++i) {
    const Eigen::VectorXd tau =
        robot.InverseDynamics(log.truth.q.row(i).transpose(), log.truth.qd.row(i).transpose(),
                              log.truth.qdd.row(i).transpose());
    std::snprintf(buffer, sizeof(buffer), "%.17g,%.17g,%.17g,%.17g,%.17g\n", log.truth.t[i],
                  log.truth.q(i, 0) + noise(rng), log.truth.q(i, 1) + noise(rng), tau[0] / gain[0],
                  tau[1] / gain[1]);
    log.csv += buffer;
  }
  return log;
}

TEST(PrepareCli, DerivesVelocitiesAndAccelerationsThatFitReads) {
  TempDir dir;
  const Log log = MakeLog();
  WriteFile(dir.File("raw.csv"), log.csv);
  const std::string out = dir.File("data.csv");
  const Result r = RunCli(dir, {"prepare", "--in", dir.File("raw.csv"), "--out", out, "--cutoff",
                                "10", "--current-gains", "0.5,2", "--trim-edges", "--quiet"});
  std::printf("%s", r.out.c_str());
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(Contains(r.out, "100 dropped at each end")) << r.out;
  const RobotData data = ReadRobotCsv(out);
  ASSERT_EQ(data.num_joints, 2);
  ASSERT_EQ(data.size(), log.truth.num_samples() - 200);
  const Eigen::Index m = data.size();
  const double qd_rms = std::sqrt(
      (data.X.middleCols(2, 2) - log.truth.qd.middleRows(100, m)).squaredNorm() / (2.0 * m));
  const double qdd_rms = std::sqrt(
      (data.X.middleCols(4, 2) - log.truth.qdd.middleRows(100, m)).squaredNorm() / (2.0 * m));
  // The library test derives these bounds (tests/test_prepare.cc): 3x the expected noise.
  EXPECT_LT(qd_rms, 1.5e-3);
  EXPECT_LT(qdd_rms, 0.075);
  EXPECT_NEAR(data.t[0], 0.1, 1e-12);
  // The data file is what 'fit' wants.
  const Result fit = RunCli(dir, {"fit", "--data", out, "--model", "pol", "--hyper", "fixed",
                                  "--out", dir.File("model.json"), "--quiet"});
  EXPECT_EQ(fit.code, 0) << fit.err;
}

TEST(PrepareCli, BadInputNamesTheFileOrFlagAndWritesNothing) {
  TempDir dir;
  const std::string out = dir.File("data.csv");
  WriteFile(out, "previous contents\n");
  const std::string raw = dir.File("raw.csv");
  struct Case {
    std::string file;
    std::vector<std::string> extra;
    std::string message;
  };
  const std::vector<Case> cases = {
      {"t,q1,tau1\n0,0,1\n0.01,0,1\n0.02,0,1\n0.015,0,1\n",
       {},
       ":5:1: time goes backwards: t = 0.015 after t = 0.02"},
      {"t,q1,tau1\n0,0,1\n0.01,0,1\n0.02,0,1\n0.03,0,1\n0.05,0,1\n",
       {},
       ":6:1: sampling is not uniform"},
      {"t,q1,tau1\n0,0,1\n0.01,x,1\n", {}, ":3:6: CSV column 2 (q1): expected a number, got 'x'"},
      {"q1,tau1\n0,1\n0,1\n0,1\n", {}, "--rate: the log has no time column"},
      {"t,q1,tau1\n0,0,1\n0.01,0,1\n0.02,0,1\n",
       {"--rate", "1000"},
       "--rate: 1000 Hz disagrees with the time column"},
      {"t,q1,tau1\n0,0,1\n0.01,0,1\n0.02,0,1\n",
       {"--cutoff", "60"},
       "--cutoff: 60 Hz is not below half the sampling rate (50 Hz)"},
      {"t,q1,q2,i1,i2\n0,0,0,1,1\n", {"--current-gains", "1"}, "--current-gains: expected 2 gains"},
      {"t,q1,i1\n0,0,1\n0.01,0,1\n0.02,0,1\n", {}, "but no torques: give --current-gains"},
      {"t,q1,tau1\n0,0,1\n0.01,0,1\n0.02,0,1\n", {"--current-gains", "2"}, "--current-gains: '"},
  };
  for (const Case& c : cases) {
    WriteFile(raw, c.file);
    std::vector<std::string> args = {"prepare", "--in", raw, "--out", out, "--quiet"};
    args.insert(args.end(), c.extra.begin(), c.extra.end());
    const Result r = RunCli(dir, args);
    EXPECT_EQ(r.code, 2) << c.message << "\n" << r.err;
    EXPECT_TRUE(Contains(r.err, c.message)) << "expected '" << c.message << "' in:\n" << r.err;
    EXPECT_EQ(ReadFile(out), "previous contents\n") << c.message;
  }
  // Missing file, bad flag values, --help.
  EXPECT_EQ(RunCli(dir, {"prepare", "--in", dir.File("none.csv"), "--out", out}).code, 2);
  EXPECT_EQ(RunCli(dir, {"prepare", "--in", raw, "--out", out, "--order", "9"}).code, 2);
  const Result help = RunCli(dir, {"prepare", "--help"});
  EXPECT_EQ(help.code, 0);
  EXPECT_TRUE(Contains(help.out, "--current-gains")) << help.out;
  EXPECT_EQ(ReadFile(out), "previous contents\n");
}

// fit on a prepared log: a kernel model beyond --max-kernel-rows takes an evenly spaced subset
// and says so; --threads 2 gives the one-thread model (same summary).
TEST(FitCli, LargeDataOptions) {
  TempDir dir;
  const Log log = MakeLog();
  WriteFile(dir.File("raw.csv"), log.csv);
  const std::string data = dir.File("data.csv");
  ASSERT_EQ(RunCli(dir, {"prepare", "--in", dir.File("raw.csv"), "--out", data, "--current-gains",
                         "0.5,2", "-q"})
                .code,
            0);
  const Result rbf = RunCli(dir, {"fit", "--data", data, "--model", "rbf", "--hyper", "fixed",
                                  "--max-kernel-rows", "500", "--out", dir.File("rbf.json")});
  ASSERT_EQ(rbf.code, 0) << rbf.err;
  const std::string note = "the function-space form was fitted on 500 evenly spaced rows of 6000";
  EXPECT_TRUE(Contains(rbf.out, note)) << rbf.out;
  EXPECT_TRUE(Contains(rbf.err, note)) << rbf.err;
  EXPECT_TRUE(Contains(rbf.out, "500 stored points")) << rbf.out;
  std::string summary[2];
  for (int threads = 1; threads <= 2; ++threads) {
    const Result pol =
        RunCli(dir, {"fit", "--data", data, "--model", "pol", "--hyper", "fixed", "--threads",
                     std::to_string(threads), "--out", dir.File("pol.json"), "-q"});
    ASSERT_EQ(pol.code, 0) << pol.err;
    // From the parameter table on (the line before it has the run time).
    summary[threads - 1] = pol.out.substr(pol.out.find("parameter"));
    summary[threads - 1] = summary[threads - 1].substr(0, summary[threads - 1].find("wrote"));
  }
  EXPECT_EQ(summary[0], summary[1]);
  EXPECT_EQ(RunCli(dir, {"fit", "--data", data, "--model", "pol", "--threads", "0", "--out",
                         dir.File("pol.json")})
                .code,
            2);
}

}  // namespace
}  // namespace structgp
