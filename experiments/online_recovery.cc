// Recovery of online learning at 7 joints: how long after a change of the robot the
// one-step-ahead error of an online model is back at its level before the change
// (docs/online.md, section "Recovery at 7 joints").
//
//   build/experiments/online_recovery            (full run: 10-15 min on a shared 2-vCPU VM)
//   build/experiments/online_recovery --quick --check   (CI size, the ctest)
//
// Robot: sim::Panda (KDL), with joint friction (Coulomb 10% and viscous 5% of each joint's RMS
// torque, tanh width 0.01 rad/s), torque noise 1% of each joint's RMS torque. The log: a
// periodic task at 1 kHz about the Panda's ready pose (a closed via-point path of 5 s traversed
// again and again, continuous velocities, +-0.8 rad), of --seconds s. Two scenarios:
// - payload: at half the log the arm picks up 2 kg, 0.2 m along the flange axis (a point mass
//   added to link 7), and keeps it;
// - drift: from half the log on, every joint's Coulomb and viscous friction grow linearly to
//   twice their value over a sixth of the log, then stay there.
// Each log is streamed in time order through an online model, predicting each sample before
// learning it (Replay for rbd, the same loop on OnlineLearner for the Nystrom model):
// - rbd+fri: the regressor form of the rigid-body model (P = 98), prior centred on the URDF of
//   the unloaded arm (exact kinematics and inertias, no friction), noise level known;
// - nys+fri: the structured kernel k_pol (PolFormulaKernel, 7 joints) by D Nystrom features
//   (inducing states by greedy variance) plus the paper's friction features, started from a
//   batch fit on 60 s of an offline excitation log of the unloaded arm (50 Hz, 60 via points,
//   +-1 rad about the ready pose);
// each without forgetting, with forgetting factors per sample and with a sliding window.
//
// Measures. Error signal: the one-step-ahead error of each joint divided by that joint's noise
// std; "level" = RMS of it over joints and a time span (1 = the noise). Steady level: over the
// last cycle (5 s) before the change. Smoothed error at time s: the level over [s, s + 0.5 s).
// Time to recover: the smallest tau (10 ms grid) after the change (payload: the pickup; drift:
// the end of the ramp) from which the smoothed error stays within 1.2x the steady level for
// 1 s (the hold inside the log); "not recovered" when there is none, "diverged before the
// change" when the steady level is above 3x that of the same model without forgetting (the
// setting never learned the arm: covariance wind-up). Also the peak smoothed error after the
// change and the level over the last cycle of the log.

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <memory>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "experiment_program.h"
#include "structgp/feature/friction_feature_map.h"
#include "structgp/feature/sum_feature_map.h"
#include "structgp/internal/text.h"
#include "structgp/kernel/nystrom_feature_map.h"
#include "structgp/kernel/pol_kernel.h"
#include "structgp/model/model_spec.h"
#include "structgp/model/robot_model.h"
#include "structgp/model/weight_space_gp.h"
#include "structgp/online/online_learner.h"
#include "structgp/online/replay.h"
#include "structgp/rigid_body/rigid_body_chain.h"
#include "structgp/sim/dataset.h"
#include "structgp/sim/friction.h"
#include "structgp/sim/robot.h"
#include "structgp/sim/trajectory.h"
#include "structgp/sim/urdf.h"

