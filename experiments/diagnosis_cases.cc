// diagnosis_cases: how far the diagnosis can be trusted, on 6-7 joint arms simulated with KDL
// and on real logs with effects injected into the measured torques (docs/diagnosis.md,
// "Calibration on 6-7 joint arms and real logs").
//
//   diagnosis_cases [--parts=sim,real]
//                   [--robots=puma560,panda] [--cases=none,spring,payload,coulomb,...]
//                   [--models=pol] [--joint=2] [--train-seconds=20] [--test-seconds=5]
//                   [--data-dir=../shared/data] [--datasets=ur10,sarcos] [--real-model=pol+fri]
//                   [--injections=cogging,coulomb,offset,drift] [--sizes=1,3,10]
//                   [--periods=0.2] [--joints=1] [--seeds=1] [--max-train=2500]
//                   [--heldout-rows=1000] [--ml-max-rows=400] [--real-ml-max-rows=1000]
//                   [--rounds=1] [--out=FILE.csv] [--findings-dir=DIR] [--models-dir=DIR]
//                   [--quick] [--check]
//
// Part A, simulated arms (sim::Puma560, sim::Panda). Three logs per case, all on the same
// closed via-point path (sim::ViaPoints, continuous velocity, --vias via points in
// [-1.2, 1.2] rad, 100 Hz), one after the other in time: a slow training log
// (--train-seconds), the fast log that is diagnosed (--test-seconds, 2.5x the training speed)
// and a second fast log, the evaluation log (--test-seconds, 2.0x the training speed: other
// states than the diagnosed log, other noise, later in time). Kernel-form fits (pol at 6-7
// joints) search the evidence on --ml-max-rows evenly spaced rows (the CLI's --ml-max-rows;
// 400 instead of its default 1000, which takes 100 s per fit here). Torques by KDL's recursive
// Newton-Euler, divided per joint by the largest rigid-body torque over the training and
// diagnosed logs (the scale); the hidden torque has the shapes of sim/hidden_effect.h, in units
// of that scale; noise --noise of the scale on every joint.
//
// | case     | hidden (on --joint j unless said)                  | true effects given to the model |
// |----------|----------------------------------------------------|---------------------------------|
// | none     | nothing                                            | none                            |
// | spring   | 0.2 sin(q_j) (pol spans it: nothing missing)       | none                            |
// | payload  | 2 kg, 5 cm along z of the last link, in all logs   | none (pol and rbd span it)      |
// | coulomb  | 0.1 tanh(qd_j / 0.01)                              | coulomb@j                       |
// | viscous  | 0.1 qd_j / max|qd_j|                               | viscous@j                       |
// | stribeck | 0.1 exp(-(qd_j / v)^2) tanh(qd_j / 0.01), v = 0.1 max|qd_j| | stribeck@j:velocity=v  |
// | cogging  | 0.05 sin(2 pi q_1 / 0.3) on joint 1                | cogging@1:period=0.3            |
// | drift    | 0.1 (t / t_end) tanh(qd_j / 0.01), t_end the end of the diagnosed log | drift@j:t0=0;span=t_end |
// | combined | 0.05 each of Coulomb, viscous, Stribeck on every joint | coulomb,viscous,stribeck@k:velocity=v_k |
//
// Per case and model (--models: pol, rbd with the simulated chain as its URDF, chain: rbd on
// the chain identified from the training log, identified again with the effects of each refit
// unless --no-reidentify; rbd shares its
// inertial parameters across joints, so it is given the torques in N m, with the noise and
// hidden torques scaled along, and its RMS is divided by the noise in N m): the model is
// fitted on the training log with the CLI's defaults (FitModel, type-II maximum likelihood),
// Diagnose runs on the diagnosed log with its defaults, the model is refitted on the training log
// with every suggestion's `spec` text added to its effects (ParseEffectList: what a user would
// type) and, separately, with the true effects. Columns: the suggestions, the expected effects,
// found (every expected effect named on its joint; cogging: period within 10%), false alarms
// (suggestions that are not expected), the RMS / noise on the evaluation log (all joints
// pooled) before, after the suggestions and with the true effects, their ratio (done when
// <= 1.2), wall time.
//
// Part B, real logs (--data-dir, see each README): UR10 (train.csv.gz trains, test.csv.gz is
// the held-out part, later in time) and SARCOS (rows 1-3,560 train, 3,561-4,449 held out; the
// file has no time column, so t = 0.1 s x row index, the spacing its README estimates), by
// default sliced to keep a run near 20 minutes on two cores: --max-train evenly spaced rows of
// the training part, the first --heldout-rows rows of the held-out part (contiguous). The
// model --real-model is fitted on the training part with the CLI's defaults and diagnosed on
// the held-out part, as is ("uninjected"); the training part is then refitted with every
// suggestion, and the held-out RMS / noise before and after is reported (pooled, and of each
// suggested joint: lagk is one GP of every joint, so a refit changes the other joints too). Then known effects
// are added to the measured torques of the held-out part on one joint at a time (the --joints
// joints with the widest range of q in that part), at a = size x the joint's noise level
// sigma_j: the uninjected diagnosis's estimate, from the successive differences of the
// residual of the model refitted there (JointFinding::noise_std_estimate; the RMS of the
// differences below when it has none); --noise-from=differences: sqrt(mean(diff(r_j)^2) / 2)
// of the model's own residual on that part, which the signal's jumps inflate (as before):
//   cogging  a sin(2 pi q_j / P + phase), P in --periods;  coulomb  a tanh(qd_j / 0.01);
//   offset   a;                                            drift    a (t - t_begin) / T,
// T the span of the part; the seed (--seeds) draws the sign of a and the cogging phase. Found:
// the effect named on its joint (cogging: period within 10% of P). False alarms: suggestions
// beyond those of the uninjected log and the found one. An effect that the model already
// spans (coulomb and offset under +fri: Effect::spanned_by) is not a candidate of the
// diagnosis on the log alone (--log-only); its rows are marked "spanned" and measure false
// alarms only. With the training data it is, on the log's rows (a change in this log).
//
// Only the fields of Diagnosis that every version has (status, message, suggestions: effect,
// joint, params, spec) are read by name; any other top-level field of its JSON (ToJson) is
// listed in the "other findings" column, so that fields added later are shown, not lost.
// --rounds=K runs the loop as a user would, up to K diagnoses in part A: the model refitted with
// the suggestions is diagnosed again on the same logs and its new suggestions added, until a
// round suggests nothing new; the columns then count every round's suggestions, and "after" is
// the last refit. --findings-dir writes the JSON of every diagnosis. --models-dir keeps the fitted models (a file
// per model label and hash of its training data) and loads them instead of fitting again: a
// rerun with a changed diagnosis skips the fits that did not change. --refit-from=model (the
// default) starts a lagk refit with effects added from the model they are added to, at its
// sigma, as RunDiagnosisLoop does; --refit-from=scratch searches the whole sigma grid, as the
// tables of earlier commits did. --quick: a CI-size run (PUMA 560, none and
// coulomb, short logs, rbd when --models is at its default; 300 rows of each UR10 part, one
// cogging injection at 10x the noise). --check: exit 3 unless
// every diagnosis ran (status ok) and every number is finite.

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <random>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "experiment_program.h"
#include "structgp/core/row_subset.h"
#include "structgp/diagnose/diagnosis.h"
#include "structgp/feature/effects.h"
#include "structgp/fit/fit_model.h"
#include "structgp/internal/text.h"
#include "structgp/io/csv.h"
#include "structgp/io/model_file.h"
#include "structgp/io/robot_data.h"
#include "structgp/model/model_spec.h"
#include "structgp/fit/chain_identification.h"
#include "structgp/rigid_body/rigid_body_chain.h"
#include "structgp/sim/dataset.h"
#include "structgp/sim/robot.h"
#include "structgp/sim/trajectory.h"
#include "structgp/sim/urdf.h"
#include "timing.h"

