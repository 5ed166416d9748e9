// Learned feedforward in a simulated 1 kHz control loop.
//
// A two-link arm moving in a vertical plane (sim::TwoLinkArm, KDL rigid-body dynamics, with
// Coulomb + viscous joint friction) is integrated at 1 kHz (semi-implicit Euler on the forward
// dynamics) and tracks a smooth periodic reference with a deliberately soft PD controller.
// The feedforward torque comes from
//   (a) nothing: PD only;
//   (b) a model trained offline (batch fit) on a different, exciting trajectory;
//   (c) a model learned online from zero during the run: each tick one fused
//       WeightSpaceGP::UpdateAndPredict learns the previous tick's (state, torque) and predicts
//       the torque for the next reference state;
//   (d) as (c), with the feedforward scaled per joint by its predictive variance,
//       gain = 1 / (1 + var / var0): trust the model only where it has seen data;
//   (e) as (c), but with the OnlineLearner: the loop only submits samples and predicts, a
//       learner thread updates the model; the loop is paced to wall-clock 1 kHz here, so this
//       run takes as long as it simulates and its figures vary a little from run to run.
// The model is k_pol (eq. 17) + the paper's friction bases as explicit features (D = 138).
//
//   build/examples/closed_loop [out_dir] [--no-threaded] [--seconds S] [--trust-std N_m]
//   build/examples/closed_loop [out_dir] --robot panda [--models rbd,nys] [--trust-fraction F]
//       [--model-noise F]
//
// With --robot panda the same runs on the 7-joint Panda (see "the 7-joint loop" below) with
// rbd+fri from a +-30% wrong URDF and Nystrom k_pol + friction, each through the OnlineLearner,
// and the per-tick predict and update times; it writes <out_dir>/closed_loop_panda.csv.
//
// Prints the tracking RMS of each run per second and overall, and writes
// <out_dir>/closed_loop.csv (per tick: reference, errors, feedforward) and
// <out_dir>/closed_loop.svg (tracking error over time and RMS per second). out_dir defaults to
// ./closed-loop-out.

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "structgp/feature/friction_feature_map.h"
#include "structgp/kernel/nystrom_feature_map.h"
#include "structgp/kernel/pol_kernel.h"
#include "structgp/model/model_spec.h"
#include "structgp/model/robot_model.h"
#include "structgp/rigid_body/rigid_body_chain.h"
#include "structgp/feature/pol_feature_map.h"
#include "structgp/feature/sum_feature_map.h"
#include "structgp/feature/feature_hyperparameters.h"
#include "structgp/model/weight_space_gp.h"
#include "structgp/online/online_learner.h"
#include "structgp/sim/dataset.h"
#include "structgp/sim/friction.h"
#include "structgp/sim/robot.h"
#include "structgp/sim/trajectory.h"
#include "structgp/sim/urdf.h"