namespace structgp {
namespace {

using Clock = std::chrono::steady_clock;
using internal::Format;

constexpr int kJoints = 7;
constexpr double kDt = 1e-3;            // s: 1 kHz
constexpr double kCycle = 5.0;          // s: period of the task
constexpr int kCycleVias = 5;
constexpr double kTaskRange = 0.8;      // rad about the ready pose
constexpr double kNoise = 0.01;         // torque noise / RMS torque, per joint
constexpr double kCoulomb = 0.1;        // Coulomb friction / RMS torque
constexpr double kViscous = 0.05;       // viscous torque at the RMS velocity / RMS torque
constexpr double kFrictionWidth = 0.01; // rad/s (simulation and models)
constexpr double kDriftFactor = 2.0;    // friction at the end of the ramp / before
constexpr double kPayload = 2.0;        // kg
constexpr double kPayloadOffset = 0.2;  // m along link 7's z axis
// Recovery measure.
constexpr double kWindow = 0.5;     // s, smoothing window
constexpr double kGrid = 0.01;      // s
constexpr double kHold = 1.0;       // s the smoothed error must stay within the bound
constexpr double kRecoveredFactor = 1.2;
// A steady level above this multiple of the model's without forgetting marks the setting as
// diverged before the change (Recovery::time = kDiverged).
constexpr double kDivergedFactor = 3.0;
constexpr double kDiverged = -2.0;
// Offline log of the Nystrom model.
constexpr double kOfflineSeconds = 60.0;
constexpr double kOfflineDt = 0.02;
constexpr int kOfflineVias = 60;
constexpr double kOfflineRange = 1.0;
constexpr std::uint64_t kTaskSeed = 21, kOfflineSeed = 22, kNoiseSeed = 23;

struct Flags {
  double seconds = 60.0;
  int features = 512;
  std::vector<double> forgetting{0.9999, 0.999, 0.99};
  std::vector<double> window_seconds{1.0};
  std::vector<std::string> models{"rbd+fri", "nys+fri"};
  std::vector<std::string> scenarios{"payload", "drift"};
  std::string csv;
  bool quick = false;
  bool check = false;
};

// The Panda's "ready" configuration (rad), about which the motions run.
Vector ReadyPose() {
  Vector q(kJoints);
  q << 0.0, -M_PI / 4, 0.0, -3 * M_PI / 4, 0.0, M_PI / 2, M_PI / 4;
  return q;
}

sim::Trajectory AboutReady(sim::Trajectory tr) {
  tr.q.rowwise() += ReadyPose().transpose();
  return tr;
}

Matrix States(const sim::Trajectory& tr) {
  Matrix X(tr.num_samples(), 3 * kJoints);
  X << tr.q, tr.qd, tr.qdd;
  return X;
}


struct Log {
  std::string scenario;
  Matrix X, Y;           // m x 21, m x 7 (N m)
  Vector t;              // s
  Vector noise;          // per joint, N m
  double change = 0.0;   // s: the pickup, or the start of the friction ramp
  double settled = 0.0;  // s: when the robot stops changing (the pickup, the ramp's end)
};

struct World {
  sim::Robot arm = sim::Panda();
  std::shared_ptr<const RigidBodyChain> urdf;  // the unloaded arm, as its URDF has it
  Vector rms, qd_rms;                          // of the task, per joint
  sim::FrictionModel friction = sim::FrictionModel::Uniform(kJoints, {});
  Vector noise;                                // N m
};

World MakeWorld(const sim::Trajectory& task) {
  World w;
  w.urdf = std::make_shared<const RigidBodyChain>(
      RigidBodyChain::FromUrdfString(sim::ToUrdf(w.arm), {}, "panda.urdf"));
  const sim::Dataset clean = sim::Simulate(w.arm, task);
  w.rms = (clean.Y.colwise().squaredNorm() / clean.Y.rows()).cwiseSqrt().transpose();
  w.qd_rms = (task.qd.colwise().squaredNorm() / task.qd.rows()).cwiseSqrt().transpose();
  std::vector<sim::JointFriction> joints(kJoints);
  for (int j = 0; j < kJoints; ++j) {
    joints[j].coulomb = kCoulomb * w.rms[j];
    joints[j].viscous = kViscous * w.rms[j] / std::max(w.qd_rms[j], 0.1);
    joints[j].smoothing_velocity = kFrictionWidth;
  }
  w.friction = sim::FrictionModel(joints);
  w.noise = kNoise * w.rms;
  return w;
}

Log MakeLog(const World& w, const sim::Trajectory& task, const std::string& scenario) {
  const Eigen::Index m = task.num_samples();
  Log log;
  log.scenario = scenario;
  log.X = States(task);
  log.t = task.t;
  log.noise = w.noise;
  log.change = 0.5 * task.t[m - 1];
  const double ramp = task.t[m - 1] / 6.0;
  log.settled = scenario == "drift" ? log.change + ramp : log.change;
  const sim::Dataset before = sim::Simulate(w.arm, task);
  sim::Dataset after = before;
  if (scenario == "payload") {
    const sim::Robot loaded = sim::Robot::FromRigidBodyChain(
        sim::ToRigidBodyChain(w.arm).WithPayload(kPayload, {0.0, 0.0, kPayloadOffset}));
    after = sim::Simulate(loaded, task);
  } else if (scenario != "drift") {
    throw std::invalid_argument("--scenarios: unknown scenario '" + scenario +
                                "' (expected payload, drift)");
  }
  std::mt19937_64 rng(kNoiseSeed);
  std::normal_distribution<double> normal;
  log.Y.resize(m, kJoints);
  for (Eigen::Index i = 0; i < m; ++i) {
    const double t = task.t[i];
    const bool changed = t >= log.change;
    Vector tau = (changed ? after.Y : before.Y).row(i).transpose();
    // Friction: scale 1 before the change, then the ramp (drift) to kDriftFactor.
    double scale = 1.0;
    if (scenario == "drift" && changed) {
      scale = 1.0 + (kDriftFactor - 1.0) * std::min(1.0, (t - log.change) / ramp);
    }
    tau += scale * w.friction.Torque(task.qd.row(i).transpose());
    for (int j = 0; j < kJoints; ++j) log.Y(i, j) = tau[j] + w.noise[j] * normal(rng);
  }
  return log;
}

// ---- the models -----------------------------------------------------------------------------

struct Setting {
  std::string name;
  double forgetting = 1.0;
  int window = 0;  // samples
};

struct Trace {
  std::string model, setting;
  Matrix errors;  // m x N (N m)
  double update_p50 = 0, update_p99 = 0, predict_p50 = 0, predict_p99 = 0;
  long bad = 0;
  int features = 0;
};

double Percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[static_cast<size_t>(q * static_cast<double>(v.size() - 1))];
}

Trace RunRbd(const World& w, const Log& log, const Setting& s) {
  RobotModelOptions ro;
  ro.rigid_body = w.urdf;
  const RobotModel model(ParseModelSpec("rbd+fri"), kJoints, ro);
  ReplayOptions o;
  o.forgetting = s.forgetting;
  o.window_length = s.window;
  o.hyperparameters = model.DefaultHyperparameters(log.Y.topRows(1000));
  // The noise is known: sigma_n s_j = the noise std of joint j.
  o.hyperparameters.log_noise_std = std::log(kNoise);
  o.hyperparameters.log_output_scale = w.rms.array().log().matrix();
  const ReplaySummary r = Replay(model, log.X, log.Y, log.t, o);
  Trace run;
  run.errors = r.errors;
  run.update_p50 = r.update_us_p50;
  run.update_p99 = r.update_us_p99;
  run.predict_p50 = r.predict_us_p50;
  run.predict_p99 = r.predict_us_p99;
  run.bad = r.bad_samples;
  run.features = r.num_features;
  return run;
}

// The Nystrom model of k_pol + friction, fitted on the offline log of the unloaded arm.
struct NystromModel {
  std::shared_ptr<const FeatureMap> map;
  std::shared_ptr<const WeightSpaceGP> offline;
  Vector scales;
  double noise_variance = kNoise * kNoise;
};

NystromModel MakeNystrom(const World& w, int features) {
  const sim::Trajectory excitation =
      AboutReady(sim::ViaPoints(kJoints, kOfflineSeconds, kOfflineDt, kOfflineVias, 1.0,
                                kOfflineRange, kOfflineSeed, sim::ViaVelocity::kContinuous));
  sim::Dataset data = sim::Simulate(w.arm, excitation);
  std::mt19937_64 rng(kOfflineSeed);
  std::normal_distribution<double> normal;
  for (Eigen::Index i = 0; i < data.Y.rows(); ++i) {
    data.Y.row(i) += w.friction.Torque(excitation.qd.row(i).transpose()).transpose();
    for (int j = 0; j < kJoints; ++j) data.Y(i, j) += w.noise[j] * normal(rng);
  }
  const PolFormulaKernel kernel(kJoints);
  const Matrix Z = SelectInducingStates(kernel, data.X, features);
  auto nystrom = std::make_shared<const NystromFeatureMap>(kernel, Z);
  auto friction = std::make_shared<const FrictionFeatureMap>(kJoints, kFrictionWidth);
  NystromModel n;
  n.map = std::make_shared<const SumFeatureMap>(
      std::vector<std::shared_ptr<const FeatureMap>>{nystrom, friction});
  // Unit prior on the Nystrom weights; a broad one (std 10 torque scales) on friction.
  Vector prior = Vector::Ones(n.map->dim());
  prior.tail(friction->dim()).setConstant(100.0);
  n.scales = w.rms;
  auto gp = std::make_shared<WeightSpaceGP>(prior, n.noise_variance, kJoints, n.scales);
  Matrix Phi;
  n.map->EvaluateRows(data.X, &Phi);
  if (gp->Fit(Phi, data.Y) != Status::kOk) {
    throw std::runtime_error("online_recovery: the offline Nystrom fit failed");
  }
  n.offline = gp;
  return n;
}

// The loop of Replay on an OnlineLearner with a feature map that is not a RobotModel.
Trace RunNystrom(const NystromModel& n, const Log& log, const Setting& s) {
  OnlineLearnerOptions o;
  o.feature_map = n.map;
  o.num_outputs = kJoints;
  o.initial_model = n.offline;
  o.forgetting = s.forgetting;
  o.window_length = s.window;
  o.start_thread = false;
  o.max_batch = 1;
  o.queue_capacity = 1;
  OnlineLearner learner(o);
  const Eigen::Index m = log.X.rows();
  Trace run;
  run.features = learner.num_features();
  run.errors.setConstant(m, kJoints, std::nan(""));
  std::vector<double> update_us(m), predict_us(m);
  Vector x(3 * kJoints), y(kJoints), mean(kJoints);
  for (Eigen::Index i = 0; i < m; ++i) {
    x = log.X.row(i).transpose();
    y = log.Y.row(i).transpose();
    const auto t0 = Clock::now();
    const Status predicted = learner.Predict(x, mean);
    const auto t1 = Clock::now();
    if (predicted == Status::kOk) run.errors.row(i) = (y - mean).transpose();
    const long failures = learner.summary().update_failures;
    const auto t2 = Clock::now();
    const SubmitResult submitted = learner.Submit(x, y);
    learner.ProcessPending();
    const auto t3 = Clock::now();
    if (submitted != SubmitResult::kAccepted || learner.summary().update_failures != failures) {
      ++run.bad;
    }
    predict_us[i] = std::chrono::duration<double, std::micro>(t1 - t0).count();
    update_us[i] = std::chrono::duration<double, std::micro>(t3 - t2).count();
  }
  run.update_p50 = Percentile(update_us, 0.5);
  run.update_p99 = Percentile(update_us, 0.99);
  run.predict_p50 = Percentile(predict_us, 0.5);
  run.predict_p99 = Percentile(predict_us, 0.99);
  return run;
}

// ---- recovery -------------------------------------------------------------------------------

// The level (RMS of error / noise over joints) of rows [begin, end); NaN entries count as
// missing.
double Level(const Matrix& errors, const Vector& noise, Eigen::Index begin, Eigen::Index end) {
  double sum = 0.0;
  long n = 0;
  for (Eigen::Index i = std::max<Eigen::Index>(0, begin); i < std::min(end, errors.rows()); ++i) {
    for (int j = 0; j < kJoints; ++j) {
      const double e = errors(i, j) / noise[j];
      if (std::isfinite(e)) {
        sum += e * e;
        ++n;
      }
    }
  }
  return n > 0 ? std::sqrt(sum / static_cast<double>(n)) : std::nan("");
}

struct Recovery {
  double steady = 0.0;      // level over the cycle before the change
  double peak = 0.0;        // largest smoothed error after the change
  double final_level = 0.0; // level over the last cycle
  double time = -1.0;       // s after `settled`; -1: not recovered; kDiverged
};

Recovery Measure(const Trace& run, const Log& log) {
  const auto row = [&](double t) { return static_cast<Eigen::Index>(std::llround(t / kDt)); };
  const Eigen::Index m = run.errors.rows();
  Recovery r;
  r.steady = Level(run.errors, log.noise, row(log.change - kCycle), row(log.change));
  r.final_level = Level(run.errors, log.noise, m - row(kCycle), m);
  const Eigen::Index w = row(kWindow);
  // Smoothed error at the grid points from the change to the end (window inside the log).
  std::vector<double> smooth;
  const double last_start = (m - w) * kDt;
  for (double s = log.change; s <= last_start + 1e-9; s += kGrid) {
    smooth.push_back(Level(run.errors, log.noise, row(s), row(s) + w));
  }
  for (double v : smooth) r.peak = std::max(r.peak, v);
  const double bound = kRecoveredFactor * r.steady;
  const auto first = static_cast<size_t>(std::llround((log.settled - log.change) / kGrid));
  const auto hold = static_cast<size_t>(std::llround(kHold / kGrid));
  // The hold must fit in the log: a bound reached in its last second does not count.
  for (size_t k = first; k + hold < smooth.size(); ++k) {
    bool stays = true;
    for (size_t l = k; l <= k + hold; ++l) {
      if (!(smooth[l] <= bound)) {
        stays = false;
        k = l;  // no start before l + 1 can hold either
        break;
      }
    }
    if (stays) {
      r.time = static_cast<double>(k - first) * kGrid;
      break;
    }
  }
  return r;
}

std::vector<Setting> Settings(const Flags& f) {
  std::vector<Setting> out = {{"none", 1.0, 0}};
  for (double l : f.forgetting) out.push_back({Format("forgetting %g", l), l, 0});
  for (double s : f.window_seconds) {
    out.push_back({Format("window %g s", s), 1.0, static_cast<int>(std::llround(s / kDt))});
  }
  return out;
}

int Run(Flags f, int argc, char** argv) {
  if (f.quick) {
    f.seconds = 15.0;
    f.models = {"rbd+fri"};
    f.scenarios = {"payload"};
    f.forgetting = {0.999};
    f.window_seconds = {};
  }
  for (double l : f.forgetting) {
    if (!(l > 0.0 && l <= 1.0)) {
      throw std::invalid_argument("--forgetting: expected values in (0, 1], got " +
                                  Format("%g", l));
    }
  }
  for (double w : f.window_seconds) {
    if (!(w >= kDt)) {
      throw std::invalid_argument("--window: expected windows of at least 0.001 s, got " +
                                  Format("%g", w));
    }
  }
  for (const std::string& m : f.models) {
    if (m != "rbd+fri" && m != "nys+fri") {
      throw std::invalid_argument("--models: unknown model '" + m +
                                  "' (expected rbd+fri, nys+fri)");
    }
  }
  for (const std::string& c : f.scenarios) {
    if (c != "payload" && c != "drift") {
      throw std::invalid_argument("--scenarios: unknown scenario '" + c +
                                  "' (expected payload, drift)");
    }
  }
  const sim::Trajectory task =
      AboutReady(sim::ViaPoints(kJoints, f.seconds, kDt, kCycleVias, f.seconds / kCycle,
                                kTaskRange, kTaskSeed, sim::ViaVelocity::kContinuous));
  const World world = MakeWorld(task);
  std::printf("# %s\n", CommandLine("online_recovery", argc, argv).c_str());
  std::printf("panda, %g s at 1 kHz (task cycle %g s), change at %g s; noise (N m):", f.seconds,
              kCycle, 0.5 * task.t[task.num_samples() - 1]);
  for (int j = 0; j < kJoints; ++j) std::printf(" %.3g", world.noise[j]);
  std::printf("\n");
  const bool nystrom = std::find(f.models.begin(), f.models.end(), "nys+fri") != f.models.end();
  NystromModel nys;
  if (nystrom) {
    const auto t0 = Clock::now();
    nys = MakeNystrom(world, f.features);
    std::printf("nys+fri: D = %d (%d Nystrom + friction), offline fit %.1f s\n", nys.map->dim(),
                nys.map->dim() - (2 * kJoints + 1),
                std::chrono::duration<double>(Clock::now() - t0).count());
  }
  std::printf(
      "\n| scenario | model | setting | steady level | peak after change | time to recover "
      "| last cycle | update p50 / p99 us | predict p50 / p99 us |\n"
      "|---|---|---|---|---|---|---|---|---|\n");
  struct Result {
    std::string scenario, model, setting;
    Recovery r;
  };
  std::vector<Result> results;
  std::ofstream csv;
  if (!f.csv.empty()) {
    csv.open(f.csv);
    if (!csv) throw std::runtime_error("cannot write " + f.csv);
    csv << "# " << CommandLine("online_recovery", argc, argv) << "\n"
        << "scenario,model,setting,t,smoothed_error_over_noise\n";
  }
  for (const std::string& scenario : f.scenarios) {
    const Log log = MakeLog(world, task, scenario);
    for (const std::string& model : f.models) {
      double reference_steady = HUGE_VAL;
      for (const Setting& s : Settings(f)) {
        Trace run = model == "rbd+fri" ? RunRbd(world, log, s) : RunNystrom(nys, log, s);
        Recovery r = Measure(run, log);
        if (s.name == "none") reference_steady = r.steady;
        // A setting whose error before the change is far above the same model's without
        // forgetting has not learned the arm (wind-up): no recovery time to report.
        if (r.steady > kDivergedFactor * reference_steady) r.time = kDiverged;
        const std::string time = r.time == kDiverged ? "diverged before the change"
                                 : r.time < 0        ? "not recovered"
                                                     : Format("%.2f s", r.time);
        std::printf("| %s | %s | %s | %.3g | %.3g | %s | %.3g | %.0f / %.0f | %.0f / %.0f |%s\n",
                    scenario.c_str(), model.c_str(), s.name.c_str(), r.steady, r.peak,
                    time.c_str(), r.final_level, run.update_p50, run.update_p99, run.predict_p50,
                    run.predict_p99, run.bad ? Format(" %ld bad samples", run.bad).c_str() : "");
        std::fflush(stdout);
        results.push_back({scenario, model, s.name, r});
        if (csv.is_open()) {
          const Eigen::Index w = std::llround(kWindow / kDt);
          for (Eigen::Index i = 0; i + w <= run.errors.rows(); i += std::llround(0.1 / kDt)) {
            csv << scenario << "," << model << "," << s.name << "," << Format("%.3f", i * kDt)
                << "," << Format("%.5g", Level(run.errors, log.noise, i, i + w)) << "\n";
          }
        }
      }
    }
  }
  std::printf(
      "\nlevel: RMS over joints of the one-step-ahead error / the joint's noise std; steady: "
      "the cycle before the change; time to recover: after the pickup (payload) or the end of "
      "the ramp (drift), until the 0.5 s-smoothed error stays within %.1fx steady for %g s\n",
      kRecoveredFactor, kHold);
  if (f.check) {
    // rbd with forgetting must be back within 1.2x after the payload; without forgetting the
    // unloaded samples must hold it back to the end of the log.
    const auto find = [&](const std::string& scenario, const std::string& setting) {
      for (const Result& r : results) {
        if (r.scenario == scenario && r.model == "rbd+fri" && r.setting == setting) return &r;
      }
      return static_cast<const Result*>(nullptr);
    };
    const Result* forget = find("payload", Format("forgetting %g", f.forgetting.front()));
    const Result* keep = find("payload", "none");
    if (forget == nullptr || keep == nullptr) {
      std::fprintf(stderr, "online_recovery: --check needs rbd+fri on payload\n");
      return kExitUsage;
    }
    bool ok = true;
    if (!(forget->r.time >= 0.0)) {
      std::fprintf(stderr, "online_recovery: check failed: rbd+fri with forgetting did not "
                           "recover from the payload within the log\n");
      ok = false;
    }
    if (keep->r.time >= 0.0) {
      std::fprintf(stderr, "online_recovery: check failed: rbd+fri without forgetting "
                           "recovered from the payload (%.2f s): the change is too small to "
                           "tell the settings apart\n", keep->r.time);
      ok = false;
    }
    if (!ok) return 3;
  }
  return 0;
}

}  // namespace
}  // namespace structgp