namespace structgp {
namespace {

using internal::Format;

constexpr double kTwoPi = 6.283185307179586;
constexpr double kSignWidth = 0.01;  // rad/s, the tanh of Coulomb friction (the effects' default)
constexpr double kDt = 0.01;         // s
constexpr double kQRange = 1.2;      // rad
constexpr double kPayload = 2.0;     // kg
constexpr double kSarcosDt = 0.1;    // s per row (reconstructed, see the README)
constexpr double kDoneRatio = 1.2;   // after / true on the evaluation log
constexpr double kPeriodTolerance = 0.1;

struct Flags {
  std::vector<std::string> parts{"sim", "real"};
  // Part A.
  std::vector<std::string> robots{"puma560", "panda"};
  std::vector<std::string> cases{"none",     "spring",   "payload", "coulomb", "viscous",
                                 "stribeck", "cogging",  "drift",   "combined"};
  std::vector<std::string> models{"pol"};
  int joint = 2;
  double train_seconds = 20.0;
  double test_seconds = 5.0;
  int vias = 8;
  double noise = 0.01;
  double fast_speed = 2.5;
  double eval_speed = 2.0;
  // Rows of the evidence search of kernel-form fits (the CLI's --ml-max-rows, default 1000):
  // O(m^3) per evaluation, and part A fits about 40 models.
  int ml_max_rows = 400;
  int rounds = 1;
  // Part B.
  std::string data_dir = "../shared/data";
  std::vector<std::string> datasets{"ur10", "sarcos"};
  std::string real_model = "pol+fri";
  std::vector<std::string> injections{"cogging", "coulomb", "offset", "drift"};
  std::vector<double> sizes{1.0, 3.0, 10.0};
  std::vector<double> periods{0.2};
  int joints = 1;
  int seeds = 1;
  // A fit of pol+fri on all 9,879 UR10 rows takes 7 minutes here, a diagnosis of the whole
  // held-out part 2 minutes: by default 2,500 evenly spaced training rows and the first 1,000
  // held-out rows (8 s of UR10; all 889 of SARCOS).
  int max_train = 2500;     // evenly spaced training rows (0: all)
  int heldout_rows = 1000;  // the first rows of the held-out part only (0: all)
  int real_ml_max_rows = 1000;  // the CLI's default
  // The noise level the injections are sized by: "diagnosis", the uninjected diagnosis's own
  // estimate (JointFinding::noise_std_estimate: the median absolute successive difference of
  // the residual, robust to the jumps of the signal); "differences", the RMS of the successive
  // differences (before commit 'diagnosis_cases: injections sized by the diagnosis's noise').
  std::string noise_from = "diagnosis";
  // Both.
  std::string out, findings_dir;
  bool quick = false;
  bool check = false;
  bool with_training = true;
  // chain: refits with effects on the chain identified again with them (else on the first).
  bool reidentify = true;
  bool chain_with_log = false;
};

// ---- reading a diagnosis --------------------------------------------------------------------

// The top-level fields of the diagnosis JSON that this program knows; the others are listed.
const std::set<std::string>& KnownFields() {
  static const std::set<std::string> known{"status",   "message", "joints",   "suggestions",
                                           "num_samples", "model", "features", "noise_std"};
  return known;
}

// "name: value" for every field of ToJson(d) not in KnownFields (values shortened).
std::string OtherFindings(const Diagnosis& d) {
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(ToJson(d));
  } catch (const std::exception& e) {
    return std::string("(findings JSON unreadable: ") + e.what() + ")";
  }
  std::string out;
  if (!j.is_object()) return out;
  for (auto it = j.begin(); it != j.end(); ++it) {
    if (KnownFields().count(it.key()) != 0) continue;
    std::string value = it.value().dump();
    if (value.size() > 60) value = value.substr(0, 57) + "...";
    out += (out.empty() ? "" : "; ") + it.key() + ": " + value;
  }
  return out;
}

// The suggestions as effect@joint:key=value with values to 3 digits (their spec text has every
// digit; it is what the refits read).
std::string SuggestionList(const Diagnosis& d) {
  std::string out;
  for (const Suggestion& s : d.suggestions) {
    std::string item = s.effect + "@" + std::to_string(s.joint);
    char sep = ':';
    for (const auto& [key, value] : s.params) {
      item += sep + key + "=" + Format("%.3g", value);
      sep = ';';
    }
    out += (out.empty() ? "" : ", ") + item;
  }
  return out.empty() ? "nothing" : out;
}

void WriteFindings(const Flags& f, const std::string& name, const Diagnosis& d) {
  if (f.findings_dir.empty()) return;
  std::filesystem::create_directories(f.findings_dir);
  std::ofstream(f.findings_dir + "/" + name + ".json") << ToJson(d) << "\n";
}

// An expected effect: name, joint (1-based), and for cogging the period (0: any).
struct Expected {
  std::string effect;
  int joint = 0;
  double period = 0.0;
};

bool Matches(const Suggestion& s, const Expected& e) {
  if (s.effect != e.effect || s.joint != e.joint) return false;
  if (e.period > 0.0) {
    const auto it = s.params.find("period");
    return it != s.params.end() && std::abs(it->second / e.period - 1.0) <= kPeriodTolerance;
  }
  return true;
}

// True when the model's spec already spans the effect (it is then not a candidate).
bool SpannedBy(const ModelSpec& spec, const std::string& effect) {
  const std::vector<std::string> blocks = MakeEffectPrototype(effect)->spanned_by();
  return spec.friction && std::find(blocks.begin(), blocks.end(), "friction") != blocks.end();
}

// ---- models ---------------------------------------------------------------------------------

struct Fit {
  std::unique_ptr<RobotModel> model;
  std::string error;  // empty when fitted
  double seconds = 0.0;
};

// --models-dir: fitted models are saved there and loaded instead of fitted again when the same
// model is fitted on the same data with the same evidence rows (the file name holds the label,
// cut to 60 characters, and a hash of the whole label and those). Models with a URDF chain are always fitted.
std::string g_models_dir;
bool g_diagnosis_chain = true;  // DiagnosisOptions::reidentify_chain
// --no-held-out-route: DiagnosisOptions::held_out_may_replace_evidence off.
bool g_held_out_route = true;
// --autocorrelation: DiagnosisOptions::autocorrelation.
DiagnosisOptions::Autocorrelation g_autocorrelation = DiagnosisOptions().autocorrelation;
// --refit-from: "model" (a lagk refit with effects added searches from the model it adds them
// to, at its sigma, as RunDiagnosisLoop does) or "scratch" (the whole sigma grid, as a first
// fit).
bool g_refit_from_model = true;
// --threads: FitOptions::num_threads and the batch's of every fit of this program.
int g_threads = 1;
// The identification of model "chain" (--chain-starts, --chain-rounds, --chain-seed).
ChainIdentificationOptions g_chain;

std::string FitKey(const ModelSpec& spec, const Matrix& X, const Matrix& Y, const Vector& t,
                   int max_evidence_rows, const std::string& extra) {
  std::uint64_t h = 1469598103934665603ULL;  // FNV-1a over the bytes
  auto mix = [&h](const void* data, std::size_t bytes) {
    const auto* p = static_cast<const unsigned char*>(data);
    for (std::size_t i = 0; i < bytes; ++i) h = (h ^ p[i]) * 1099511628211ULL;
  };
  for (const Matrix* A : {&X, &Y}) {
    const Eigen::Index rows = A->rows(), cols = A->cols();
    mix(&rows, sizeof rows);
    mix(&cols, sizeof cols);
    mix(A->data(), sizeof(double) * static_cast<std::size_t>(A->size()));
  }
  mix(t.data(), sizeof(double) * static_cast<std::size_t>(t.size()));
  mix(&max_evidence_rows, sizeof max_evidence_rows);
  mix(extra.data(), extra.size());
  std::string label = ModelLabel(spec);
  mix(label.data(), label.size());
  if (label.size() > 60) label.resize(60);  // the hash holds the whole label
  for (char& c : label) {
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '.' && c != '-') c = '_';
  }
  return label + "_" + Format("%016llx", static_cast<unsigned long long>(h));
}

