// paper_fig12: the simulation study of Section IV of Cheng et al. ("Learning the Inverse
// Dynamics of Robotic Manipulators in Structured Reproducing Kernel Hilbert Space"), Figs. 1
// and 2: prediction error of the structured kernel (pol), the squared-exponential kernels
// (rbf, rbfs) and the motor baseline, each alone and with the semi-parametric friction
// bases (+fri), on random KDL robots of N = 1..6 joints, on data without and with joint
// friction.
//
// Protocol (per N, per random robot sim::RandomRobot(N, seed)):
//   - states: i.i.d. sim::UniformBox, q in [-pi, pi] rad, qd in [-2, 2] rad/s,
//     qdd in [-4, 4] rad/s^2 (flags --q-range, --qd-range, --qdd-range); the first
//     --train = 500 rows train, the next --test = 15,000 validate;
//   - torques by KDL's recursive Newton-Euler, plus, on the friction data, Coulomb
//     (sign(qd), not smoothed) and viscous friction per joint: F_c = u_c r_n and
//     F_v = u_v r_n / qd_range, u ~ U[0.1, 0.3] (--friction-min/max), r_n the RMS rigid-body
//     torque of joint n over the sample;
//   - one global scale so that max |tau| = 1 over train and validation (noise-free), then
//     Gaussian noise of std 0.05 (--noise) on the training torques;
//   - error: mean over validation states of N^(-1/2) ||f(x) - f_hat(x)||, f the noise-free
//     torque; mean and spread over the robots of one N.
// Hyper-parameters by type-II maximum likelihood (all models) and, where a finite feature
// map is used in weight space (pol for N <= 2, motor), also by 5-fold blocked
// cross-validation over a grid of (log sigma, log noise).
//
// Models: pol in weight space while its D <= m (N <= 2), else in kernel form with
// PolFormulaKernel (+ the friction map's FeatureKernel through SumKernel); rbf and rbfs
// (ARD) in kernel form (+ friction likewise); motor in weight space.
//
// Writes <out-dir>/paper_fig12.md (tables; text after the discussion marker of an existing
// file is kept), paper_fig12.csv (summary), paper_fig12_runs.csv (one row per robot and
// model) and paper_fig12.svg (RMS error against N). --check exits with status 3 unless pol
// beats rbf at N = 2 on the data without friction.
//
//   paper_fig12 [--quick] [--n-min=1] [--n-max=6] [--robots=10] [--seed=1] [--threads=2]
//               [--budget-cpu-seconds=1200] [--out-dir=docs] [--check] [--help]
//
// The budget is CPU time of this process: "10 minutes on 2 cores" = 1200 CPU-seconds, however
// busy the machine is with other work.

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include <Eigen/Core>

#include "experiment_program.h"
#include "kernel_mean.h"
#include "structgp/core/status.h"
#include "structgp/core/types.h"
#include "structgp/feature/friction_feature_map.h"
#include "structgp/fit/fit_model.h"
#include "structgp/feature/pol_feature_map.h"
#include "structgp/hyper/marginal_likelihood.h"
#include "structgp/io/atomic_file.h"
#include "structgp/kernel/feature_kernel.h"
#include "structgp/kernel/pol_kernel.h"
#include "structgp/kernel/rbf_kernel.h"
#include "structgp/kernel/sum_kernel.h"
#include "structgp/model/robot_model.h"
#include "structgp/sim/dataset.h"
#include "structgp/sim/friction.h"
#include "structgp/sim/robot.h"
#include "structgp/sim/trajectory.h"
#include "timing.h"