namespace {

using structgp::Matrix;
using structgp::Vector;
using Clock = std::chrono::steady_clock;

constexpr int kJoints = 2;
constexpr double kDt = 1e-3;             // s, 1 kHz
constexpr double kFrictionWidth = 0.02;  // rad/s, smoothing of the Coulomb term (plant & model)
constexpr std::uint64_t kReferenceSeed = 7;
constexpr std::uint64_t kOfflineSeed = 8;
constexpr std::uint64_t kSensorSeed = 9;
// Sensor noise on the learning samples: joint acceleration (rad/s^2) and torque (N m).
constexpr double kAccelerationNoise = 0.05;
constexpr double kTorqueNoise = 0.02;
// Default predictive standard deviation (N m) at which (d) halves the feedforward.
constexpr double kDefaultTrustStd = 1.0;

// kPrior (panda only): the feedforward of the model's prior mean (rbd: the URDF), not learning.
enum class Mode { kPd, kPrior, kOffline, kOnline, kOnlineVariance, kThreaded };

const char* Name(Mode mode) {
  switch (mode) {
    case Mode::kPd:
      return "(a) PD only";
    case Mode::kPrior:
      return "(a') PD + prior mean (the URDF)";
    case Mode::kOffline:
      return "(b) PD + offline model";
    case Mode::kOnline:
      return "(c) PD + online model";
    case Mode::kOnlineVariance:
      return "(d) PD + online, variance-scaled";
    case Mode::kThreaded:
      return "(e) PD + OnlineLearner thread";
  }
  return "?";
}

const char* Key(Mode mode) {
  switch (mode) {
    case Mode::kPd:
      return "pd";
    case Mode::kPrior:
      return "prior";
    case Mode::kOffline:
      return "offline";
    case Mode::kOnline:
      return "online";
    case Mode::kOnlineVariance:
      return "online_var";
    case Mode::kThreaded:
      return "threaded";
  }
  return "?";
}

struct Setup {
  structgp::sim::Robot robot = structgp::sim::TwoLinkArm();
  structgp::sim::FrictionModel friction = structgp::sim::FrictionModel::Uniform(kJoints, [] {
    structgp::sim::JointFriction f;
    f.coulomb = 0.8;
    f.viscous = 0.5;
    f.smoothing_velocity = kFrictionWidth;
    return f;
  }());
  structgp::sim::Trajectory reference;
  Vector kp = (Vector(kJoints) << 60.0, 30.0).finished();  // N m / rad
  Vector kd = (Vector(kJoints) << 8.0, 4.0).finished();    // N m s / rad
  std::shared_ptr<const structgp::FeatureMap> map;
  Vector prior_variance;
  Vector output_scales;
  double noise_variance = 0.0;
  std::unique_ptr<structgp::WeightSpaceGP> offline;
};

struct Run {
  Mode mode;
  Matrix error;                        // ticks x N, q_ref - q (rad)
  Matrix ff;                           // ticks x N, feedforward applied (N m)
  Matrix gain;                         // ticks x N, feedforward gain (1 except (d))
  std::vector<double> rms_per_second;  // rad
  double rms = 0.0;
  double compute_p50_us = 0.0;  // controller time per tick (learning modes)
  double compute_max_us = 0.0;
  std::string note;
};

Vector State(const Vector& q, const Vector& qd, const Vector& qdd) {
  Vector x(3 * kJoints);
  x << q, qd, qdd;
  return x;
}

Run Simulate(Mode mode, const Setup& s, bool paced, double trust_variance) {
  const structgp::sim::Trajectory& ref = s.reference;
  const int ticks = static_cast<int>(ref.num_samples());
  Run run;
  run.mode = mode;
  run.error.setZero(ticks, kJoints);
  run.ff.setZero(ticks, kJoints);
  run.gain.setOnes(ticks, kJoints);

  // Models.
  const int D = s.map->dim();
  std::unique_ptr<structgp::WeightSpaceGP> online;
  std::unique_ptr<structgp::OnlineLearner> learner;
  if (mode == Mode::kOnline || mode == Mode::kOnlineVariance) {
    online = std::make_unique<structgp::WeightSpaceGP>(s.prior_variance, s.noise_variance, kJoints,
                                                       s.output_scales);
  }
  if (mode == Mode::kThreaded) {
    structgp::OnlineLearnerOptions o;
    o.feature_map = s.map;
    o.num_outputs = kJoints;
    o.prior_variance = s.prior_variance;
    o.noise_variance = s.noise_variance;
    o.output_scales = s.output_scales;
    o.queue_capacity = 256;
    // Plausibility bounds of the sensors: |q| <= pi rad, |qd| <= 20 rad/s, |qdd| <= 500 rad/s^2,
    // |tau| <= 100 N m. Anything outside is a sensor glitch and must not be learned.
    o.input_upper.resize(3 * kJoints);
    o.input_upper << Vector::Constant(kJoints, 3.14159), Vector::Constant(kJoints, 20.0),
        Vector::Constant(kJoints, 500.0);
    o.input_lower = -o.input_upper;
    o.target_limit = Vector::Constant(kJoints, 100.0);
    learner = std::make_unique<structgp::OnlineLearner>(o);
  }
  Vector phi_sample(D), phi_ref(D), mean(kJoints), latent(kJoints), noisy(kJoints);
  Vector none(0);  // "no variance" for UpdateAndPredict
  Vector sample_x(3 * kJoints), sample_tau(kJoints);
  bool have_sample = false;
  std::mt19937_64 rng(kSensorSeed);
  std::normal_distribution<double> normal;
  std::vector<double> compute_us;
  compute_us.reserve(static_cast<std::size_t>(ticks));

  Vector q = ref.q.row(0).transpose();
  Vector qd = ref.qd.row(0).transpose();
  const auto start = Clock::now();
  for (int k = 0; k < ticks; ++k) {
    if (paced) std::this_thread::sleep_until(start + std::chrono::microseconds(1000 * k));
    const Vector q_ref = ref.q.row(k).transpose();
    const Vector qd_ref = ref.qd.row(k).transpose();
    const Vector x_ref = State(q_ref, qd_ref, ref.qdd.row(k).transpose());

    // Feedforward for this tick.
    Vector ff = Vector::Zero(kJoints);
    Vector gain = Vector::Ones(kJoints);
    const auto t0 = Clock::now();
    switch (mode) {
      case Mode::kPd:
        break;
      case Mode::kOffline:
        s.map->Evaluate(x_ref, phi_ref);
        s.offline->Predict(phi_ref, mean);
        ff = mean;
        break;
      case Mode::kOnline:
      case Mode::kOnlineVariance: {
        const bool variance = mode == Mode::kOnlineVariance;
        s.map->Evaluate(x_ref, phi_ref);
        if (have_sample) {
          // Learn the last tick's sample and predict this tick's torque in one pass.
          s.map->Evaluate(sample_x, phi_sample);
          if (variance) {
            online->UpdateAndPredict(phi_sample, sample_tau, phi_ref, mean, latent, noisy);
          } else {
            online->UpdateAndPredict(phi_sample, sample_tau, phi_ref, mean, none, none);
          }
        } else {
          online->PredictWithVariance(phi_ref, mean, latent, noisy);
        }
        ff = mean;
        if (variance) gain = (1.0 + latent.array() / trust_variance).inverse().matrix();
        break;
      }
      case Mode::kThreaded:
        if (have_sample) learner->Submit(sample_x, sample_tau);
        learner->Predict(x_ref, mean);
        ff = mean;
        break;
      case Mode::kPrior:  // the panda's runs only
        break;
    }
    if (mode != Mode::kPd && mode != Mode::kOffline) {
      compute_us.push_back(1e6 * std::chrono::duration<double>(Clock::now() - t0).count());
    }

    // Control law and plant: M qdd + C qd + G = tau - tau_friction(qd).
    const Vector e = q_ref - q;
    const Vector tau =
        gain.cwiseProduct(ff) + s.kp.cwiseProduct(e) + s.kd.cwiseProduct(qd_ref - qd);
    const Vector qdd = s.robot.ForwardDynamics(q, qd, tau - s.friction.Torque(qd));
    run.error.row(k) = e.transpose();
    run.ff.row(k) = (gain.cwiseProduct(ff)).transpose();
    run.gain.row(k) = gain.transpose();

    // The sample this tick produced (noisy sensors), learned at the next tick.
    sample_x = State(q, qd, qdd + kAccelerationNoise * Vector::NullaryExpr(kJoints, [&]() {
                                    return normal(rng);
                                  }));
    sample_tau = tau + kTorqueNoise * Vector::NullaryExpr(kJoints, [&]() { return normal(rng); });
    have_sample = true;

    qd += kDt * qdd;  // semi-implicit Euler
    q += kDt * qd;
  }

  // Figures.
  const int seconds = ticks / 1000;
  double total = 0.0;
  for (int sec = 0; sec < seconds; ++sec) {
    const double sq = run.error.middleRows(sec * 1000, 1000).squaredNorm() / (1000.0 * kJoints);
    run.rms_per_second.push_back(std::sqrt(sq));
    total += sq;
  }
  run.rms = std::sqrt(total / seconds);
  if (!compute_us.empty()) {
    std::sort(compute_us.begin(), compute_us.end());
    run.compute_p50_us = compute_us[compute_us.size() / 2];
    run.compute_max_us = compute_us.back();
  }
  if (learner != nullptr) {
    learner->WaitUntilIdle();
    const structgp::OnlineLearnerSummary summary = learner->summary();
    std::ostringstream os;
    os << "learner: " << summary.updates << " updates, " << summary.rejected()
       << " rejected (out of range " << summary.rejected_out_of_range << ", non-finite "
       << summary.rejected_non_finite << "), " << summary.dropped_queue_full << " dropped, "
       << summary.weight_publishes << " weight publishes";
    run.note = os.str();
  }
  return run;
}

// Offline model: batch fit on 60 s of an excitation trajectory of the same arm (smooth motion
// through 60 random via points, |q| <= 1.3 rad, 100 Hz). A via-point excitation matters: a
// periodic one retraces a single closed curve in state space, from which the inertial, Coriolis
// and gravity terms cannot be told apart, and such a model extrapolates poorly to other paths.
void TrainOffline(Setup* s) {
  const structgp::sim::Trajectory excitation = structgp::sim::ViaPoints(
      kJoints, 60.0, 0.01, 60, 1.0, 1.3, kOfflineSeed, structgp::sim::ViaVelocity::kContinuous);
  structgp::sim::SimulationOptions options;
  options.friction = s->friction;
  options.noise_std = kTorqueNoise;
  options.seed = kOfflineSeed;
  const structgp::sim::Dataset data = structgp::sim::Simulate(s->robot, excitation, options);
  auto map = std::make_shared<structgp::SumFeatureMap>(
      std::vector<std::shared_ptr<const structgp::FeatureMap>>{
          std::make_shared<structgp::PolFeatureMap>(kJoints),
          std::make_shared<structgp::FrictionFeatureMap>(kJoints, kFrictionWidth)});
  structgp::Hyperparameters hyper = structgp::DefaultHyperparameters(*map, kJoints);
  // Broad prior on the friction coefficients (the semi-parametric sum, eqs. 43-44).
  hyper.log_block_scale[hyper.log_block_scale.size() - 1] = std::log(10.0);
  s->map = map;
  s->prior_variance = structgp::PriorVariance(*map, hyper);
  s->output_scales = data.Y.array().square().colwise().mean().sqrt().transpose();
  s->noise_variance = 1e-4;  // sigma_n = 1% of each joint's torque scale
  s->offline = std::make_unique<structgp::WeightSpaceGP>(s->prior_variance, s->noise_variance,
                                                         kJoints, s->output_scales);
  Matrix Phi;
  map->EvaluateRows(data.X, &Phi);
  if (s->offline->Fit(Phi, data.Y) != structgp::Status::kOk) {
    throw std::runtime_error("offline fit failed");
  }
}

// ---- output -------------------------------------------------------------------------------

void WriteCsv(const std::string& path, const Setup& s, const std::vector<Run>& runs) {
  std::ofstream out(path);
  if (!out) throw std::runtime_error("cannot write " + path);
  out << "t";
  for (int j = 1; j <= kJoints; ++j) out << ",q_ref" << j;
  for (const Run& r : runs) {
    for (int j = 1; j <= kJoints; ++j) out << ",err_" << Key(r.mode) << j;
    for (int j = 1; j <= kJoints; ++j) out << ",ff_" << Key(r.mode) << j;
    if (r.mode == Mode::kOnlineVariance) {
      for (int j = 1; j <= kJoints; ++j) out << ",gain_" << Key(r.mode) << j;
    }
  }
  out << "\n";
  const int ticks = static_cast<int>(s.reference.num_samples());
  char buffer[64];
  for (int k = 0; k < ticks; ++k) {
    std::snprintf(buffer, sizeof(buffer), "%.3f", s.reference.t[k]);
    out << buffer;
    for (int j = 0; j < kJoints; ++j) out << "," << s.reference.q(k, j);
    for (const Run& r : runs) {
      for (int j = 0; j < kJoints; ++j) out << "," << r.error(k, j);
      for (int j = 0; j < kJoints; ++j) out << "," << r.ff(k, j);
      if (r.mode == Mode::kOnlineVariance) {
        for (int j = 0; j < kJoints; ++j) out << "," << r.gain(k, j);
      }
    }
    out << "\n";
  }
}

const char* Colour(Mode mode) {
  switch (mode) {
    case Mode::kPd:
      return "#7f7f7f";
    case Mode::kPrior:
      return "#9467bd";
    case Mode::kOffline:
      return "#1f77b4";
    case Mode::kOnline:
      return "#d62728";
    case Mode::kOnlineVariance:
      return "#2ca02c";
    case Mode::kThreaded:
      return "#ff7f0e";
  }
  return "#000000";
}

// A panel with a log10 y axis: maps data to pixels.
struct Panel {
  double left, top, width, height;
  double x_max;
  double log_min, log_max;  // decades
  double X(double x) const { return left + width * x / x_max; }
  double Y(double v) const {
    const double l = std::log10(std::max(v, std::pow(10.0, log_min)));
    return top + height * (log_max - l) / (log_max - log_min);
  }
};

void Axes(std::ostream& svg, const Panel& p, const std::string& title, const std::string& x_label,
          const std::string& y_label) {
  svg << "<rect x='" << p.left << "' y='" << p.top << "' width='" << p.width << "' height='"
      << p.height << "' fill='none' stroke='#000'/>\n";
  svg << "<text x='" << p.left + p.width / 2 << "' y='" << p.top - 8
      << "' text-anchor='middle' font-size='14'>" << title << "</text>\n";
  svg << "<text x='" << p.left + p.width / 2 << "' y='" << p.top + p.height + 34
      << "' text-anchor='middle' font-size='12'>" << x_label << "</text>\n";
  svg << "<text transform='translate(" << p.left - 48 << "," << p.top + p.height / 2
      << ") rotate(-90)' text-anchor='middle' font-size='12'>" << y_label << "</text>\n";
  for (int d = static_cast<int>(p.log_min); d <= static_cast<int>(p.log_max); ++d) {
    const double y = p.Y(std::pow(10.0, d));
    svg << "<line x1='" << p.left << "' y1='" << y << "' x2='" << p.left + p.width << "' y2='" << y
        << "' stroke='#ddd'/>\n";
    svg << "<text x='" << p.left - 6 << "' y='" << y + 4 << "' text-anchor='end' font-size='11'>1e"
        << d << "</text>\n";
  }
  for (int t = 0; t <= static_cast<int>(p.x_max); ++t) {
    const double x = p.X(t);
    svg << "<line x1='" << x << "' y1='" << p.top + p.height << "' x2='" << x << "' y2='"
        << p.top + p.height + 4 << "' stroke='#000'/>\n";
    svg << "<text x='" << x << "' y='" << p.top + p.height + 17
        << "' text-anchor='middle' font-size='11'>" << t << "</text>\n";
  }
}

void WriteSvg(const std::string& path, const std::vector<Run>& runs, double seconds) {
  std::ofstream svg(path);
  if (!svg) throw std::runtime_error("cannot write " + path);
  const double width = 900, height = 760;
  svg << "<svg xmlns='http://www.w3.org/2000/svg' width='" << width << "' height='" << height
      << "' font-family='sans-serif'>\n<rect width='100%' height='100%' fill='#fff'/>\n";
  // Top: |e(t)| in mrad, every 10 ms.
  const Panel top{80, 40, 600, 300, seconds, -2.0, 3.0};
  Axes(svg, top, "Tracking error |q_ref - q| (mrad), two-link arm at 1 kHz", "time (s)", "mrad");
  for (const Run& r : runs) {
    svg << "<polyline fill='none' stroke-width='1' stroke='" << Colour(r.mode) << "' points='";
    for (int k = 0; k < r.error.rows(); k += 10) {
      svg << top.X(k * kDt) << "," << top.Y(1e3 * r.error.row(k).norm()) << " ";
    }
    svg << "'/>\n";
  }
  // Bottom: RMS per second.
  const Panel bottom{80, 420, 600, 280, seconds, -1.0, 3.0};
  Axes(svg, bottom, "Tracking RMS per second (mrad)", "end of second (s)", "mrad");
  for (const Run& r : runs) {
    svg << "<polyline fill='none' stroke-width='2' stroke='" << Colour(r.mode) << "' points='";
    for (std::size_t sec = 0; sec < r.rms_per_second.size(); ++sec) {
      svg << bottom.X(sec + 1.0) << "," << bottom.Y(1e3 * r.rms_per_second[sec]) << " ";
    }
    svg << "'/>\n";
    for (std::size_t sec = 0; sec < r.rms_per_second.size(); ++sec) {
      svg << "<circle cx='" << bottom.X(sec + 1.0) << "' cy='"
          << bottom.Y(1e3 * r.rms_per_second[sec]) << "' r='3' fill='" << Colour(r.mode) << "'/>\n";
    }
  }
  // Legend.
  double y = 60;
  for (const Run& r : runs) {
    svg << "<line x1='700' y1='" << y << "' x2='725' y2='" << y << "' stroke-width='3' stroke='"
        << Colour(r.mode) << "'/>\n<text x='732' y='" << y + 4 << "' font-size='12'>"
        << Name(r.mode) << "</text>\n";
    char rms[64];
    std::snprintf(rms, sizeof(rms), "RMS %.2f mrad", 1e3 * r.rms);
    svg << "<text x='732' y='" << y + 19 << "' font-size='11' fill='#555'>" << rms << "</text>\n";
    y += 44;
  }
  svg << "</svg>\n";
}

// ---- the 7-joint loop (--robot panda) --------------------------------------------------------
//
// sim::Panda (KDL, no armature) with joint friction (Coulomb 10% and viscous 5% of each joint's
// RMS torque on the reference, tanh width 0.01 rad/s), integrated at 1 kHz like the two-link
// arm, tracking three harmonics of 0.5 Hz (+-0.5 rad per joint) about the Panda's ready pose
// with a soft PD (per joint Kp = M_jj w^2, Kd = 2 M_jj w, w = 2 pi 2 rad/s, M at the ready pose).
// Two models, each through the OnlineLearner (the learning runs use it without a thread,
// Submit + ProcessPending each tick, except (e)):
// - rbd: rbd+fri, the regressor form (P = 98), its prior centred on a URDF whose inertial
//   parameters are all off by up to +-30% (what a user starts from);
// - nys: k_pol + friction by 512 Nystrom features, no kinematics; inducing states from the
//   offline excitation log (both for the offline fit and for learning from zero).
// Offline fits: 60 s of a via-point excitation (50 Hz) of the same plant. Sensor noise on the
// learned samples: 0.05 rad/s^2 on qdd, 1% of each joint's RMS torque on tau.

namespace panda {

constexpr int kN = 7;
constexpr double kAmplitude = 0.5;        // rad
constexpr double kBaseFrequency = 0.5;    // Hz
constexpr double kBandwidth = 2.0 * M_PI * 2.0;  // rad/s of the PD
constexpr double kTorqueNoise = 0.01;     // of each joint's RMS torque
constexpr double kCoulomb = 0.1, kViscous = 0.05;
constexpr double kWidth = 0.01;           // rad/s
constexpr double kUrdfError = 0.3;        // relative, uniform
constexpr int kFeatures = 512;
// Prior variance of the friction weights of nys, in units of s_j^2: std 10 torque scales.
constexpr double kNystromFrictionPrior = 100.0;
constexpr std::uint64_t kUrdfSeed = 5;
// A tracking error beyond this (rad) on any joint stops the run, as a robot's safety limit
// would (the table reports when).
constexpr double kDivergedError = 1.0;

Vector ReadyPose() {
  Vector q(kN);
  q << 0.0, -M_PI / 4, 0.0, -3 * M_PI / 4, 0.0, M_PI / 2, M_PI / 4;
  return q;
}

struct Plant {
  structgp::sim::Robot robot = structgp::sim::Panda();
  structgp::sim::FrictionModel friction = structgp::sim::FrictionModel::Uniform(kN, {});
  structgp::sim::Trajectory reference;
  Vector kp, kd, scale;  // scale: RMS torque of the reference, N m
};

struct Model {
  std::string key, label;
  structgp::OnlineLearnerOptions prior;    // learning from zero
  structgp::OnlineLearnerOptions offline;  // the offline fit, not learning
};

struct Result {
  std::string model;
  Mode mode;
  Matrix error;  // ticks x N, rad
  Vector rms;    // per joint, rad
  double total = 0.0, first_second = 0.0, last_second = 0.0;
  double predict_p50 = 0, predict_p99 = 0, predict_max = 0;
  double update_p50 = 0, update_p99 = 0, update_max = 0;
  double mean_gain = 1.0;
  double diverged_at = -1.0;  // s; < 0: the run did not diverge
  std::string note;
};

structgp::sim::Dataset Excitation(const Plant& p) {
  structgp::sim::Trajectory tr = structgp::sim::ViaPoints(
      kN, 60.0, 0.02, 60, 1.0, 1.0, kOfflineSeed, structgp::sim::ViaVelocity::kContinuous);
  tr.q.rowwise() += ReadyPose().transpose();
  structgp::sim::Dataset d = structgp::sim::Simulate(p.robot, tr);
  std::mt19937_64 rng(kOfflineSeed);
  std::normal_distribution<double> normal;
  for (Eigen::Index i = 0; i < d.Y.rows(); ++i) {
    d.Y.row(i) += p.friction.Torque(tr.qd.row(i).transpose()).transpose();
    for (int j = 0; j < kN; ++j) d.Y(i, j) += kTorqueNoise * p.scale[j] * normal(rng);
  }
  return d;
}

Plant MakePlant(double seconds) {
  Plant p;
  p.reference =
      structgp::sim::SumOfSines(kN, seconds, kDt, 3, kBaseFrequency, kAmplitude, kReferenceSeed);
  p.reference.q.rowwise() += ReadyPose().transpose();
  const structgp::sim::Dataset rb = structgp::sim::Simulate(p.robot, p.reference);
  p.scale = (rb.Y.colwise().squaredNorm() / rb.Y.rows()).cwiseSqrt().transpose();
  const Vector qd_rms =
      (p.reference.qd.colwise().squaredNorm() / p.reference.qd.rows()).cwiseSqrt().transpose();
  std::vector<structgp::sim::JointFriction> joints(kN);
  for (int j = 0; j < kN; ++j) {
    joints[j].coulomb = kCoulomb * p.scale[j];
    joints[j].viscous = kViscous * p.scale[j] / std::max(qd_rms[j], 0.1);
    joints[j].smoothing_velocity = kWidth;
  }
  p.friction = structgp::sim::FrictionModel(joints);
  const Vector m = p.robot.MassMatrix(ReadyPose()).diagonal();
  p.kp = m * kBandwidth * kBandwidth;
  p.kd = m * 2.0 * kBandwidth;
  return p;
}

Model MakeRbd(const Plant& p, const structgp::sim::Dataset& excitation, double model_noise) {
  structgp::RigidBodyChain chain = structgp::RigidBodyChain::FromUrdfString(
      structgp::sim::ToUrdf(p.robot), {}, "panda.urdf");
  std::mt19937_64 rng(kUrdfSeed);
  std::uniform_real_distribution<double> u(-kUrdfError, kUrdfError);
  Vector pi = chain.parameters();
  for (Eigen::Index k = 0; k < pi.size(); ++k) pi[k] *= 1.0 + u(rng);
  structgp::RobotModelOptions ro;
  ro.rigid_body = std::make_shared<const structgp::RigidBodyChain>(chain.WithParameters(pi));
  ro.friction_width = kWidth;
  structgp::RobotModel model(structgp::ParseModelSpec("rbd+fri"), kN, ro);
  structgp::Hyperparameters h = model.DefaultHyperparameters(excitation.Y);
  h.log_noise_std = std::log(model_noise);
  h.log_output_scale = p.scale.array().log().matrix();
  Model m;
  m.key = "rbd";
  m.label = "rbd+fri, URDF +-30%";
  m.prior.regressor_map = model.regressor_map();
  m.prior.prior_variance = structgp::RegressorPriorVariance(*model.regressor_map(), h.log_block_scale);
  m.prior.noise_variance = h.noise_variance();
  m.prior.output_scales = h.output_scales();
  if (model.Fit(excitation.X, excitation.Y, h) != structgp::Status::kOk) {
    throw std::runtime_error("the offline rbd fit failed");
  }
  m.offline = m.prior;
  m.offline.initial_regressor =
      std::make_shared<const structgp::RegressorGP>(*model.gp().regressor());
  return m;
}

// k_pol with its inertial and Coriolis blocks scaled so that each term is about 1 on the
// candidate states (at unit scales the inertial term is <qdd, qdd'> / N, about 100 on this
// reference: a prior 10 torque scales wide in the acceleration directions).
std::shared_ptr<const structgp::FeatureMap> NystromMap(const Matrix& candidates) {
  const double qdd2 = candidates.rightCols(kN).rowwise().squaredNorm().mean() / kN;
  const double qd4 =
      (candidates.middleCols(kN, kN).rowwise().squaredNorm() / kN).array().square().mean();
  Vector theta(4);
  theta << 0.0, -0.5 * std::log(qdd2), -0.5 * std::log(qd4), 0.0;
  const auto scaled = structgp::PolFormulaKernel(kN).WithParameters(theta);
  const structgp::Kernel& kernel = *scaled;
  const Matrix Z = structgp::SelectInducingStates(kernel, candidates, kFeatures);
  return std::make_shared<const structgp::SumFeatureMap>(
      std::vector<std::shared_ptr<const structgp::FeatureMap>>{
          std::make_shared<const structgp::NystromFeatureMap>(kernel, Z),
          std::make_shared<const structgp::FrictionFeatureMap>(kN, kWidth)});
}

Model MakeNystrom(const Plant& p, const structgp::sim::Dataset& excitation,
                  double model_noise) {
  const auto options = [&](std::shared_ptr<const structgp::FeatureMap> map) {
    structgp::OnlineLearnerOptions o;
    o.feature_map = map;
    o.num_outputs = kN;
    o.prior_variance = Vector::Ones(map->dim());
    o.prior_variance.tail(2 * kN + 1).setConstant(kNystromFrictionPrior);
    o.noise_variance = model_noise * model_noise;
    o.output_scales = p.scale;
    return o;
  };
  Model m;
  m.key = "nys";
  m.label = "k_pol+fri, Nystrom D = " + std::to_string(kFeatures);
  // Inducing states from the offline log's states, for both runs. Learning from zero uses them
  // without the offline fit. (States of the reference path alone do not do: a sample off the
  // path - the arm pushed off by a wrong feedforward - is then projected onto path states, the
  // learner attributes its large torque to them, and the loop feeds its own feedforward back:
  // it diverged within 50 ms in this set-up.)
  m.offline = options(NystromMap(excitation.X));
  m.prior = m.offline;
  auto gp = std::make_shared<structgp::WeightSpaceGP>(
      m.offline.prior_variance, m.offline.noise_variance, kN, m.offline.output_scales);
  Matrix Phi;
  m.offline.feature_map->EvaluateRows(excitation.X, &Phi);
  if (gp->Fit(Phi, excitation.Y) != structgp::Status::kOk) {
    throw std::runtime_error("the offline Nystrom fit failed");
  }
  m.offline.initial_model = gp;
  return m;
}

double Percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(q * static_cast<double>(v.size() - 1))];
}