// from: the model a refit adds effects to (--refit-from), or null.
Fit FitSpec(const ModelSpec& spec, const Matrix& X, const Matrix& Y, const Vector& t,
            std::shared_ptr<const RigidBodyChain> chain, int max_evidence_rows,
            const RobotModel* from = nullptr) {
  Fit fit;
  const auto start = std::chrono::steady_clock::now();
  FitOptions options;
  std::string extra;  // the start, in the cache key
  if (g_refit_from_model && from != nullptr && StartFromModel(*from, &options)) {
    const EulerLagrangeGPHyperparameters& h = *options.euler_lagrange.start;
    extra = Format("from sigma %.17g", h.sigma);
    for (const Vector* v : {&h.part_weights, &h.noise_std}) {
      for (Eigen::Index k = 0; k < v->size(); ++k) extra += Format(" %.17g", (*v)[k]);
    }
  }
  const std::string cached =
      g_models_dir.empty() || chain
          ? std::string()
          : g_models_dir + "/" + FitKey(spec, X, Y, t, max_evidence_rows, extra) + ".json";
  if (!cached.empty() && std::filesystem::exists(cached)) {
    try {
      fit.model = std::make_unique<RobotModel>(LoadModel(cached));
      std::fprintf(stderr, "    fit %s: loaded %s\n", ModelLabel(spec).c_str(), cached.c_str());
      fit.seconds = Seconds(start);
      return fit;
    } catch (const std::exception& e) {
      std::fprintf(stderr, "    %s: %s (fitting again)\n", cached.c_str(), e.what());
    }
  }
  options.max_evidence_rows = max_evidence_rows;
  options.model.rigid_body = std::move(chain);
  options.num_threads = g_threads;
  options.model.batch.num_threads = g_threads;
  try {
    FittedModel fitted = FitModel(spec, X, Y, t, options);
    std::fprintf(stderr, "    fit %s: %s; %d tightenings, %d evaluations, %d evidence rows\n",
                 ModelLabel(spec).c_str(), fitted.summary.BriefReport().c_str(),
                 fitted.summary.prior_tightenings, fitted.summary.num_evaluations,
                 fitted.summary.hyperparameter_rows);
    if (!fitted.summary.IsUsable()) {
      fit.error = "fit failed: " + fitted.summary.message;
    } else {
      fit.model = std::make_unique<RobotModel>(std::move(fitted.model));
      if (!cached.empty()) {
        std::filesystem::create_directories(g_models_dir);
        SaveModel(cached, *fit.model);
      }
    }
  } catch (const std::exception& e) {
    fit.error = std::string("fit failed: ") + e.what();
  }
  fit.seconds = Seconds(start);
  return fit;
}

Matrix PredictOn(const RobotModel& model, const Matrix& X, const Vector& t) {
  Matrix mean;
  model.PredictRows(ModelInputs(model, X, t), &mean);
  return mean;
}

// RMS of each column of A - B.
Vector ColumnRms(const Matrix& A, const Matrix& B) {
  return ((A - B).colwise().squaredNorm() / static_cast<double>(A.rows())).cwiseSqrt().transpose();
}

// The diagnosis of a fitted model on (X, Y, t), with its wall time; a thrown error becomes a
// numerical-failure status with the message.
// With train_X (and train_Y, train_t), the model's training data go to the diagnosis too.
Diagnosis RunDiagnosis(const RobotModel& model, const Matrix& X, const Matrix& Y, const Vector& t,
                       double* seconds, const Matrix* train_X = nullptr,
                       const Matrix* train_Y = nullptr, const Vector* train_t = nullptr) {
  const auto start = std::chrono::steady_clock::now();
  Diagnosis d;
  try {
    DiagnosisOptions options;
    options.held_out_may_replace_evidence = g_held_out_route;
    options.autocorrelation = g_autocorrelation;
    options.reidentify_chain = g_diagnosis_chain;
    options.chain.num_threads = g_threads;
    if (train_X != nullptr) {
      options.training_inputs = ModelInputs(model, *train_X, *train_t);
      options.training_targets = *train_Y;
      options.training_times = *train_t;
    }
    d = Diagnose(model, ModelInputs(model, X, t), Y, t, options);
  } catch (const std::exception& e) {
    d.status = DiagnosisStatus::kNumericalFailure;
    d.message = std::string("threw: ") + e.what();
  }
  *seconds = Seconds(start);
  return d;
}

// ---- part A: simulated arms -----------------------------------------------------------------

sim::Robot MakeRobot(const std::string& name) {
  try {
    return sim::RobotByName(name);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string("--robots: ") + e.what());
  }
}


// One hidden term: kind on joint (1-based) with magnitude (units of the joint's scale).
struct Hidden {
  std::string kind;  // coulomb, viscous, stribeck, cogging, drift, spring
  int joint = 1;
  double magnitude = 0.0;
  double period = 0.3;  // cogging
};

struct SimCase {
  std::vector<Hidden> hidden;
  bool payload = false;
};

SimCase MakeSimCase(const std::string& name, int N, int joint) {
  SimCase c;
  if (name == "none") return c;
  if (name == "payload") {
    c.payload = true;
    return c;
  }
  if (name == "spring") {
    c.hidden.push_back({"spring", joint, 0.2});
  } else if (name == "coulomb" || name == "viscous" || name == "stribeck" || name == "drift") {
    c.hidden.push_back({name, joint, 0.1});
  } else if (name == "cogging") {
    c.hidden.push_back({"cogging", 1, 0.05, 0.3});
  } else if (name == "combined") {
    for (int j = 1; j <= N; ++j) {
      for (const char* kind : {"coulomb", "viscous", "stribeck"}) c.hidden.push_back({kind, j, 0.05});
    }
  } else {
    throw std::invalid_argument("--cases: unknown case '" + name +
                                "' (expected none, spring, payload, coulomb, viscous, stribeck, "
                                "cogging, drift, combined)");
  }
  return c;
}

struct SimLogs {
  sim::Dataset train, diag, eval;
  Vector qd_max;     // per joint, over the training and diagnosed logs
  double t_end = 0;  // end of the diagnosed log
  std::vector<EffectSpec> truth;
  std::vector<Expected> expected;
  std::shared_ptr<const RigidBodyChain> urdf;  // the arm without the payload
};

SimLogs MakeSimLogs(const sim::Robot& arm, const SimCase& c, const Flags& f, std::uint64_t seed) {
  const int N = arm.num_joints();
  SimLogs logs;
  logs.urdf = std::make_shared<const RigidBodyChain>(sim::ToRigidBodyChain(arm));
  const sim::Robot robot =
      c.payload ? sim::Robot::FromRigidBodyChain(logs.urdf->WithPayload(kPayload, {0, 0, 0.05}))
                : arm;
  const double slow_len = f.train_seconds;
  const sim::Trajectory slow = sim::ViaPoints(N, slow_len, kDt, f.vias, 1.0, kQRange, seed,
                                              sim::ViaVelocity::kContinuous);
  auto fast = [&](double speed, double t_offset) {
    sim::Trajectory tr = sim::ViaPoints(N, f.test_seconds, kDt, f.vias,
                                        speed * f.test_seconds / slow_len, kQRange, seed,
                                        sim::ViaVelocity::kContinuous);
    tr.t.array() += t_offset;
    return tr;
  };
  const sim::Trajectory diag = fast(f.fast_speed, slow_len);
  const sim::Trajectory eval = fast(f.eval_speed, slow_len + f.test_seconds);
  logs.train = sim::Simulate(robot, slow);
  logs.diag = sim::Simulate(robot, diag);
  logs.eval = sim::Simulate(robot, eval);
  logs.t_end = slow_len + f.test_seconds;
  Vector scale(N);
  logs.qd_max.resize(N);
  for (int j = 0; j < N; ++j) {
    scale[j] = std::max(logs.train.Y.col(j).cwiseAbs().maxCoeff(),
                        logs.diag.Y.col(j).cwiseAbs().maxCoeff());
    if (!(scale[j] > 0)) scale[j] = 1.0;
    logs.qd_max[j] = std::max({logs.train.X.col(N + j).cwiseAbs().maxCoeff(),
                               logs.diag.X.col(N + j).cwiseAbs().maxCoeff(), 1e-9});
  }
  auto shape = [&](const Hidden& h, double q, double qd, double t) {
    const double vmax = logs.qd_max[h.joint - 1];
    if (h.kind == "coulomb") return std::tanh(qd / kSignWidth);
    if (h.kind == "viscous") return qd / vmax;
    if (h.kind == "stribeck") {
      const double r = qd / (0.1 * vmax);
      return std::exp(-r * r) * std::tanh(qd / kSignWidth);
    }
    if (h.kind == "cogging") return std::sin(kTwoPi * q / h.period);
    if (h.kind == "drift") return t / logs.t_end * std::tanh(qd / kSignWidth);
    if (h.kind == "spring") return std::sin(q);
    throw std::logic_error("unknown hidden term " + h.kind);
  };
  std::uint64_t noise_seed = seed * 7919;
  auto finish = [&](sim::Dataset* d) {
    std::mt19937_64 rng(++noise_seed);
    std::normal_distribution<double> normal;
    for (int j = 0; j < N; ++j) d->Y.col(j) /= scale[j];
    for (const Hidden& h : c.hidden) {
      const int j = h.joint - 1;
      for (Eigen::Index i = 0; i < d->X.rows(); ++i) {
        d->Y(i, j) += h.magnitude * shape(h, d->X(i, j), d->X(i, N + j), d->t[i]);
      }
    }
    for (Eigen::Index i = 0; i < d->Y.rows(); ++i) {
      for (int j = 0; j < N; ++j) d->Y(i, j) += f.noise * normal(rng);
    }
    d->torque_scale = scale;
  };
  finish(&logs.train);
  finish(&logs.diag);
  finish(&logs.eval);
  for (const Hidden& h : c.hidden) {
    if (h.kind == "spring") continue;  // inside pol's space: nothing to add
    EffectSpec e{h.kind, {h.joint}, {}};
    if (h.kind == "stribeck") e.params["velocity"] = 0.1 * logs.qd_max[h.joint - 1];
    if (h.kind == "cogging") e.params["period"] = h.period;
    if (h.kind == "drift") e.params = {{"t0", 0.0}, {"span", logs.t_end}};
    logs.truth.push_back(e);
    logs.expected.push_back({h.kind, h.joint, h.kind == "cogging" ? h.period : 0.0});
  }
  return logs;
}