int main(int argc, char** argv) {
  CLI::App app(
      "Time to recover of online models at 7 joints after a payload change and a friction "
      "drift (docs/online.md)",
      "online_recovery");
  structgp::Flags f;
  structgp::AddFlag(&app, "--seconds", &f.seconds, "length of the 1 kHz log, s (>= 11)")
      ->check(structgp::AtLeast(11));
  structgp::AddFlag(&app, "--features", &f.features, "Nystrom features of nys+fri")
      ->check(structgp::AtLeast(8));
  app.add_option("--forgetting", f.forgetting, "forgetting factors per sample, besides none")
      ->delimiter(',');
  app.add_option("--window", f.window_seconds, "sliding windows, s")->delimiter(',');
  structgp::AddListFlag(&app, "--models", &f.models, "rbd+fri, nys+fri");
  structgp::AddListFlag(&app, "--scenarios", &f.scenarios, "payload, drift");
  app.add_option("--csv", f.csv, "smoothed error over time of every run (CSV)");
  app.add_flag("--quick", f.quick,
               "CI size: 15 s log, rbd+fri on the payload, forgetting 0.999 only, no window");
  app.add_flag("--check", f.check,
               "exit 3 unless rbd+fri with forgetting recovers from the payload and without "
               "does not");
  return structgp::RunProgram(&app, argc, argv, [&] { return structgp::Run(f, argc, argv); });
}