Result Simulate(Mode mode, const Plant& p, const Model* model, double trust_fraction) {
  const structgp::sim::Trajectory& ref = p.reference;
  const int ticks = static_cast<int>(ref.num_samples());
  Result r;
  r.model = model != nullptr ? model->label : "-";
  r.mode = mode;
  r.error.setZero(ticks, kN);
  std::unique_ptr<structgp::OnlineLearner> learner;
  if (mode != Mode::kPd) {
    structgp::OnlineLearnerOptions o = mode == Mode::kOffline ? model->offline : model->prior;
    o.start_thread = mode == Mode::kThreaded;
    o.max_batch = mode == Mode::kThreaded ? 16 : 1;
    o.queue_capacity = 256;
    o.covariance_publish_period = mode == Mode::kOnlineVariance ? 1 : 0;
    learner = std::make_unique<structgp::OnlineLearner>(o);
  }
  const bool learning = mode == Mode::kOnline || mode == Mode::kOnlineVariance ||
                        mode == Mode::kThreaded;
  const Vector trust_variance = (trust_fraction * p.scale).array().square().matrix();
  Vector mean(kN), latent(kN), sample_x(3 * kN), sample_tau(kN), x_ref(3 * kN);
  bool have_sample = false;
  std::mt19937_64 rng(kSensorSeed);
  std::normal_distribution<double> normal;
  std::vector<double> predict_us, update_us;
  predict_us.reserve(ticks);
  update_us.reserve(ticks);
  double gain_sum = 0.0;
  Vector q = ref.q.row(0).transpose();
  Vector qd = ref.qd.row(0).transpose();
  const auto start = Clock::now();
  for (int k = 0; k < ticks; ++k) {
    if (mode == Mode::kThreaded) {
      std::this_thread::sleep_until(start + std::chrono::microseconds(1000 * k));
    }
    x_ref << ref.q.row(k).transpose(), ref.qd.row(k).transpose(), ref.qdd.row(k).transpose();
    Vector ff = Vector::Zero(kN);
    Vector gain = Vector::Ones(kN);
    if (learner != nullptr) {
      const auto t0 = Clock::now();
      if (learning && have_sample) {
        learner->Submit(sample_x, sample_tau);
        if (mode != Mode::kThreaded) learner->ProcessPending();
      }
      const auto t1 = Clock::now();
      const structgp::Status status = mode == Mode::kOnlineVariance
                                          ? learner->PredictWithVariance(x_ref, mean, latent)
                                          : learner->Predict(x_ref, mean);
      const auto t2 = Clock::now();
      if (learning) update_us.push_back(std::chrono::duration<double, std::micro>(t1 - t0).count());
      predict_us.push_back(std::chrono::duration<double, std::micro>(t2 - t1).count());
      if (status == structgp::Status::kOk) ff = mean;
      if (mode == Mode::kOnlineVariance) {
        gain = (1.0 + latent.array() / trust_variance.array()).inverse().matrix();
      }
    }
    gain_sum += gain.mean();
    const Vector e = ref.q.row(k).transpose() - q;
    const Vector tau = gain.cwiseProduct(ff) + p.kp.cwiseProduct(e) +
                       p.kd.cwiseProduct(ref.qd.row(k).transpose() - qd);
    r.error.row(k) = e.transpose();
    if (!e.allFinite() || e.cwiseAbs().maxCoeff() > kDivergedError) {
      r.diverged_at = k * kDt;
      r.error.bottomRows(ticks - k).setConstant(std::nan(""));
      break;
    }
    const Vector qdd = p.robot.ForwardDynamics(q, qd, tau - p.friction.Torque(qd));
    sample_x << q, qd, qdd + kAccelerationNoise * Vector::NullaryExpr(kN, [&]() {
      return normal(rng);
    });
    sample_tau = tau + kTorqueNoise * p.scale.cwiseProduct(
                           Vector::NullaryExpr(kN, [&]() { return normal(rng); }));
    have_sample = true;
    qd += kDt * qdd;
    q += kDt * qd;
  }
  if (r.diverged_at >= 0.0) {
    char b[96];
    std::snprintf(b, sizeof(b), "stopped at t = %.3f s: tracking error above %g rad",
                  r.diverged_at, kDivergedError);
    r.note = b;
    r.rms = Vector::Constant(kN, std::nan(""));
    r.total = r.first_second = r.last_second = std::nan("");
    return r;
  }
  r.rms = (r.error.colwise().squaredNorm() / ticks).cwiseSqrt().transpose();
  r.total = std::sqrt(r.error.squaredNorm() / (static_cast<double>(ticks) * kN));
  r.first_second = std::sqrt(r.error.topRows(1000).squaredNorm() / (1000.0 * kN));
  r.last_second = std::sqrt(r.error.bottomRows(1000).squaredNorm() / (1000.0 * kN));
  r.mean_gain = gain_sum / ticks;
  r.predict_p50 = Percentile(predict_us, 0.5);
  r.predict_p99 = Percentile(predict_us, 0.99);
  r.predict_max = Percentile(predict_us, 1.0);
  r.update_p50 = Percentile(update_us, 0.5);
  r.update_p99 = Percentile(update_us, 0.99);
  r.update_max = Percentile(update_us, 1.0);
  if (learner != nullptr && learning) {
    learner->WaitUntilIdle();
    const structgp::OnlineLearnerSummary s = learner->summary();
    std::ostringstream os;
    os << s.updates << " updates in " << s.batches << " passes, " << s.rejected()
       << " rejected, " << s.dropped_queue_full << " dropped, " << s.update_failures
       << " update failures";
    r.note = os.str();
  }
  return r;
}