struct SimRow {
  std::string robot, kase, model, suggestions, expected, found, other, note;
  int false_alarms = 0;
  bool diagnosed = false;
  Vector before, after, truth;  // RMS / noise per joint on the evaluation log
  double pooled_before = NAN, pooled_after = NAN, pooled_truth = NAN;
  double seconds = 0.0;
};

double Pooled(const Vector& per_joint) {
  return per_joint.size() ? std::sqrt(per_joint.squaredNorm() / per_joint.size()) : NAN;
}

std::string ExpectedText(const std::vector<Expected>& expected) {
  if (expected.empty()) return "nothing";
  std::map<std::string, std::vector<int>> by_effect;
  std::vector<std::string> order;
  for (const Expected& e : expected) {
    if (by_effect.count(e.effect) == 0) order.push_back(e.effect);
    by_effect[e.effect].push_back(e.joint);
  }
  std::string out;
  for (const std::string& name : order) {
    std::string joints;
    for (int j : by_effect[name]) joints += (joints.empty() ? "" : "/") + std::to_string(j);
    out += (out.empty() ? "" : ", ") + name + "@" + joints;
  }
  return out;
}

SimRow RunSimCase(const std::string& robot_name, const std::string& case_name,
                  const std::string& model_name, const SimLogs& scaled, const Flags& f) {
  const auto start = std::chrono::steady_clock::now();
  // "chain": rbd on the chain `structgp identify` finds from the training log (no URDF).
  const bool identified = model_name == "chain";
  const ModelSpec spec = ParseModelSpec(identified ? "rbd" : model_name);
  const bool rigid_body = spec.base == BaseModel::kRbd || spec.rigid_body_features;
  // Models with rigid-body parameters share them across joints, and the Lagrangian models
  // explain every joint by one M(q) and V(q): torques scaled per joint are not in their class,
  // so they get the torques in N m (noise and hidden effects scale along).
  const bool one_lagrangian =
      rigid_body || spec.base == BaseModel::kLag || spec.base == BaseModel::kLagk;
  SimLogs logs = scaled;
  const int N = static_cast<int>(scaled.train.Y.cols());
  Vector noise = Vector::Constant(N, f.noise);
  if (one_lagrangian) {
    const Vector& scale = scaled.train.torque_scale;
    for (sim::Dataset* d : {&logs.train, &logs.diag, &logs.eval}) {
      d->Y = d->Y * scale.asDiagonal();
      d->torque_scale.setOnes();
    }
    noise = f.noise * scale;
  }
  SimRow row;
  row.robot = robot_name;
  row.kase = case_name;
  row.model = model_name;
  row.expected = ExpectedText(logs.expected);
  // The chain identified from the training log with the effects of a model (the loop a user
  // runs without a URDF: identify, fit rbd, diagnose, identify again with the suggestions).
  auto identify = [&](const std::vector<EffectSpec>& effects) {
    const auto begin = std::chrono::steady_clock::now();
    ChainIdentificationOptions o = g_chain;
    o.num_threads = g_threads;
    o.effects = effects;
    // --chain-data=train+log: the diagnosed log's rows beside the training log's.
    const bool both = f.chain_with_log;
    Matrix X = logs.train.X, Y = logs.train.Y;
    Vector t = logs.train.t;
    if (both) {
      X.conservativeResize(X.rows() + logs.diag.X.rows(), Eigen::NoChange);
      X.bottomRows(logs.diag.X.rows()) = logs.diag.X;
      Y.conservativeResize(Y.rows() + logs.diag.Y.rows(), Eigen::NoChange);
      Y.bottomRows(logs.diag.Y.rows()) = logs.diag.Y;
      t.conservativeResize(t.size() + logs.diag.t.size());
      t.tail(logs.diag.t.size()) = logs.diag.t;
    }
    const ChainIdentificationSummary id = IdentifyChain(X, t, Y, o);
    std::fprintf(stderr,
                 "%s %s chain%s%s: identified in %.0f s, %d round%s, %d of %d kept starts at the "
                 "best cost %.3g\n",
                 robot_name.c_str(), case_name.c_str(), effects.empty() ? "" : " with ",
                 ToString(effects).c_str(), Seconds(begin), id.rounds, id.rounds > 1 ? "s" : "",
                 id.starts_at_best, static_cast<int>(id.start_costs.size()),
                 *std::min_element(id.start_costs.begin(), id.start_costs.end()));
    return std::make_shared<const RigidBodyChain>(
        RigidBodyChain::FromUrdfString(id.urdf, {}, "identified.urdf"));
  };
  std::shared_ptr<const RigidBodyChain> chain;
  if (identified) {
    chain = identify({});
  } else if (rigid_body) {
    chain = logs.urdf;
  }
  const Fit base = FitSpec(spec, logs.train.X, logs.train.Y, logs.train.t, chain, f.ml_max_rows);
  if (!base.model) {
    row.note = base.error;
    row.seconds = Seconds(start);
    return row;
  }
  double diag_seconds = 0;
  const bool with_training = f.with_training;
  auto diagnose = [&](const RobotModel& model, const std::string& name) {
    const Diagnosis d = RunDiagnosis(model, logs.diag.X, logs.diag.Y, logs.diag.t, &diag_seconds,
                                     with_training ? &logs.train.X : nullptr, &logs.train.Y,
                                     &logs.train.t);
    std::fprintf(stderr, "%s %s %s: diagnosis %.0f s: %s\n", robot_name.c_str(),
                 case_name.c_str(), name.c_str(), diag_seconds, SuggestionList(d).c_str());
    if (d.chain) std::fprintf(stderr, "  %s\n", d.chain->message.c_str());
    return d;
  };
  std::fprintf(stderr, "%s %s %s: fit %.0f s\n", robot_name.c_str(), case_name.c_str(),
               model_name.c_str(), base.seconds);
  const Diagnosis d = diagnose(*base.model, model_name);
  WriteFindings(f, "sim_" + robot_name + "_" + case_name + "_" + model_name, d);
  row.diagnosed = d.status == DiagnosisStatus::kOk;
  if (!row.diagnosed) row.note = std::string(ToString(d.status)) + ": " + d.message;
  row.suggestions = SuggestionList(d);
  row.other = OtherFindings(d);
  row.before = ColumnRms(PredictOn(*base.model, logs.eval.X, logs.eval.t), logs.eval.Y)
                   .cwiseQuotient(noise);
  // Refit with the suggestions (their spec text, as a user would add it) and with the truth;
  // a model with the same text as one already fitted (the suggestions are the true effects)
  // is not fitted again.
  struct Refit {
    Vector rms;  // RMS / noise per joint on the evaluation log
    std::string error;
    std::shared_ptr<const RobotModel> model;
  };
  std::map<std::string, Refit> fitted;  // by label
  fitted[ModelLabel(spec)] = {row.before, "", nullptr};
  // from: the model the effects are added to (--refit-from).
  auto evaluate = [&](const ModelSpec& s, const RobotModel* from) {
    const std::string label = ModelLabel(s);
    auto it = fitted.find(label);
    if (it != fitted.end()) return it->second;
    // Without a URDF the chain is identified again with the effects (--reidentify).
    const std::shared_ptr<const RigidBodyChain> refit_chain =
        identified && f.reidentify && !s.effects.empty() ? identify(s.effects) : chain;
    Fit fit = FitSpec(s, logs.train.X, logs.train.Y, logs.train.t, refit_chain, f.ml_max_rows, from);
    Refit result{Vector(), fit.error, std::move(fit.model)};
    if (result.model) {
      result.rms = ColumnRms(PredictOn(*result.model, logs.eval.X, logs.eval.t), logs.eval.Y)
                       .cwiseQuotient(noise);
    }
    std::fprintf(stderr, "  %s %s: refit %s in %.0f s\n", robot_name.c_str(), case_name.c_str(),
                 label.c_str(), fit.seconds);
    return fitted[label] = result;
  };
  // The loop (--rounds): the model refitted with the suggestions is diagnosed again and its
  // new suggestions added, until a round suggests nothing new.
  std::vector<Suggestion> suggestions = d.suggestions;
  ModelSpec suggested = spec;
  std::string failures;
  auto add = [&](const std::vector<Suggestion>& list) {
    int added = 0;
    try {
      for (const Suggestion& s : list) {
        for (const EffectSpec& e : ParseEffectList(s.spec)) {
          suggested.effects.push_back(e);
          ++added;
        }
      }
    } catch (const std::invalid_argument& e) {
      failures += std::string("a suggestion does not parse: ") + e.what() + "; ";
      return -1;
    }
    return added;
  };
  int added = add(d.suggestions);
  if (added == 0) row.after = row.before;
  std::shared_ptr<const RobotModel> current;  // the model of the round (null: the base)
  for (int round = 1; added > 0; ++round) {
    const Refit after = evaluate(suggested, current ? current.get() : base.model.get());
    current = after.model;
    row.after = after.rms;
    if (!after.error.empty()) failures += "with the suggestions: " + after.error + "; ";
    if (round >= f.rounds || !after.model) break;
    const std::string name = ModelLabel(suggested);
    const Diagnosis next = diagnose(*after.model, name);
    WriteFindings(f, Format("sim_%s_%s_%s_round%d", robot_name.c_str(), case_name.c_str(),
                            model_name.c_str(), round + 1),
                  next);
    if (next.status != DiagnosisStatus::kOk) {
      failures += Format("round %d: %s: %s; ", round + 1, ToString(next.status),
                         next.message.c_str());
      break;
    }
    row.suggestions += Format("; round %d: ", round + 1) + SuggestionList(next);
    suggestions.insert(suggestions.end(), next.suggestions.begin(), next.suggestions.end());
    added = add(next.suggestions);
  }
  int found = 0;
  for (const Expected& e : logs.expected) {
    for (const Suggestion& s : suggestions) {
      if (Matches(s, e)) {
        ++found;
        break;
      }
    }
  }
  for (const Suggestion& s : suggestions) {
    bool expected = false;
    for (const Expected& e : logs.expected) expected = expected || Matches(s, e);
    row.false_alarms += expected ? 0 : 1;
  }
  if (logs.expected.empty()) {
    row.found = "—";
  } else if (logs.expected.size() == 1) {
    row.found = found == 1 ? "yes" : "no";
  } else {
    row.found = Format("%d/%d", found, static_cast<int>(logs.expected.size()));
  }
  ModelSpec true_spec = spec;
  for (const EffectSpec& e : logs.truth) true_spec.effects.push_back(e);
  const Refit truth = evaluate(true_spec, base.model.get());
  row.truth = truth.rms;
  if (!truth.error.empty()) failures += "with the true effects: " + truth.error + "; ";
  row.pooled_before = Pooled(row.before);
  row.pooled_after = Pooled(row.after);
  row.pooled_truth = Pooled(row.truth);
  if (!failures.empty()) row.note += failures;
  row.seconds = Seconds(start);
  return row;
}