namespace structgp {
namespace {

constexpr double kPi = 3.141592653589793;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
// Marker after which a hand-written discussion in paper_fig12.md survives regeneration.
constexpr char kDiscussionMarker[] = "<!-- discussion: kept when the file is regenerated -->";
// Pseudo-model of the summaries: the validation "error" of predicting 0, i.e. the size of f.
constexpr char kSignal[] = "signal";
// Number of folds of the blocked cross-validation.
constexpr int kNumFolds = 5;

// ---- command line -----------------------------------------------------------------------

struct Flags {
  int n_min = 1;
  int n_max = 6;
  int robots = 10;
  int train = 500;
  int test = 15000;
  std::uint64_t seed = 1;
  double noise = 0.05;
  double q_range = kPi;
  double qd_range = 2.0;
  double qdd_range = 4.0;
  double friction_min = 0.1;
  double friction_max = 0.3;
  int threads = 2;
  double budget_cpu_seconds = 1200.0;
  int ml_iterations = 60;
  double fit_seconds = 120.0;
  bool cv = true;
  bool plain_ml = false;
  std::vector<std::string> models;  // subset of the models to run; empty = all
  bool quick = false;
  bool check = false;
  std::string out_dir = "docs";
};

bool StartsWith(const std::string& s, const std::string& prefix) {
  return s.compare(0, prefix.size(), prefix) == 0;
}

// ---- models -----------------------------------------------------------------------------

enum class Base { kPol, kRbf, kRbfs, kMotor };
enum class Tuning { kMaximumLikelihood, kCrossValidation };

const char* ToString(Tuning t) { return t == Tuning::kMaximumLikelihood ? "ml2" : "cv5"; }

struct ModelKind {
  Base base;
  bool friction;
  std::string name;  // "pol", "pol+fri", ...
};

const std::vector<ModelKind>& Models() {
  static const std::vector<ModelKind> models = {
      {Base::kPol, false, "pol"},     {Base::kPol, true, "pol+fri"},
      {Base::kRbf, false, "rbf"},     {Base::kRbf, true, "rbf+fri"},
      {Base::kRbfs, false, "rbfs"},   {Base::kRbfs, true, "rbfs+fri"},
      {Base::kMotor, false, "motor"}, {Base::kMotor, true, "motor+fri"}};
  return models;
}

// The flags of the program, bound to *f.
void AddFlags(CLI::App* app, Flags* f) {
  app->add_flag("--quick", f->quick, "N = 1..2, 3 robots (a CI-size run)");
  AddFlag(app, "--n-min", &f->n_min, "smallest joint count");
  AddFlag(app, "--n-max", &f->n_max, "largest joint count");
  AddFlag(app, "--robots", &f->robots, "random robots per N");
  AddFlag(app, "--seed", &f->seed, "base seed of robots, states, friction and noise");
  AddFlag(app, "--train", &f->train, "training states per robot");
  AddFlag(app, "--test", &f->test, "validation states per robot");
  AddFlag(app, "--noise", &f->noise, "noise std of the normalised training torques");
  AddFlag(app, "--q-range", &f->q_range, "state box: |q| <= R rad");
  AddFlag(app, "--qd-range", &f->qd_range, "state box: |qd| <= R rad/s");
  AddFlag(app, "--qdd-range", &f->qdd_range, "state box: |qdd| <= R rad/s^2");
  AddFlag(app, "--friction-min", &f->friction_min, "relative friction size, lower end");
  AddFlag(app, "--friction-max", &f->friction_max, "relative friction size, upper end");
  AddFlag(app, "--threads", &f->threads, "robots fitted in parallel");
  AddFlag(app, "--budget-cpu-seconds", &f->budget_cpu_seconds,
          "start a new N only if it is expected to end within this CPU time of the process "
          "(1200: 10 minutes on 2 cores)");
  AddFlag(app, "--ml-iterations", &f->ml_iterations, "LBFGS iterations per ML-II fit");
  AddFlag(app, "--fit-seconds", &f->fit_seconds, "wall-clock limit per ML-II fit");
  app->add_flag_callback("--no-cv", [f]() { f->cv = false; }, "skip the cross-validated variants");
  app->add_flag_callback("--plain-ml", [f]() { f->plain_ml = true; },
                         "plain type-II maximum likelihood: no prior on the log hyper-parameters, "
                         "one start, no held-out check (the library before its type-II MAP)");
  AddListFlag(app, "--models", &f->models,
              "run only these of pol, pol+fri, rbf, rbf+fri, rbfs, rbfs+fri, motor, motor+fri "
              "(default all)");
  AddFlag(app, "--out-dir", &f->out_dir, "where the .md, .csv and .svg go");
  app->add_flag("--check", f->check, "exit 3 unless pol beats rbf at N = 2 without friction");
}

// Applies --quick (unless --n-min, --n-max or --robots say otherwise) and checks the flags
// together. Throws std::invalid_argument naming the bad flag.
void FinishFlags(const CLI::App& app, Flags* f) {
  if (f->quick) {
    if (app.count("--n-min") == 0 && app.count("--n-max") == 0) {
      f->n_min = 1;
      f->n_max = 2;
    }
    if (app.count("--robots") == 0) f->robots = 3;
  }
  if (f->n_min < 1 || f->n_max > 7 || f->n_min > f->n_max) {
    throw std::invalid_argument("expected 1 <= --n-min <= --n-max <= 7, got " +
                                std::to_string(f->n_min) + ".." + std::to_string(f->n_max));
  }
  if (f->robots < 1 || f->train < kNumFolds || f->test < 1 || f->threads < 1 ||
      f->ml_iterations < 1) {
    throw std::invalid_argument("--robots, --test, --threads, --ml-iterations must be >= 1 and "
                                "--train >= 5");
  }
  if (!(f->noise >= 0.0) || !(f->q_range > 0.0) || !(f->qd_range > 0.0) ||
      !(f->qdd_range > 0.0) || !(f->friction_min >= 0.0) ||
      !(f->friction_max >= f->friction_min)) {
    throw std::invalid_argument("expected noise >= 0, positive ranges and "
                                "0 <= friction-min <= friction-max");
  }
  if (!(f->fit_seconds > 0.0) || !(f->budget_cpu_seconds >= 0.0)) {
    throw std::invalid_argument("expected --fit-seconds > 0 and --budget-cpu-seconds >= 0");
  }
  for (const std::string& m : f->models) {
    bool known = false;
    for (const ModelKind& kind : Models()) known = known || kind.name == m;
    if (!known) throw std::invalid_argument("--models: unknown model '" + m + "'");
  }
}

// True when `model` is to run (--models).
bool Selected(const Flags& f, const std::string& model) {
  return f.models.empty() || std::find(f.models.begin(), f.models.end(), model) != f.models.end();
}

// One training / validation problem: noisy training torques, noise-free validation torques,
// all divided by one global scale.
struct Problem {
  Matrix X_train, Y_train;
  Matrix X_test, F_test;
};

struct RobotData {
  std::string robot_name;
  Problem plain;          // rigid-body torques only
  Problem with_friction;  // plus Coulomb and viscous friction
};

// Seeds of robot r (0-based) of N joints: distinct streams for the robot, the states, the
// friction draw and the noise.
// Seed k (0..3) of robot r.
std::uint64_t RobotSeed(const Flags& f, int n, int r, int k) {
  const std::uint64_t robot = f.seed * 1000003ULL + static_cast<std::uint64_t>(n) * 1009ULL +
                              static_cast<std::uint64_t>(r);
  return 4 * robot + static_cast<std::uint64_t>(k);
}

Problem MakeProblem(const sim::Robot& robot, const sim::Trajectory& states,
                    const std::optional<sim::FrictionModel>& friction, const Flags& f,
                    std::uint64_t noise_seed) {
  sim::SimulationOptions options;
  options.friction = friction;
  options.normalization = sim::TorqueNormalization::kGlobal;
  const sim::Dataset clean = sim::Simulate(robot, states, options);
  options.noise_std = f.noise;
  options.seed = noise_seed;
  const sim::Dataset noisy = sim::Simulate(robot, states, options);
  Problem p;
  p.X_train = clean.X.topRows(f.train);
  p.Y_train = noisy.Y.topRows(f.train);
  p.X_test = clean.X.bottomRows(f.test);
  p.F_test = clean.Y.bottomRows(f.test);
  return p;
}

RobotData MakeRobotData(int n, int r, const Flags& f) {
  const sim::Robot robot = sim::RandomRobot(n, RobotSeed(f, n, r, 0));
  const sim::Trajectory states = sim::UniformBox(n, f.train + f.test, f.q_range, f.qd_range,
                                                 f.qdd_range, RobotSeed(f, n, r, 1));
  // Friction relative to each joint's RMS rigid-body torque.
  const sim::TorqueComponents rigid = sim::SimulateComponents(robot, states);
  const Matrix tau = rigid.Total();
  std::mt19937_64 rng(RobotSeed(f, n, r, 2));
  std::uniform_real_distribution<double> relative(f.friction_min, f.friction_max);
  std::vector<sim::JointFriction> joints(static_cast<size_t>(n));
  for (int j = 0; j < n; ++j) {
    const double rms = std::sqrt(tau.col(j).squaredNorm() / static_cast<double>(tau.rows()));
    joints[static_cast<size_t>(j)].coulomb = relative(rng) * rms;
    joints[static_cast<size_t>(j)].viscous = relative(rng) * rms / f.qd_range;
  }
  RobotData data;
  data.robot_name = robot.name();
  // The same states and noise draw for both data sets: the comparison is paired.
  data.plain = MakeProblem(robot, states, std::nullopt, f, RobotSeed(f, n, r, 3));
  data.with_friction =
      MakeProblem(robot, states, sim::FrictionModel(joints), f, RobotSeed(f, n, r, 3));
  return data;
}

// Mean over rows of N^(-1/2) ||F_i - P_i||.
double MeanRms(const Matrix& F, const Matrix& P) {
  const double inv_n = 1.0 / static_cast<double>(F.cols());
  double sum = 0.0;
  for (Eigen::Index i = 0; i < F.rows(); ++i) {
    sum += std::sqrt((F.row(i) - P.row(i)).squaredNorm() * inv_n);
  }
  return sum / static_cast<double>(F.rows());
}

struct FitResult {
  double rms = kNaN;
  double seconds = 0.0;
  std::string form;  // "weight space (D = 133)", "kernel form"
  std::string note;  // ML-II termination, the CV choice, or why it failed
  // Kernel form: the fitted kernel parameters and log sigma_n (a warm start for "+fri").
  Vector kernel_parameters;
  double log_noise_std = kNaN;
};

MaximumLikelihoodOptions MlOptions(const Flags& f) {
  MaximumLikelihoodOptions o;
  o.max_iterations = f.ml_iterations;
  // Of f = -log p / (m N), f ~ -1: a change of 1e-7 relative or a gradient of 1e-4 is
  // 1e-4 .. 0.1 nats of -log p over the m N = 500 N observations, far below what moves the
  // validation error.
  o.gradient_tolerance = 1e-4;
  o.function_tolerance = 1e-7;
  o.max_seconds = f.fit_seconds;
  if (f.plain_ml) {
    o.prior.family = HyperpriorFamily::kNone;
    o.num_starts = 1;
  }
  return o;
}

ModelSpec SpecOf(const ModelKind& kind) {
  ModelSpec spec;
  spec.base = kind.base == Base::kPol ? BaseModel::kPol : BaseModel::kMotor;
  spec.friction = kind.friction;
  return spec;
}

// The grid of the cross-validated variants: log sigma of pol (absolute values; FitModel takes
// offsets from the default, which is 0) and sigma_n relative to the output scales.
const std::vector<double> kCvLogSigma = {-3.0, -2.0, -1.0, 0.0, 1.0, 2.0, 3.0, 5.0, 8.0};
const std::vector<double> kCvNoiseLevels = {0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0};

// Weight-space model (pol with D <= m, motor), hyper-parameters by ML-II or blocked CV through
// the library's FitModel. The output scales stay at 1 (OutputScaling::kUnit): one global
// torque scale and one noise level for all joints, the paper's setting. The CV grid is the
// paper's: offsets from the default log sigma (0) are the absolute values.
FitResult FitWeightSpace(const ModelKind& kind, const Problem& p, Tuning tuning,
                         const Flags& f) {
  FitOptions options;
  options.model.form = Form::kWeightSpace;
  options.output_scaling = OutputScaling::kUnit;
  options.check.enabled = !f.plain_ml;
  if (tuning == Tuning::kMaximumLikelihood) {
    options.method = HyperparameterMethod::kEvidence;
    options.evidence = MlOptions(f);
  } else {
    options.method = HyperparameterMethod::kCrossValidation;
    options.cv_folds = kNumFolds;
    options.cv_shape_offsets = kCvLogSigma;
    options.cv_noise_levels = kCvNoiseLevels;
  }
  const FittedModel fit = FitModel(SpecOf(kind), p.X_train, p.Y_train, Vector(), options);
  FitResult result;
  result.form = "weight space (D = " + std::to_string(fit.model.feature_map()->dim()) + ")";
  if (tuning == Tuning::kMaximumLikelihood) {
    result.note = std::string(ToString(fit.summary.termination)) + " after " +
                  std::to_string(fit.summary.num_evaluations) + " evaluations";
  } else if (fit.summary.IsUsable()) {
    const Hyperparameters& hyper = fit.model.hyperparameters();
    std::ostringstream note;
    note << std::setprecision(3) << "sigma_n " << std::exp(hyper.log_noise_std);
    if (hyper.shape.size() > 0) note << ", log sigma " << hyper.shape[0];
    result.note = note.str();
  }
  if (!fit.summary.IsUsable()) {
    result.note += (result.note.empty() ? "" : "; ") + fit.summary.message;
    return result;
  }
  Matrix prediction;
  fit.model.PredictRows(p.X_test, &prediction);
  result.rms = MeanRms(p.F_test, prediction);
  return result;
}

// Standard deviation of every column of X.
Vector ColumnStd(const Matrix& X) {
  const Eigen::RowVectorXd mean = X.colwise().mean();
  return ((X.rowwise() - mean).colwise().squaredNorm() / static_cast<double>(X.rows()))
      .cwiseSqrt()
      .transpose();
}

// The kernel of a kernel-form model, with starting parameters from the data: ARD length
// scales = the inputs' spreads (1 for the angles of rbfs, whose chordal distance is at most
// 2), signal std = the torques' spread; pol at its defaults (sigma = 1, unit block scales);
// friction: unit prior std of the coefficients (the torques are at most 1).
std::unique_ptr<Kernel> MakeKernel(const ModelKind& kind, const Problem& p) {
  const int n = static_cast<int>(p.Y_train.cols());
  const Vector spread = ColumnStd(p.X_train);
  const double signal = std::sqrt(p.Y_train.squaredNorm() / static_cast<double>(p.Y_train.size()));
  std::unique_ptr<Kernel> base;
  if (kind.base == Base::kPol) {
    base = std::make_unique<PolFormulaKernel>(n);
  } else if (kind.base == Base::kRbf) {
    auto k = std::make_unique<RbfKernel>(3 * n, /*ard=*/true);
    Vector theta(3 * n + 1);
    theta << spread.array().log().matrix(), std::log(signal);
    base = k->WithParameters(theta);
  } else {
    auto k = std::make_unique<RbfsKernel>(n, /*ard=*/true);
    Vector theta(3 * n + 1);
    theta << Vector::Zero(n), spread.tail(2 * n).array().log().matrix(), std::log(signal);
    base = k->WithParameters(theta);
  }
  if (!kind.friction) return base;
  auto friction_map = std::make_shared<FrictionFeatureMap>(n, RobotModelOptions().friction_width);
  const FeatureKernel friction(friction_map, DefaultHyperparameters(*friction_map, n));
  return std::make_unique<SumKernel>(std::vector<const Kernel*>{base.get(), &friction});
}

// Kernel-form model, hyper-parameters by ML-II; prediction K_* (K + sigma_n^2 I)^{-1} Y.
// Not through FitModel: ARD rbf/rbfs kernels started from the data's spreads, a unit friction
// prior and warm starts of "+fri" from the base model are this experiment's comparison, not
// what the library's models offer.
// A "+fri" model starts from the fitted parameters and noise of its base model when given
// (`base`, a kernel-form result on the same data), with a unit friction prior.
FitResult FitKernelForm(const ModelKind& kind, const Problem& p, const Flags& f,
                        const FitResult* base) {
  const int n = static_cast<int>(p.Y_train.cols());
  FitResult result;
  result.form = "kernel form";
  std::unique_ptr<Kernel> kernel = MakeKernel(kind, p);
  Hyperparameters hyper = DefaultHyperparameters(*kernel, n);
  const bool warm = kind.friction && base != nullptr && std::isfinite(base->log_noise_std) &&
                    base->kernel_parameters.size() + 1 == kernel->num_parameters();
  if (warm) {
    hyper.shape.head(base->kernel_parameters.size()) = base->kernel_parameters;
    hyper.log_noise_std = base->log_noise_std;
  }
  const MaximumLikelihoodSummary s =
      FitKernelHyperparameters(*kernel, p.X_train, p.Y_train, MlOptions(f), &hyper);
  result.note = std::string(ToString(s.termination)) + " after " +
                std::to_string(s.num_evaluations) + " evaluations" + (warm ? ", warm start" : "");
  if (!s.usable()) return result;
  result.kernel_parameters = hyper.shape;
  result.log_noise_std = hyper.log_noise_std;
  kernel = kernel->WithParameters(hyper.shape);
  Matrix alpha;
  if (!SolveKernelSystem(*kernel, p.X_train, p.Y_train, std::exp(2.0 * hyper.log_noise_std),
                         &alpha)) {
    result.note += "; K + sigma_n^2 I not positive definite";
    return result;
  }
  result.rms = MeanRms(p.F_test, KernelMean(*kernel, p.X_train, alpha, p.X_test));
  return result;
}

bool UsesWeightSpace(const ModelKind& kind, int n, int m) {
  if (kind.base == Base::kMotor) return true;
  if (kind.base != Base::kPol) return false;
  const int fri = kind.friction ? 2 * n + 1 : 0;
  return n <= kMaxPolJoints && PolFeatureDimension(n) + fri <= m;
}

// ---- one robot --------------------------------------------------------------------------

struct Record {
  int n = 0;
  int robot = 0;
  std::string robot_name;
  bool data_friction = false;
  std::string model;
  Tuning tuning = Tuning::kMaximumLikelihood;
  FitResult result;
};

std::vector<Record> RunRobot(int n, int r, const Flags& f) {
  const RobotData data = MakeRobotData(n, r, f);
  std::vector<Record> records;
  for (bool data_friction : {false, true}) {
    const Problem& p = data_friction ? data.with_friction : data.plain;
    // The size of what is predicted: the error of predicting 0 ("signal").
    Record signal;
    signal.n = n;
    signal.robot = r;
    signal.robot_name = data.robot_name;
    signal.data_friction = data_friction;
    signal.model = kSignal;
    signal.result.rms = MeanRms(p.F_test, Matrix::Zero(p.F_test.rows(), p.F_test.cols()));
    records.push_back(signal);
    FitResult base;  // the last base model's result: warm start of the "+fri" that follows
    for (const ModelKind& kind : Models()) {
      if (!Selected(f, kind.name)) continue;
      const bool weight_space = UsesWeightSpace(kind, n, f.train);
      std::vector<Tuning> tunings = {Tuning::kMaximumLikelihood};
      if (weight_space && f.cv) tunings.push_back(Tuning::kCrossValidation);
      for (Tuning tuning : tunings) {
        Record rec;
        rec.n = n;
        rec.robot = r;
        rec.robot_name = data.robot_name;
        rec.data_friction = data_friction;
        rec.model = kind.name;
        rec.tuning = tuning;
        const auto start = std::chrono::steady_clock::now();
        try {
          rec.result = weight_space ? FitWeightSpace(kind, p, tuning, f)
                                    : FitKernelForm(kind, p, f, &base);
        } catch (const std::exception& e) {
          rec.result.note = std::string("error: ") + e.what();
        }
        rec.result.seconds = Seconds(start);
        if (!kind.friction && tuning == Tuning::kMaximumLikelihood) base = rec.result;
        records.push_back(rec);
      }
    }
  }
  return records;
}

// ---- summaries and output ---------------------------------------------------------------

struct Summary {
  int count = 0;     // robots with a finite error
  int failures = 0;  // robots without
  double mean = kNaN, std = kNaN, median = kNaN, q25 = kNaN, q75 = kNaN, min = kNaN,
         max = kNaN;
  double seconds = 0.0;  // mean wall-clock time per fit (fit + validation)
};

// Quantile by linear interpolation between order statistics (sorted input).
double Quantile(const std::vector<double>& sorted, double q) {
  const double pos = q * static_cast<double>(sorted.size() - 1);
  const size_t lo = static_cast<size_t>(std::floor(pos));
  const size_t hi = std::min(lo + 1, sorted.size() - 1);
  return sorted[lo] + (pos - static_cast<double>(lo)) * (sorted[hi] - sorted[lo]);
}

Summary Summarize(const std::vector<const Record*>& records) {
  Summary s;
  std::vector<double> values;
  double seconds = 0.0;
  for (const Record* r : records) {
    seconds += r->result.seconds;
    if (std::isfinite(r->result.rms)) {
      values.push_back(r->result.rms);
    } else {
      ++s.failures;
    }
  }
  if (!records.empty()) s.seconds = seconds / static_cast<double>(records.size());
  s.count = static_cast<int>(values.size());
  if (values.empty()) return s;
  std::sort(values.begin(), values.end());
  double sum = 0.0;
  for (double v : values) sum += v;
  s.mean = sum / s.count;
  double ss = 0.0;
  for (double v : values) ss += (v - s.mean) * (v - s.mean);
  s.std = s.count > 1 ? std::sqrt(ss / (s.count - 1)) : 0.0;
  s.median = Quantile(values, 0.5);
  s.q25 = Quantile(values, 0.25);
  s.q75 = Quantile(values, 0.75);
  s.min = values.front();
  s.max = values.back();
  return s;
}

struct Key {
  int n;
  bool data_friction;
  std::string model;
  Tuning tuning;
  bool operator<(const Key& o) const {
    return std::tie(n, data_friction, model, tuning) <
           std::tie(o.n, o.data_friction, o.model, o.tuning);
  }
};

std::map<Key, Summary> SummarizeAll(const std::vector<Record>& records) {
  std::map<Key, std::vector<const Record*>> groups;
  for (const Record& r : records) groups[Key{r.n, r.data_friction, r.model, r.tuning}].push_back(&r);
  std::map<Key, Summary> out;
  for (const auto& [key, group] : groups) out[key] = Summarize(group);
  return out;
}

std::string Format(double v, int digits = 3) {
  if (!std::isfinite(v)) return "—";
  std::ostringstream s;
  s << std::scientific << std::setprecision(digits - 1) << v;
  return s.str();
}

std::string Cell(const std::map<Key, Summary>& summaries, const Key& key) {
  const auto it = summaries.find(key);
  if (it == summaries.end() || it->second.count == 0) {
    return it == summaries.end() ? "" : "failed";
  }
  const Summary& s = it->second;
  std::string cell = Format(s.mean) + " ± " + Format(s.std, 2);
  if (s.failures > 0) cell += " (" + std::to_string(s.failures) + " failed)";
  return cell;
}

std::string Csv(const std::map<Key, Summary>& summaries) {
  std::ostringstream out;
  out << "n,data_friction,model,tuning,robots,failures,mean,std,median,q25,q75,min,max,"
         "mean_seconds\n";
  out << std::setprecision(6);
  for (const auto& [k, s] : summaries) {
    out << k.n << ',' << (k.data_friction ? 1 : 0) << ',' << k.model << ',' << ToString(k.tuning)
        << ',' << s.count << ',' << s.failures << ',' << s.mean << ',' << s.std << ','
        << s.median << ',' << s.q25 << ',' << s.q75 << ',' << s.min << ',' << s.max << ','
        << s.seconds << '\n';
  }
  return out.str();
}

std::string RunsCsv(const std::vector<Record>& records) {
  std::ostringstream out;
  out << "n,robot,robot_name,data_friction,model,tuning,rms,seconds,form,note\n";
  out << std::setprecision(6);
  for (const Record& r : records) {
    std::string note = r.result.note;
    std::replace(note.begin(), note.end(), ',', ';');
    out << r.n << ',' << r.robot << ',' << r.robot_name << ',' << (r.data_friction ? 1 : 0) << ','
        << r.model << ',' << ToString(r.tuning) << ',' << r.result.rms << ','
        << r.result.seconds << ',' << r.result.form << ',' << note << '\n';
  }
  return out.str();
}

// ---- SVG ----------------------------------------------------------------------------------

std::string Color(const std::string& model) {
  if (StartsWith(model, "pol")) return "#1b9e77";
  if (StartsWith(model, "rbfs")) return "#7570b3";
  if (StartsWith(model, "rbf")) return "#d95f02";
  return "#e7298a";
}

// Two panels (data without / with friction), log10 of the mean error against N for the ML-II
// models, whiskers from the lower to the upper quartile over the robots.
std::string Svg(const std::map<Key, Summary>& summaries, const std::vector<int>& ns) {
  const double panel_w = 430, panel_h = 330, left = 70, top = 40, gap = 60;
  const double plot_w = panel_w - left - 20, plot_h = panel_h - top - 50;
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (const auto& [k, s] : summaries) {
    if (k.tuning != Tuning::kMaximumLikelihood || s.count == 0) continue;
    lo = std::min(lo, std::min(s.q25, s.mean));
    hi = std::max(hi, std::max(s.q75, s.mean));
  }
  if (!std::isfinite(lo)) {
    lo = 1e-3;
    hi = 1.0;
  }
  const double y0 = std::floor(std::log10(lo)), y1 = std::ceil(std::log10(hi));
  const double y_span = std::max(1.0, y1 - y0);
  const int n_lo = ns.front(), n_hi = ns.back();
  const double n_span = n_hi - n_lo;
  const double width = 2 * panel_w + gap + 150, height = panel_h + 20;
  std::ostringstream o;
  o << std::fixed << std::setprecision(1);
  o << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << width << "\" height=\"" << height
    << "\" viewBox=\"0 0 " << width << ' ' << height
    << "\" font-family=\"sans-serif\" font-size=\"12\">\n";
  o << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
  for (int panel = 0; panel < 2; ++panel) {
    const bool friction = panel == 1;
    const double ox = panel * (panel_w + gap);
    auto px = [&](double n) { return ox + left + (n - n_lo + 0.25) / (n_span + 0.5) * plot_w; };
    auto py = [&](double v) { return top + (y1 - std::log10(v)) / y_span * plot_h; };
    o << "<text x=\"" << ox + left + plot_w / 2 << "\" y=\"20\" text-anchor=\"middle\" "
      << "font-size=\"14\">" << (friction ? "data with friction" : "data without friction")
      << "</text>\n";
    o << "<rect x=\"" << ox + left << "\" y=\"" << top << "\" width=\"" << plot_w
      << "\" height=\"" << plot_h << "\" fill=\"none\" stroke=\"black\"/>\n";
    for (int e = static_cast<int>(y0); e <= static_cast<int>(y0 + y_span); ++e) {
      const double y = py(std::pow(10.0, e));
      o << "<line x1=\"" << ox + left << "\" y1=\"" << y << "\" x2=\"" << ox + left + plot_w
        << "\" y2=\"" << y << "\" stroke=\"#ddd\"/>\n";
      o << "<text x=\"" << ox + left - 6 << "\" y=\"" << y + 4
        << "\" text-anchor=\"end\">1e" << e << "</text>\n";
    }
    for (int n : ns) {
      o << "<text x=\"" << px(n) << "\" y=\"" << top + plot_h + 18
        << "\" text-anchor=\"middle\">" << n << "</text>\n";
    }
    o << "<text x=\"" << ox + left + plot_w / 2 << "\" y=\"" << top + plot_h + 38
      << "\" text-anchor=\"middle\">N (joints)</text>\n";
    o << "<text transform=\"translate(" << ox + 16 << ',' << top + plot_h / 2
      << ") rotate(-90)\" text-anchor=\"middle\">mean RMS error (max |tau| = 1)</text>\n";
    for (size_t mi = 0; mi < Models().size(); ++mi) {
      const ModelKind& kind = Models()[mi];
      const std::string color = Color(kind.name);
      const double dx = (static_cast<double>(mi) - 3.5) * 2.0;  // keep whiskers apart
      std::ostringstream path;
      bool first = true;
      for (int n : ns) {
        const auto it = summaries.find(Key{n, friction, kind.name, Tuning::kMaximumLikelihood});
        if (it == summaries.end() || it->second.count == 0) continue;
        const Summary& s = it->second;
        const double x = px(n) + dx;
        path << (first ? "M" : " L") << x << ' ' << py(s.mean);
        first = false;
        o << "<line x1=\"" << x << "\" y1=\"" << py(s.q25) << "\" x2=\"" << x << "\" y2=\""
          << py(s.q75) << "\" stroke=\"" << color << "\" stroke-width=\"1\"/>\n";
        o << "<circle cx=\"" << x << "\" cy=\"" << py(s.mean) << "\" r=\"3\" fill=\""
          << (kind.friction ? "white" : color) << "\" stroke=\"" << color << "\"/>\n";
      }
      if (!first) {
        o << "<path d=\"" << path.str() << "\" fill=\"none\" stroke=\"" << color
          << "\" stroke-width=\"1.5\"" << (kind.friction ? " stroke-dasharray=\"5,3\"" : "")
          << "/>\n";
      }
    }
  }
  const double lx = 2 * panel_w + gap + 10;
  for (size_t mi = 0; mi < Models().size(); ++mi) {
    const ModelKind& kind = Models()[mi];
    const double y = top + 10 + 20 * static_cast<double>(mi);
    o << "<line x1=\"" << lx << "\" y1=\"" << y << "\" x2=\"" << lx + 30 << "\" y2=\"" << y
      << "\" stroke=\"" << Color(kind.name) << "\" stroke-width=\"1.5\""
      << (kind.friction ? " stroke-dasharray=\"5,3\"" : "") << "/>\n";
    o << "<text x=\"" << lx + 36 << "\" y=\"" << y + 4 << "\">" << kind.name << "</text>\n";
  }
  o << "<text x=\"" << lx << "\" y=\"" << top + 180 << "\" font-size=\"10\">"
    << "mean over robots;</text>\n<text x=\"" << lx << "\" y=\"" << top + 193
    << "\" font-size=\"10\">bars: quartiles</text>\n";
  o << "</svg>\n";
  return o.str();
}

// ---- markdown -----------------------------------------------------------------------------

struct RunInfo {
  std::vector<int> ns;                  // the N that ran
  std::vector<double> seconds_per_n;    // wall-clock per N
  std::vector<double> cpu_per_n;        // CPU time per N (all threads)
  std::string stop_reason;              // empty when all requested N ran
  double total_seconds = 0.0;
  double total_cpu_seconds = 0.0;
  std::string command;
};

double MeanOf(const std::map<Key, Summary>& summaries, int n, bool friction,
              const std::string& model, Tuning tuning = Tuning::kMaximumLikelihood) {
  const auto it = summaries.find(Key{n, friction, model, tuning});
  return it == summaries.end() ? kNaN : it->second.mean;
}

std::string Ratio(double a, double b) {
  if (!std::isfinite(a) || !std::isfinite(b) || b == 0.0) return "—";
  std::ostringstream s;
  s << std::setprecision(3) << a / b;
  return s.str();
}

// Paired comparison of two models (ML-II) over the robots of one N and data set: "k/r", the
// number k of robots on which `a` has the smaller error, of the r robots where both ran.
std::string Wins(const std::vector<Record>& records, int n, bool friction, const std::string& a,
                 const std::string& b) {
  std::map<int, double> error_a, error_b;
  for (const Record& r : records) {
    if (r.n != n || r.data_friction != friction || r.tuning != Tuning::kMaximumLikelihood ||
        !std::isfinite(r.result.rms)) {
      continue;
    }
    if (r.model == a) error_a[r.robot] = r.result.rms;
    if (r.model == b) error_b[r.robot] = r.result.rms;
  }
  int wins = 0, both = 0;
  for (const auto& [robot, e] : error_a) {
    const auto it = error_b.find(robot);
    if (it == error_b.end()) continue;
    ++both;
    if (e < it->second) ++wins;
  }
  return both == 0 ? "—" : std::to_string(wins) + "/" + std::to_string(both);
}

std::string Markdown(const std::map<Key, Summary>& summaries, const std::vector<Record>& records,
                     const RunInfo& info, const Flags& f, const std::string& kept_discussion) {
  std::ostringstream o;
  o << "# Paper Section IV, Figs. 1 and 2: structured kernel vs. rbf, rbfs and motor models\n\n";
  o << "Generated by `experiments/paper_fig12.cc`:\n\n    " << info.command << "\n\n";
  o << "Setting (Cheng et al., Sec. IV, as far as stated there; the choices here are ours):\n\n";
  o << "- robots: " << f.robots << " random KDL robots per N (`sim::RandomRobot(N, seed)`, "
    << "base seed " << f.seed << "), N = " << info.ns.front() << ".." << info.ns.back() << ";\n";
  o << "- states: i.i.d. uniform, q in [-" << std::setprecision(4) << f.q_range << ", "
    << f.q_range << "] rad, qd in [-" << f.qd_range << ", " << f.qd_range
    << "] rad/s, qdd in [-" << f.qdd_range << ", " << f.qdd_range << "] rad/s^2; m = "
    << f.train << " training and " << f.test << " validation states per robot;\n";
  o << "- torques: KDL recursive Newton-Euler; with friction, per joint Coulomb F_c sign(qd) "
    << "and viscous F_v qd with F_c = u r_n, F_v = u' r_n / " << f.qd_range << " rad/s, u, u' ~ U["
    << f.friction_min << ", " << f.friction_max
    << "], r_n the RMS rigid-body torque of joint n;\n";
  o << "- one global scale per robot and data set so that max |tau| = 1 (noise-free, training and "
       "validation), then noise of std "
    << f.noise << " on the training torques;\n";
  o << "- error: mean over the validation states of N^(-1/2) ||f(x) - f_hat(x)||, against the "
       "noise-free torque f; cells are mean ± standard deviation over the robots; \"f (size)\" "
       "is the same measure for f_hat = 0 "
       "(quartiles in paper_fig12.csv, every run in paper_fig12_runs.csv);\n";
  o << "- hyper-parameters: type-II maximum likelihood (ML-II, LBFGS, at most "
    << f.ml_iterations << " iterations, " << f.fit_seconds
    << " s per fit) for every model; 5-fold blocked cross-validation on a grid of log sigma "
       "{-3..3, 5, 8} x sigma_n {0.005 .. 1} for the weight-space models;\n";
  o << "- forms: pol in weight space while D <= m (N <= 2), else in kernel form with "
       "`PolFormulaKernel` (+ the friction map's `FeatureKernel` through `SumKernel`); rbf "
       "and rbfs with one length scale per input (ARD), kernel form; motor in weight space.\n\n";
  o << "Ran N = ";
  for (size_t i = 0; i < info.ns.size(); ++i) {
    o << (i ? ", " : "") << info.ns[i] << " (" << std::fixed << std::setprecision(0)
      << info.seconds_per_n[i] << " s wall, " << info.cpu_per_n[i] << " s CPU)";
  }
  o << std::defaultfloat << "; total " << std::fixed << std::setprecision(0)
    << info.total_seconds << " s wall, " << info.total_cpu_seconds << " s CPU, " << f.threads
    << " threads." << std::defaultfloat;
  if (!info.stop_reason.empty()) o << " " << info.stop_reason;
  o << "\n\n";

  for (bool friction : {false, true}) {
    o << "## Data " << (friction ? "with" : "without") << " friction (ML-II)\n\n| N | f (size) |";
    for (const auto& m : Models()) o << ' ' << m.name << " |";
    o << "\n|---|---|";
    for (size_t i = 0; i < Models().size(); ++i) o << "---|";
    o << '\n';
    for (int n : info.ns) {
      o << "| " << n << " | "
        << Format(MeanOf(summaries, n, friction, kSignal)) << " |";
      for (const auto& m : Models()) {
        o << ' ' << Cell(summaries, Key{n, friction, m.name, Tuning::kMaximumLikelihood}) << " |";
      }
      o << '\n';
    }
    o << '\n';
  }

  if (f.cv) {
    o << "## Blocked 5-fold cross-validation (weight-space models)\n\n"
      << "| N | data | pol | pol+fri | motor | motor+fri |\n|---|---|---|---|---|---|\n";
    for (int n : info.ns) {
      for (bool friction : {false, true}) {
        o << "| " << n << " | " << (friction ? "friction" : "no friction") << " |";
        for (const char* m : {"pol", "pol+fri", "motor", "motor+fri"}) {
          const std::string cell = Cell(summaries, Key{n, friction, m, Tuning::kCrossValidation});
          o << ' ' << (cell.empty() ? "— (kernel form)" : cell) << " |";
        }
        o << '\n';
      }
    }
    o << '\n';
  }

  o << "## Time per fit (ML-II, fit + 15,000 predictions, mean over robots and both data sets, "
       "seconds)\n\n| N |";
  for (const auto& m : Models()) o << ' ' << m.name << " |";
  o << "\n|---|";
  for (size_t i = 0; i < Models().size(); ++i) o << "---|";
  o << '\n';
  for (int n : info.ns) {
    o << "| " << n << " |";
    for (const auto& m : Models()) {
      double t = 0.0;
      int c = 0;
      for (bool friction : {false, true}) {
        const auto it = summaries.find(Key{n, friction, m.name, Tuning::kMaximumLikelihood});
        if (it != summaries.end()) {
          t += it->second.seconds;
          ++c;
        }
      }
      std::ostringstream s;
      s << std::setprecision(2) << (c ? t / c : kNaN);
      o << ' ' << s.str() << " |";
    }
    o << '\n';
  }
  o << '\n';

  o << "## The paper's claims, checked on these numbers (ML-II)\n\n"
    << "Ratios of mean errors (above 1 favours the second model) and paired counts "
       "(robots on which the first model has the smaller error).\n\n"
    << "| N | best, no friction | rbf / pol | pol < rbf | rbf / rbfs | rbfs < rbf "
       "| best, friction | pol / pol+fri | pol+fri < rbfs+fri | pol+fri (friction) / pol "
       "(no friction) |\n"
    << "|---|---|---|---|---|---|---|---|---|---|\n";
  for (int n : info.ns) {
    std::string best[2];
    for (bool friction : {false, true}) {
      double best_value = std::numeric_limits<double>::infinity();
      for (const auto& m : Models()) {
        const double v = MeanOf(summaries, n, friction, m.name);
        if (std::isfinite(v) && v < best_value) {
          best_value = v;
          best[friction] = m.name;
        }
      }
    }
    o << "| " << n << " | " << best[0] << " | "
      << Ratio(MeanOf(summaries, n, false, "rbf"), MeanOf(summaries, n, false, "pol")) << " | "
      << Wins(records, n, false, "pol", "rbf") << " | "
      << Ratio(MeanOf(summaries, n, false, "rbf"), MeanOf(summaries, n, false, "rbfs")) << " | "
      << Wins(records, n, false, "rbfs", "rbf") << " | " << best[1] << " | "
      << Ratio(MeanOf(summaries, n, true, "pol"), MeanOf(summaries, n, true, "pol+fri"))
      << " | " << Wins(records, n, true, "pol+fri", "rbfs+fri") << " | "
      << Ratio(MeanOf(summaries, n, true, "pol+fri"), MeanOf(summaries, n, false, "pol"))
      << " |\n";
  }
  o << '\n';
  o << kDiscussionMarker << '\n';
  o << kept_discussion;
  return o.str();
}

// The text after the discussion marker of an existing file ("" when none).
std::string KeptDiscussion(const std::string& path) {
  std::ifstream in(path);
  if (!in) return "";
  std::stringstream buffer;
  buffer << in.rdbuf();
  const std::string text = buffer.str();
  const size_t at = text.find(kDiscussionMarker);
  if (at == std::string::npos) return "";
  size_t begin = at + std::char_traits<char>::length(kDiscussionMarker);
  if (begin < text.size() && text[begin] == '\n') ++begin;
  return text.substr(begin);
}

int Run(const Flags& f, const std::string& command) {
  RunInfo info;
  info.command = command;
  std::printf("paper_fig12: N = %d..%d, %d robots per N, m = %d, %d validation states, "
              "%d threads, budget %.0f CPU-seconds\n",
              f.n_min, f.n_max, f.robots, f.train, f.test, f.threads, f.budget_cpu_seconds);
  std::fflush(stdout);

  const auto start = std::chrono::steady_clock::now();
  std::vector<Record> records;
  std::mutex mutex;
  for (int n = f.n_min; n <= f.n_max; ++n) {
    // Start N only if it is expected to end within the budget: its CPU time predicted from
    // the last N by the growth between the last two (at least x1.5).
    const double used = CpuSeconds();
    if (!info.cpu_per_n.empty()) {
      const double last = info.cpu_per_n.back();
      double growth = 1.5;
      if (info.cpu_per_n.size() >= 2) {
        growth = std::max(growth, last / info.cpu_per_n[info.cpu_per_n.size() - 2]);
      }
      const double predicted = last * growth;
      if (used + predicted > f.budget_cpu_seconds) {
        std::ostringstream why;
        why << std::fixed << std::setprecision(0) << "Stopped before N = " << n << ": after "
            << used << " CPU-seconds, N = " << n << " was expected to take about " << predicted
            << " (N = " << n - 1 << " took " << last << ", growth x" << std::setprecision(1)
            << growth << "), beyond the budget of " << std::setprecision(0)
            << f.budget_cpu_seconds << " CPU-seconds (--budget-cpu-seconds).";
        info.stop_reason = why.str();
        std::printf("%s\n", info.stop_reason.c_str());
        break;
      }
    }
    const double cpu_start = CpuSeconds();
    const auto n_start = std::chrono::steady_clock::now();
    std::atomic<int> next{0};
    auto worker = [&]() {
      for (int r = next++; r < f.robots; r = next++) {
        const auto robot_start = std::chrono::steady_clock::now();
        std::vector<Record> local = RunRobot(n, r, f);
        std::lock_guard<std::mutex> lock(mutex);
        std::printf("N = %d, robot %d/%d (%s): %.1f s;", n, r + 1, f.robots,
                    local.front().robot_name.c_str(), Seconds(robot_start));
        for (const Record& rec : local) {
          if (rec.tuning == Tuning::kMaximumLikelihood && !rec.data_friction) {
            std::printf(" %s %.2e", rec.model.c_str(), rec.result.rms);
          }
        }
        std::printf("\n");
        std::fflush(stdout);
        records.insert(records.end(), local.begin(), local.end());
      }
    };
    std::vector<std::thread> pool;
    for (int t = 0; t < std::min(f.threads, f.robots); ++t) pool.emplace_back(worker);
    for (auto& t : pool) t.join();
    info.ns.push_back(n);
    info.seconds_per_n.push_back(Seconds(n_start));
    info.cpu_per_n.push_back(CpuSeconds() - cpu_start);
    std::printf("N = %d done in %.1f s wall, %.1f s CPU (total %.1f s wall, %.1f s CPU)\n", n,
                info.seconds_per_n.back(), info.cpu_per_n.back(), Seconds(start), CpuSeconds());
    std::fflush(stdout);
  }
  info.total_seconds = Seconds(start);
  info.total_cpu_seconds = CpuSeconds();
  if (info.ns.empty()) {
    std::fprintf(stderr, "paper_fig12: nothing ran\n");
    return 1;
  }

  std::sort(records.begin(), records.end(), [](const Record& a, const Record& b) {
    return std::tie(a.n, a.robot, a.data_friction, a.model, a.tuning) <
           std::tie(b.n, b.robot, b.data_friction, b.model, b.tuning);
  });
  const std::map<Key, Summary> summaries = SummarizeAll(records);
  std::filesystem::create_directories(f.out_dir);
  const std::string md_path = f.out_dir + "/paper_fig12.md";
  WriteTextAtomically(md_path, Markdown(summaries, records, info, f, KeptDiscussion(md_path)));
  WriteTextAtomically(f.out_dir + "/paper_fig12.csv", Csv(summaries));
  WriteTextAtomically(f.out_dir + "/paper_fig12_runs.csv", RunsCsv(records));
  WriteTextAtomically(f.out_dir + "/paper_fig12.svg", Svg(summaries, info.ns));
  std::printf("wrote %s/paper_fig12.{md,csv,svg} and paper_fig12_runs.csv\n", f.out_dir.c_str());

  if (f.check) {
    const double pol = MeanOf(summaries, 2, false, "pol");
    const double rbf = MeanOf(summaries, 2, false, "rbf");
    std::printf("check: N = 2 without friction, pol %.3e vs rbf %.3e\n", pol, rbf);
    if (!(pol < rbf)) {
      std::fprintf(stderr, "paper_fig12 --check: pol does not beat rbf at N = 2\n");
      return 3;
    }
  }
  return 0;
}

}  // namespace
}  // namespace structgp

int main(int argc, char** argv) {
  CLI::App app(
      "The simulation study of the paper's Section IV (Figs. 1 and 2): prediction error of "
      "pol, rbf, rbfs and motor, each alone and with friction, on random KDL robots.",
      "paper_fig12");
  structgp::Flags f;
  structgp::AddFlags(&app, &f);
  return structgp::RunProgram(&app, argc, argv, [&]() {
    structgp::FinishFlags(app, &f);
    return structgp::Run(f, structgp::CommandLine("paper_fig12", argc, argv));
  });
}