int Main(const std::string& out_dir, double seconds, bool threaded, double trust_fraction,
         const std::vector<std::string>& models, double model_noise) {
  const Plant plant = MakePlant(seconds);
  const structgp::sim::Dataset excitation = Excitation(plant);
  std::printf("panda (7 joints, KDL), %g s at 1 kHz, reference 3 harmonics of %g Hz (+-%g rad)"
              " about the ready pose\nPD Kp:", seconds, kBaseFrequency, kAmplitude);
  for (int j = 0; j < kN; ++j) std::printf(" %.3g", plant.kp[j]);
  std::printf(" N m/rad; Kd:");
  for (int j = 0; j < kN; ++j) std::printf(" %.3g", plant.kd[j]);
  std::printf(" N m s/rad\nmodels' noise std %.3g of each joint's torque scale (the torque "
              "sensor's: %.3g)\ntorque scales (N m):", model_noise, kTorqueNoise);
  for (int j = 0; j < kN; ++j) std::printf(" %.3g", plant.scale[j]);
  std::printf("\n");
  std::vector<Model> built;
  for (const std::string& key : models) {
    const auto t0 = Clock::now();
    if (key == "rbd") {
      built.push_back(MakeRbd(plant, excitation, model_noise));
    } else if (key == "nys") {
      built.push_back(MakeNystrom(plant, excitation, model_noise));
    } else {
      throw std::invalid_argument("--models: unknown model '" + key + "' (expected rbd, nys)");
    }
    std::printf("%s: built and fitted offline in %.1f s\n", built.back().label.c_str(),
                std::chrono::duration<double>(Clock::now() - t0).count());
  }
  std::vector<Result> results;
  results.push_back(Simulate(Mode::kPd, plant, nullptr, trust_fraction));
  for (const Model& m : built) {
    for (const Mode mode : {Mode::kPrior, Mode::kOffline, Mode::kOnline, Mode::kOnlineVariance,
                            Mode::kThreaded}) {
      if (mode == Mode::kThreaded && !threaded) continue;
      if (mode == Mode::kPrior && m.key != "rbd") continue;  // nys: zero, PD only
      results.push_back(Simulate(mode, plant, &m, trust_fraction));
    }
  }
  std::printf(
      "\n| model | run | tracking RMS per joint (mrad) | all | 1st s | last s | predict p50 / p99 "
      "/ max us | update p50 / p99 / max us |\n|---|---|---|---|---|---|---|---|\n");
  for (const Result& r : results) {
    std::string joints;
    for (int j = 0; j < kN; ++j) {
      char b[32];
      std::snprintf(b, sizeof(b), "%s%.3g", j ? " " : "", 1e3 * r.rms[j]);
      joints += b;
    }
    char timing[160] = "-", update[160] = "-";
    if (r.mode != Mode::kPd) {
      std::snprintf(timing, sizeof(timing), "%.0f / %.0f / %.0f", r.predict_p50, r.predict_p99,
                    r.predict_max);
    }
    if (r.update_p50 > 0) {
      std::snprintf(update, sizeof(update), "%.0f / %.0f / %.0f", r.update_p50, r.update_p99,
                    r.update_max);
    }
    if (r.diverged_at >= 0.0) {
      std::printf("| %s | %s | stopped at %.3f s: error > %g rad | - | - | - | - | - |\n",
                  r.model.c_str(), Name(r.mode), r.diverged_at, kDivergedError);
      continue;
    }
    std::printf("| %s | %s | %s | %.3g | %.3g | %.3g | %s | %s |\n", r.model.c_str(), Name(r.mode),
                joints.c_str(), 1e3 * r.total, 1e3 * r.first_second, 1e3 * r.last_second, timing,
                update);
  }
  std::printf("\n");
  for (const Result& r : results) {
    if (r.mode == Mode::kOnlineVariance) {
      std::printf("%s, %s: mean feedforward gain %.2f (trust std %.2g of each joint's torque "
                  "scale)\n", r.model.c_str(), Name(r.mode), r.mean_gain, trust_fraction);
    }
    if (!r.note.empty()) std::printf("%s, %s: %s\n", r.model.c_str(), Name(r.mode), r.note.c_str());
  }
  const std::string csv = out_dir + "/closed_loop_panda.csv";
  std::ofstream out(csv);
  if (!out) throw std::runtime_error("cannot write " + csv);
  out << "t";
  for (const Result& r : results) {
    const std::string key = std::string(Key(r.mode)) +
                            (r.mode == Mode::kPd ? "" : "_" + (r.model.rfind("rbd", 0) == 0
                                                                    ? std::string("rbd")
                                                                    : std::string("nys")));
    for (int j = 1; j <= kN; ++j) out << ",err_" << key << j;
  }
  out << "\n";
  for (Eigen::Index k = 0; k < plant.reference.num_samples(); k += 10) {
    out << plant.reference.t[k];
    for (const Result& r : results) {
      for (int j = 0; j < kN; ++j) out << "," << r.error(k, j);
    }
    out << "\n";
  }
  std::printf("\nwrote %s (errors every 10 ms)\n", csv.c_str());
  return 0;
}

}  // namespace panda

}  // namespace