std::string Num(double v) { return std::isfinite(v) ? Format("%.3g", v) : "—"; }

std::vector<SimRow> RunSim(const Flags& f) {
  std::vector<SimRow> rows;
  std::printf("### Part A: simulated arms (slow training log, diagnosed fast log, evaluation on a "
              "second fast log)\n\n"
              "| case | robot | model | suggestions | expected | found | false alarms | eval "
              "RMS/noise before | after suggestions | with true effects | after/true | done | "
              "wall s | other findings |\n"
              "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  std::fflush(stdout);
  for (const std::string& robot_name : f.robots) {
    const sim::Robot robot = MakeRobot(robot_name);
    const int N = robot.num_joints();
    if (f.joint < 1 || f.joint > N) {
      throw std::invalid_argument("--joint: expected 1.." + std::to_string(N) + " for " +
                                  robot_name + ", got " + std::to_string(f.joint));
    }
    for (const std::string& case_name : f.cases) {
      const SimCase c = MakeSimCase(case_name, N, f.joint);
      const SimLogs logs = MakeSimLogs(robot, c, f, 1);
      for (const std::string& model : f.models) {
        SimRow r = RunSimCase(robot_name, case_name, model, logs, f);
        const double ratio = r.pooled_after / r.pooled_truth;
        std::printf("| %s | %s | %s | %s | %s | %s | %d | %s | %s | %s | %s | %s | %.0f | %s |\n",
                    r.kase.c_str(), r.robot.c_str(), r.model.c_str(),
                    (r.suggestions + (r.note.empty() ? "" : " (" + r.note + ")")).c_str(),
                    r.expected.c_str(), r.found.c_str(), r.false_alarms,
                    Num(r.pooled_before).c_str(), Num(r.pooled_after).c_str(),
                    Num(r.pooled_truth).c_str(), Num(ratio).c_str(),
                    std::isfinite(ratio) ? (ratio <= kDoneRatio ? "yes" : "no") : "—", r.seconds,
                    r.other.c_str());
        std::fflush(stdout);
        rows.push_back(std::move(r));
      }
    }
  }
  int effect_cases = 0, found = 0, done = 0, clean_cases = 0, silent = 0;
  for (const SimRow& r : rows) {
    if (r.expected == "nothing") {
      ++clean_cases;
      silent += r.suggestions == "nothing" ? 1 : 0;
    } else {
      ++effect_cases;
      found += r.found == "yes" || (r.found.find('/') != std::string::npos &&
                                    r.found.substr(0, r.found.find('/')) ==
                                        r.found.substr(r.found.find('/') + 1))
                   ? 1
                   : 0;
    }
    const double ratio = r.pooled_after / r.pooled_truth;
    done += std::isfinite(ratio) && ratio <= kDoneRatio ? 1 : 0;
  }
  std::printf("\nMissing effect named on its joint: %d of %d cases; no suggestion where nothing "
              "is missing: %d of %d; after/true <= %.1f: %d of %d.\n",
              found, effect_cases, silent, clean_cases, kDoneRatio, done,
              static_cast<int>(rows.size()));
  return rows;
}

// ---- part B: real logs ----------------------------------------------------------------------

struct RealLog {
  std::string name, description;
  RobotData train, held;
};

std::vector<RealLog> LoadRealLogs(const Flags& f) {
  std::vector<RealLog> logs;
  for (const std::string& name : f.datasets) {
    RealLog log;
    log.name = name;
    if (name == "ur10") {
      const std::string dir = f.data_dir + "/ur10-picknplace";
      if (!std::filesystem::exists(dir + "/train.csv.gz")) continue;
      log.train = ReadRobotCsv(dir + "/train.csv.gz");
      log.held = ReadRobotCsv(dir + "/test.csv.gz");
      log.description = "UR10: train.csv.gz trains, test.csv.gz (later in time) is diagnosed";
    } else if (name == "sarcos") {
      const std::string path = f.data_dir + "/sarcos/sarcos_inv_test.csv.gz";
      if (!std::filesystem::exists(path)) continue;
      RobotData all = ReadRobotCsv(path);
      all.t = Vector::LinSpaced(all.size(), 0.0, kSarcosDt * (all.size() - 1));
      const int train_rows = std::min(3560, all.size() - 1);
      log.train = all.Rows(0, train_rows);
      log.held = all.Rows(train_rows, all.size() - train_rows);
      log.description = "SARCOS: rows 1-3,560 train, 3,561-4,449 diagnosed (t = 0.1 s x row)";
    } else {
      throw std::invalid_argument("--datasets: unknown data set '" + name + "' (ur10, sarcos)");
    }
    if (f.max_train > 0 && f.max_train < log.train.size()) {
      const std::vector<int> rows = EvenlySpacedRows(log.train.size(), f.max_train);
      RobotData t = log.train;
      t.X = SelectRows(log.train.X, rows);
      t.Y = SelectRows(log.train.Y, rows);
      t.t = log.train.has_time() ? Vector(SelectRows(log.train.t, rows)) : Vector();
      t.line.resize(0);
      log.train = t;
    }
    if (f.heldout_rows > 0 && f.heldout_rows < log.held.size()) {
      log.held = log.held.Rows(0, f.heldout_rows);
    }
    logs.push_back(std::move(log));
  }
  return logs;
}

// Noise level per joint from successive differences of the residual r (m x N).
Vector DifferenceNoise(const Matrix& r) {
  const Eigen::Index m = r.rows();
  const Matrix diff = r.bottomRows(m - 1) - r.topRows(m - 1);
  return (diff.colwise().squaredNorm() / (2.0 * static_cast<double>(m - 1))).cwiseSqrt().transpose();
}

struct InjectionRow {
  std::string log, effect;
  double size = 0, period = 0;
  int joint = 0, seed = 0;
  bool spanned = false, found = false, diagnosed = false;
  bool in_baseline = false;  // the uninjected log already had this effect on this joint
  int false_alarms = 0;
  std::string suggestions, other;
  double seconds = 0;
};

struct BaselineRow {
  std::string log, model, suggestions, other, note;
  Vector noise;
  double fit_seconds = 0, seconds = 0;
  bool diagnosed = false;
  // The training part refitted with every suggestion: held-out RMS / noise (pooled), and of
  // each suggested joint ("joint 2: 12.6 -> 11.6").
  double before = NAN, after = NAN;
  std::string suggested_joints;
};

struct RealResult {
  std::vector<BaselineRow> baselines;
  std::vector<InjectionRow> injections;
};

std::string Key(const Suggestion& s) { return s.effect + "@" + std::to_string(s.joint); }

RealResult RunReal(const Flags& f) {
  RealResult result;
  const std::vector<RealLog> logs = LoadRealLogs(f);
  if (logs.empty()) {
    std::printf("\n(no real logs under %s: part B skipped)\n", f.data_dir.c_str());
    return result;
  }
  const ModelSpec spec = ParseModelSpec(f.real_model);
  for (const RealLog& log : logs) {
    const int N = log.train.num_joints;
    BaselineRow base;
    base.log = log.name;
    base.model = ToString(spec);
    const Fit fit = FitSpec(spec, log.train.X, log.train.Y, log.train.t, nullptr, f.real_ml_max_rows);
    base.fit_seconds = fit.seconds;
    if (!fit.model) {
      base.note = fit.error;
      result.baselines.push_back(base);
      continue;
    }
    const Matrix X = log.held.X, Y = log.held.Y;
    const Vector t = log.held.t;
    const Matrix prediction = PredictOn(*fit.model, X, t);
    base.noise = DifferenceNoise(Y - prediction);
    const Matrix* train_X = f.with_training ? &log.train.X : nullptr;
    const Diagnosis d0 =
        RunDiagnosis(*fit.model, X, Y, t, &base.seconds, train_X, &log.train.Y, &log.train.t);
    if (f.noise_from == "diagnosis") {
      bool estimated = d0.joints.size() == static_cast<size_t>(N);
      for (int j = 0; estimated && j < N; ++j) {
        estimated = d0.joints[static_cast<size_t>(j)].noise_std_estimate > 0;
      }
      if (estimated) {
        for (int j = 0; j < N; ++j) base.noise[j] = d0.joints[static_cast<size_t>(j)].noise_std_estimate;
      } else {
        base.note += "noise from the RMS of the differences (the uninjected diagnosis gave no "
                     "positive estimate on every joint); ";
      }
    }
    WriteFindings(f, "real_" + log.name + "_uninjected", d0);
    base.diagnosed = d0.status == DiagnosisStatus::kOk;
    if (!base.diagnosed) base.note += std::string(ToString(d0.status)) + ": " + d0.message;
    base.suggestions = SuggestionList(d0);
    base.other = OtherFindings(d0);
    std::set<std::string> baseline_keys;
    for (const Suggestion& s : d0.suggestions) baseline_keys.insert(Key(s));
    // Does adding the uninjected suggestions help on the held-out part (refit on training)?
    const Vector rms_before = ColumnRms(prediction, Y).cwiseQuotient(base.noise);
    base.before = Pooled(rms_before);
    if (!d0.suggestions.empty()) {
      ModelSpec with = spec;
      try {
        for (const Suggestion& s : d0.suggestions) {
          for (const EffectSpec& e : ParseEffectList(s.spec)) with.effects.push_back(e);
        }
        const Fit refit =
            FitSpec(with, log.train.X, log.train.Y, log.train.t, nullptr, f.real_ml_max_rows,
                    fit.model.get());
        if (refit.model) {
          const Vector rms_after =
              ColumnRms(PredictOn(*refit.model, X, t), Y).cwiseQuotient(base.noise);
          base.after = Pooled(rms_after);
          std::set<int> joints;
          for (const Suggestion& s : d0.suggestions) joints.insert(s.joint);
          for (int j : joints) {
            base.suggested_joints += Format("%sjoint %d: %s -> %s",
                                            base.suggested_joints.empty() ? "" : ", ", j,
                                            Num(rms_before[j - 1]).c_str(),
                                            Num(rms_after[j - 1]).c_str());
          }
        } else {
          base.note += "refit with the suggestions: " + refit.error;
        }
      } catch (const std::invalid_argument& e) {
        base.note += std::string("a suggestion does not parse: ") + e.what();
      }
    } else {
      base.after = base.before;
    }
    std::fprintf(stderr, "%s: fit %.0f s, uninjected diagnosis %.0f s: %s\n", log.name.c_str(),
                 base.fit_seconds, base.seconds, base.suggestions.c_str());
    result.baselines.push_back(base);
    if (!base.diagnosed) continue;

    // The joints with the widest range of q in the held-out part.
    std::vector<int> order(static_cast<size_t>(N));
    for (int j = 0; j < N; ++j) order[static_cast<size_t>(j)] = j;
    std::vector<double> range(static_cast<size_t>(N));
    for (int j = 0; j < N; ++j) {
      range[static_cast<size_t>(j)] = X.col(j).maxCoeff() - X.col(j).minCoeff();
    }
    std::stable_sort(order.begin(), order.end(),
                     [&](int a, int b) { return range[static_cast<size_t>(a)] > range[static_cast<size_t>(b)]; });
    order.resize(static_cast<size_t>(std::min(f.joints, N)));
    const double t0 = t.size() ? t[0] : 0.0;
    const double T = t.size() ? std::max(t[t.size() - 1] - t0, 1e-9) : 1.0;
    for (const std::string& effect : f.injections) {
      // With the training data, an effect the model spans is still a candidate on the log
      // alone (Suggestion::scope "log"): a change of it in this log.
      const bool spanned = !f.with_training && SpannedBy(spec, effect);
      const std::vector<double> periods =
          effect == "cogging" ? f.periods : std::vector<double>{0.0};
      for (double size : f.sizes) {
        for (int j : order) {
          for (double period : periods) {
            for (int seed = 1; seed <= f.seeds; ++seed) {
              std::mt19937_64 rng(static_cast<std::uint64_t>(seed) * 104729 + j);
              const double sign = std::uniform_real_distribution<double>(0, 1)(rng) < 0.5 ? -1 : 1;
              const double phase = std::uniform_real_distribution<double>(0, kTwoPi)(rng);
              const double a = sign * size * base.noise[j];
              Matrix Yi = Y;
              for (Eigen::Index i = 0; i < X.rows(); ++i) {
                const double q = X(i, j), qd = X(i, N + j);
                double v = 0;
                if (effect == "cogging") v = std::sin(kTwoPi * q / period + phase);
                if (effect == "coulomb") v = std::tanh(qd / kSignWidth);
                if (effect == "offset") v = 1.0;
                if (effect == "drift") v = (t[i] - t0) / T;
                Yi(i, j) += a * v;
              }
              InjectionRow row;
              row.log = log.name;
              row.effect = effect;
              row.size = size;
              row.period = period;
              row.joint = j + 1;
              row.seed = seed;
              row.spanned = spanned;
              row.in_baseline = baseline_keys.count(effect + "@" + std::to_string(j + 1)) != 0;
              const Diagnosis d = RunDiagnosis(*fit.model, X, Yi, t, &row.seconds, train_X,
                                               &log.train.Y, &log.train.t);
              WriteFindings(f,
                            Format("real_%s_%s_j%d_x%g_p%g_s%d", log.name.c_str(), effect.c_str(),
                                   j + 1, size, period, seed),
                            d);
              row.diagnosed = d.status == DiagnosisStatus::kOk;
              row.suggestions = SuggestionList(d);
              row.other = OtherFindings(d);
              const Expected expected{effect, j + 1, period};
              for (const Suggestion& s : d.suggestions) {
                if (Matches(s, expected)) {
                  row.found = true;
                } else if (baseline_keys.count(Key(s)) == 0) {
                  ++row.false_alarms;
                }
              }
              std::fprintf(stderr, "  %s %s@%d x%g%s: %s (%.0f s)\n", log.name.c_str(),
                           effect.c_str(), j + 1, size,
                           period > 0 ? Format(" P=%g", period).c_str() : "",
                           row.suggestions.c_str(), row.seconds);
              result.injections.push_back(row);
            }
          }
        }
      }
    }
  }
  // Tables.
  std::printf("\n### Part B: real logs, model %s (CLI defaults) fitted on the training part\n\n"
              "Uninjected held-out part:\n\n"
              "| log | model | noise per joint (--noise-from) | suggestions | held-out "
              "RMS/noise | refit on training + suggestions | the suggested joints | fit s | "
              "diagnosis s | other findings |\n|---|---|---|---|---|---|---|---|---|---|\n",
              ToString(spec).c_str());
  for (const BaselineRow& b : result.baselines) {
    std::string noise;
    for (Eigen::Index j = 0; j < b.noise.size(); ++j) noise += (j ? " " : "") + Num(b.noise[j]);
    std::printf("| %s | %s | %s | %s | %s | %s | %s | %.0f | %.0f | %s |\n", b.log.c_str(),
                b.model.c_str(), noise.c_str(),
                (b.suggestions + (b.note.empty() ? "" : " (" + b.note + ")")).c_str(),
                Num(b.before).c_str(), Num(b.after).c_str(),
                b.suggested_joints.empty() ? "—" : b.suggested_joints.c_str(), b.fit_seconds,
                b.seconds, b.other.c_str());
  }
  std::printf("\nInjected effects (one joint at a time; found: named on its joint, cogging period "
              "within 10%%; false alarms: suggestions beyond the uninjected log's, per run):\n\n"
              "| log | effect | size / noise | runs | found | false alarms per run | runs with a "
              "false alarm | diagnosis s (mean) |\n|---|---|---|---|---|---|---|---|\n");
  for (const RealLog& log : logs) {
    for (const std::string& effect : f.injections) {
      for (double size : f.sizes) {
        int runs = 0, found = 0, alarms = 0, with_alarm = 0, in_baseline = 0;
        double seconds = 0;
        bool spanned = false;
        for (const InjectionRow& r : result.injections) {
          if (r.log != log.name || r.effect != effect || r.size != size) continue;
          ++runs;
          found += r.found ? 1 : 0;
          in_baseline += r.in_baseline ? 1 : 0;
          alarms += r.false_alarms;
          with_alarm += r.false_alarms > 0 ? 1 : 0;
          seconds += r.seconds;
          spanned = r.spanned;
        }
        if (runs == 0) continue;
        std::printf("| %s | %s | %g | %d | %s | %.2f | %d | %.0f |\n", log.name.c_str(),
                    effect.c_str(), size, runs,
                    spanned ? "spanned by the model (not a candidate)"
                            : (Format("%d/%d (%.0f%%)", found, runs, 100.0 * found / runs) +
                               (in_baseline ? Format("; in %d the uninjected log had it already",
                                                     in_baseline)
                                            : ""))
                                  .c_str(),
                    static_cast<double>(alarms) / runs, with_alarm, seconds / runs);
      }
    }
    int runs = 0, alarms = 0, with_alarm = 0;
    for (const InjectionRow& r : result.injections) {
      if (r.log != log.name) continue;
      ++runs;
      alarms += r.false_alarms;
      with_alarm += r.false_alarms > 0 ? 1 : 0;
    }
    if (runs > 0) {
      std::printf("| %s | all | | %d | | %.2f | %d | |\n", log.name.c_str(), runs,
                  static_cast<double>(alarms) / runs, with_alarm);
    }
  }
  std::fflush(stdout);
  return result;
}

// ---- output ---------------------------------------------------------------------------------

std::string Csv(std::string s) {
  for (char& c : s) {
    if (c == '"') c = '\'';
  }
  return "\"" + s + "\"";
}

void WriteCsv(const Flags& f, const std::vector<SimRow>& sim, const RealResult& real, int argc,
              char** argv) {
  std::ofstream out(f.out);
  out << "# " << CommandLine("diagnosis_cases", argc, argv) << "\n";
  out << "part,robot_or_log,model,case_or_effect,joint,size,period,seed,suggestions,expected,"
         "found,false_alarms,before,after,with_truth,seconds,other_findings\n";
  for (const SimRow& r : sim) {
    out << "sim," << r.robot << "," << r.model << "," << r.kase << ",,,,," << Csv(r.suggestions)
        << "," << Csv(r.expected) << "," << Csv(r.found) << "," << r.false_alarms << ","
        << Format("%.6g", r.pooled_before) << "," << Format("%.6g", r.pooled_after) << ","
        << Format("%.6g", r.pooled_truth) << "," << Format("%.2f", r.seconds) << ","
        << Csv(r.other + (r.note.empty() ? "" : " note: " + r.note)) << "\n";
  }
  for (const BaselineRow& b : real.baselines) {
    out << "real," << b.log << "," << b.model << ",uninjected,,,,," << Csv(b.suggestions) << ",,,"
        << "," << Format("%.6g", b.before) << "," << Format("%.6g", b.after) << ",,"
        << Format("%.2f", b.seconds) << "," << Csv(b.other + (b.note.empty() ? "" : " note: " + b.note))
        << "\n";
  }
  for (const InjectionRow& r : real.injections) {
    out << "real," << r.log << "," << f.real_model << "," << r.effect << "," << r.joint << ","
        << r.size << "," << r.period << "," << r.seed << "," << Csv(r.suggestions) << ","
        << r.effect << "@" << r.joint << ","
        << (r.spanned ? "spanned" : r.found ? (r.in_baseline ? "yes (uninjected too)" : "yes") : "no")
        << "," << r.false_alarms << ",,,," << Format("%.2f", r.seconds) << "," << Csv(r.other)
        << "\n";
  }
}

bool Finite(double v) { return std::isfinite(v); }

int Run(const Flags& flags, int argc, char** argv) {
  Flags f = flags;
  if (f.quick) {
    f.robots = {"puma560"};
    f.cases = {"none", "coulomb"};
    if (f.models == std::vector<std::string>{"pol"}) f.models = {"rbd"};  // seconds, not minutes
    f.train_seconds = 6.0;
    f.test_seconds = 2.0;
    f.datasets = {"ur10"};
    f.injections = {"cogging"};
    f.sizes = {10.0};
    f.periods = {0.4};
    f.joints = 1;
    f.max_train = 300;
    f.heldout_rows = 300;
  }
  for (const std::string& p : f.parts) {
    if (p != "sim" && p != "real") {
      throw std::invalid_argument("--parts: unknown part '" + p + "' (expected sim, real)");
    }
  }
  if (f.rounds < 1) {
    throw std::invalid_argument("--rounds: expected at least 1, got " + std::to_string(f.rounds));
  }
  // Names are checked before anything runs.
  for (const std::string& c : f.cases) MakeSimCase(c, 7, 1);
  for (const std::string& r : f.robots) MakeRobot(r);
  for (const std::string& m : f.models) ParseModelSpec(m == "chain" ? "rbd" : m);
  const ModelSpec real_spec = ParseModelSpec(f.real_model);
  if (real_spec.base == BaseModel::kRbd || real_spec.rigid_body_features) {
    throw std::invalid_argument("--real-model: the real logs have no URDF here; expected a model "
                                "without rbd, got '" + f.real_model + "'");
  }
  for (const std::string& d : f.datasets) {
    if (d != "ur10" && d != "sarcos") {
      throw std::invalid_argument("--datasets: unknown data set '" + d + "' (ur10, sarcos)");
    }
  }
  for (const std::string& e : f.injections) {
    if (e != "cogging" && e != "coulomb" && e != "offset" && e != "drift") {
      throw std::invalid_argument("--injections: unknown effect '" + e +
                                  "' (expected cogging, coulomb, offset, drift)");
    }
  }
  const auto start = std::chrono::steady_clock::now();
  const bool sim = std::find(f.parts.begin(), f.parts.end(), "sim") != f.parts.end();
  const bool real = std::find(f.parts.begin(), f.parts.end(), "real") != f.parts.end();
  std::vector<SimRow> sim_rows;
  RealResult real_result;
  if (sim) sim_rows = RunSim(f);
  if (real) real_result = RunReal(f);
  std::printf("\ntotal wall time %.0f s\n", Seconds(start));
  if (!f.out.empty()) WriteCsv(f, sim_rows, real_result, argc, argv);
  if (f.check) {
    bool ok = true;
    for (const SimRow& r : sim_rows) {
      ok = ok && r.diagnosed && Finite(r.pooled_before) && Finite(r.pooled_after) &&
           Finite(r.pooled_truth);
    }
    for (const BaselineRow& b : real_result.baselines) ok = ok && b.diagnosed && Finite(b.before);
    for (const InjectionRow& r : real_result.injections) ok = ok && r.diagnosed;
    if (!ok) {
      std::fprintf(stderr, "diagnosis_cases: check failed: a fit or diagnosis failed, or a "
                           "number is not finite\n");
      return 3;
    }
  }
  return 0;
}

}  // namespace
}  // namespace structgp

int main(int argc, char** argv) {
  CLI::App app("The diagnosis on 6-7 joint simulated arms and on real logs with injected effects "
               "(docs/diagnosis.md)",
               "diagnosis_cases");
  structgp::Flags f;
  using structgp::AddFlag;
  using structgp::AddListFlag;
  using structgp::AtLeast;
  using structgp::GreaterThan;
  AddListFlag(&app, "--parts", &f.parts, "sim (part A) and/or real (part B)");
  AddListFlag(&app, "--robots", &f.robots,
              "the simulator's robots (sim::RobotByName): puma560, panda, ur10, three_link, "
              "random1 .. random7");
  AddFlag(&app, "--chain-starts", &structgp::g_chain.starts,
          "model chain: random starts of each round of the identification");
  AddFlag(&app, "--chain-rounds", &structgp::g_chain.max_rounds,
          "model chain: rounds of starts at most");
  AddFlag(&app, "--chain-seed", &structgp::g_chain.seed, "model chain: the starts' seed");
  AddFlag(&app, "--threads", &structgp::g_threads,
          "threads of the fits and refits of this program (as structgp fit --threads)");
  AddListFlag(&app, "--cases", &f.cases,
              "none, spring, payload, coulomb, viscous, stribeck, cogging, drift, combined");
  AddListFlag(&app, "--models", &f.models, "models of part A: pol, rbd (simulated chain as URDF), chain (rbd on the chain identified from the training log), ...");
  AddFlag(&app, "--joint", &f.joint, "joint of the single hidden effects (cogging: joint 1)")
      ->check(AtLeast(1));
  AddFlag(&app, "--train-seconds", &f.train_seconds, "length of the slow training log, s")
      ->check(GreaterThan(0));
  AddFlag(&app, "--test-seconds", &f.test_seconds, "length of each fast log, s")
      ->check(GreaterThan(0));
  AddFlag(&app, "--vias", &f.vias, "via points of the closed path")->check(AtLeast(2));
  AddFlag(&app, "--noise", &f.noise, "noise std relative to each joint's torque scale")
      ->check(GreaterThan(0));
  AddFlag(&app, "--fast-speed", &f.fast_speed, "speed of the diagnosed log (training: 1)")
      ->check(GreaterThan(0));
  AddFlag(&app, "--eval-speed", &f.eval_speed, "speed of the evaluation log (training: 1)")
      ->check(GreaterThan(0));
  AddFlag(&app, "--ml-max-rows", &f.ml_max_rows,
          "part A: evenly spaced rows of the evidence search of kernel-form fits (the CLI's "
          "--ml-max-rows)")
      ->check(AtLeast(10));
  AddFlag(&app, "--real-ml-max-rows", &f.real_ml_max_rows, "the same for part B")
      ->check(AtLeast(10));
  AddFlag(&app, "--data-dir", &f.data_dir, "directory with ur10-picknplace/ and sarcos/");
  AddListFlag(&app, "--datasets", &f.datasets, "ur10, sarcos");
  AddFlag(&app, "--real-model", &f.real_model, "model of part B");
  AddListFlag(&app, "--injections", &f.injections, "cogging, coulomb, offset, drift");
  AddFlag(&app, "--sizes", &f.sizes, "injected amplitudes, in multiples of the joint's noise")
      ->delimiter(',')
      ->check(GreaterThan(0));
  AddFlag(&app, "--periods", &f.periods, "injected cogging periods, rad")
      ->delimiter(',')
      ->check(GreaterThan(0));
  AddFlag(&app, "--joints", &f.joints, "joints per log (widest range of q first)")
      ->check(AtLeast(1));
  AddFlag(&app, "--seeds", &f.seeds, "seeds per injection (sign and cogging phase)")
      ->check(AtLeast(1));
  AddFlag(&app, "--max-train", &f.max_train, "evenly spaced training rows of part B (0: all)")
      ->check(AtLeast(0));
  AddFlag(&app, "--heldout-rows", &f.heldout_rows,
          "first rows of part B's held-out part only (0: all)")
      ->check(AtLeast(0));
  AddFlag(&app, "--noise-from", &f.noise_from,
          "part B: the noise level the injections are sized by (and the held-out RMS divided "
          "by): diagnosis (the uninjected diagnosis's estimate, robust) or differences (the RMS "
          "of the residual's successive differences)")
      ->check(CLI::IsMember({"diagnosis", "differences"}));
  AddFlag(&app, "--out", &f.out, "CSV file of every row");
  AddFlag(&app, "--findings-dir", &f.findings_dir, "write every diagnosis's JSON here");
  AddFlag(&app, "--rounds", &f.rounds,
          "rounds of the loop in part A: the model refitted with the suggestions is diagnosed "
          "again and its new suggestions added (1: one diagnosis)");
  std::string refit_from = "model";
  app.add_option("--refit-from", refit_from,
                 "lagk refits with effects added: from the model they are added to, at its sigma "
                 "(model, as RunDiagnosisLoop), or from the whole sigma grid (scratch)")
      ->check(CLI::IsMember({"model", "scratch"}))
      ->capture_default_str();
  AddFlag(&app, "--models-dir", &structgp::g_models_dir,
          "save each fitted model here, and load it instead of fitting the same model on the "
          "same data again (not models with a URDF)");
  app.add_flag("--held-out-route,!--no-held-out-route", structgp::g_held_out_route,
               "an effect that lowers the held-out error by 25% in all folds but one passes "
               "without the evidence bars (DiagnosisOptions::held_out_may_replace_evidence)");
  std::string autocorrelation = structgp::ToString(structgp::g_autocorrelation);
  AddFlag(&app, "--autocorrelation", &autocorrelation,
          "how the evidence is corrected for autocorrelated residuals "
          "(DiagnosisOptions::autocorrelation)")
      ->check(CLI::IsMember({"bartlett", "prewhitening", "none"}))
      ->capture_default_str();
  app.add_flag("--diagnosis-chain,!--no-diagnosis-chain", structgp::g_diagnosis_chain,
               "part A, model chain: the diagnosis identifies the chain again on the training "
               "data and the log (DiagnosisOptions::reidentify_chain; the default)");
  app.add_option("--chain-data", f.chain_with_log,
                 "part A, model chain: identify the chain on the training log (train, the "
                 "default) or on the training and the diagnosed log together (train+log)")
      ->transform(CLI::CheckedTransformer(std::map<std::string, bool>{{"train", false},
                                                                      {"train+log", true}}));
  app.add_flag("--reidentify,!--no-reidentify", f.reidentify,
               "part A, model chain: refits with effects (the suggestions, the true ones) on a "
               "chain identified again with those effects in its least squares, as a user "
               "without a URDF would run the loop (or on the first chain)");
  app.add_flag("--with-training,!--log-only", f.with_training,
               "give the diagnosis the model's training data too (the default; --log-only: the "
               "diagnosed log alone)");
  app.add_flag("--quick", f.quick,
               "a CI-size run: PUMA 560 none/coulomb on short logs (rbd when --models is "
               "at its default), a UR10 slice with one cogging injection");
  app.add_flag("--check", f.check,
               "exit 3 unless every fit and diagnosis ran and every number is finite");
  return structgp::RunProgram(&app, argc, argv, [&] {
    structgp::g_refit_from_model = refit_from == "model";
    structgp::FromString(autocorrelation, &structgp::g_autocorrelation);
    return structgp::Run(f, argc, argv);
  });
}