int main(int argc, char** argv) {
  std::string out_dir = "closed-loop-out";
  bool threaded = true;
  double seconds = 10.0;
  double trust_std = kDefaultTrustStd;
  std::string robot = "two_link";
  std::vector<std::string> models = {"rbd", "nys"};
  double trust_fraction = 0.1;
  double model_noise = panda::kTorqueNoise;
  CLI::App app("Learned feedforward in a simulated 1 kHz control loop.", "closed_loop");
  app.add_option("--robot", robot, "two_link (k_pol + friction, D = 138) or panda (7 joints)")
      ->check(CLI::IsMember({"two_link", "panda"}))
      ->capture_default_str();
  app.add_option("--models", models, "panda: rbd (rbd+fri, URDF +-30%), nys (Nystrom k_pol+fri)")
      ->delimiter(',')
      ->check(CLI::IsMember({"rbd", "nys"}));
  app.add_option("--trust-fraction", trust_fraction,
                 "panda: predictive std, as a fraction of each joint's torque scale, at which "
                 "the variance-scaled feedforward halves")
      ->capture_default_str();
  app.add_option("out_dir", out_dir, "where closed_loop.csv and closed_loop.svg go")
      ->capture_default_str();
  app.add_flag_callback("--no-threaded", [&threaded]() { threaded = false; },
                        "skip the run with the OnlineLearner thread");
  app.add_option("--seconds", seconds, "simulated seconds, 1..600")->capture_default_str();
  app.add_option("--trust-std", trust_std,
                 "N m: predictive std at which the variance-scaled feedforward halves")
      ->capture_default_str();
  app.add_option("--model-noise", model_noise,
                 "panda: the models' noise std, as a fraction of each joint's torque scale "
                 "(default: the torque sensor's)")
      ->capture_default_str();
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::fprintf(stderr, "closed_loop: %s\nrun 'closed_loop --help' for the flags\n", e.what());
    return 2;
  }
  if (!(seconds >= 1.0 && seconds <= 600.0)) {
    std::fprintf(stderr, "closed_loop: --seconds must be in [1, 600], got %g\n", seconds);
    return 2;
  }
  if (!(trust_std > 0.0)) {
    std::fprintf(stderr, "closed_loop: --trust-std must be > 0, got %g\n", trust_std);
    return 2;
  }
  if (!(trust_fraction > 0.0)) {
    std::fprintf(stderr, "closed_loop: --trust-fraction must be > 0, got %g\n", trust_fraction);
    return 2;
  }
  if (!(model_noise > 0.0)) {
    std::fprintf(stderr, "closed_loop: --model-noise must be > 0, got %g\n", model_noise);
    return 2;
  }
  seconds = std::floor(seconds);
  if (robot == "panda") {
    try {
      std::filesystem::create_directories(out_dir);
      return panda::Main(out_dir, seconds, threaded, trust_fraction, models, model_noise);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "closed_loop: %s\n", e.what());
      return 1;
    }
  }
  try {
    std::filesystem::create_directories(out_dir);
    Setup setup;
    // Reference: a sum of three harmonics of 0.5 Hz (period 2 s), +-1 rad per joint.
    setup.reference = structgp::sim::SumOfSines(kJoints, seconds, kDt, 3, 0.5, 1.0, kReferenceSeed);
    TrainOffline(&setup);
    std::printf(
        "two-link arm, %g s at 1 kHz, reference period 2 s; model: k_pol + friction, "
        "D = %d features, 2 outputs\n",
        seconds, setup.map->dim());

    std::vector<Mode> modes = {Mode::kPd, Mode::kOffline, Mode::kOnline, Mode::kOnlineVariance};
    if (threaded) modes.push_back(Mode::kThreaded);
    std::vector<Run> runs;
    for (const Mode mode : modes)
      runs.push_back(Simulate(mode, setup, mode == Mode::kThreaded, trust_std * trust_std));

    std::printf("\ntracking RMS per second (mrad)\n%-34s", "run");
    for (int sec = 1; sec <= static_cast<int>(seconds); ++sec) std::printf("%7d", sec);
    std::printf("%9s\n", "total");
    for (const Run& r : runs) {
      std::printf("%-34s", Name(r.mode));
      for (double v : r.rms_per_second) std::printf("%7.2f", 1e3 * v);
      std::printf("%9.2f\n", 1e3 * r.rms);
    }
    std::printf("\n");
    for (const Run& r : runs) {
      if (r.mode == Mode::kOnlineVariance) {
        std::printf("%-34s mean feedforward gain per second:", Name(r.mode));
        for (int sec = 0; sec < static_cast<int>(seconds); ++sec) {
          std::printf(" %.2f", r.gain.middleRows(sec * 1000, 1000).mean());
        }
        std::printf(" (trust std %.2g N m)\n", trust_std);
      }
      if (r.compute_p50_us > 0.0) {
        std::printf("%-34s controller time per tick: median %.1f us, max %.1f us\n", Name(r.mode),
                    r.compute_p50_us, r.compute_max_us);
      }
      if (!r.note.empty()) std::printf("%-34s %s\n", "", r.note.c_str());
    }
    const std::string csv = out_dir + "/closed_loop.csv";
    const std::string svg = out_dir + "/closed_loop.svg";
    WriteCsv(csv, setup, runs);
    WriteSvg(svg, runs, seconds);
    std::printf("\nwrote %s and %s\n", csv.c_str(), svg.c_str());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "closed_loop: %s\n", e.what());
    return 1;
  }
  return 0;
}
