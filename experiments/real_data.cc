// real_data: the models of the library on real robot logs, with contiguous time splits.
//
// Data sets (under --data-dir, see each README there):
//   sarcos  sarcos/sarcos_inv_test.csv.gz, 7 joints, 4,449 rows in trajectory order; train =
//           rows 1..3,560, test = rows 3,561..4,449 (the split its README recommends);
//   ur10    ur10-picknplace/train.csv.gz (9,879 rows) and test.csv.gz (2,470 rows that
//           follow in time), 6 joints.
// or any pair of files with --train-file, --test-file (and --name).
//
// Models (--models, default all):
//   linear      least squares per joint on (q, qd, qdd, sign(qd), 1), raw torques;
//   motor+fri   the motor baseline c1 qdd_n + c2 qd_n with the friction bases, weight space;
//   pol, pol+fri  the structured kernel k_pol (PolFormulaKernel) [+ the friction map as a
//               FeatureKernel through SumKernel] in kernel form; in weight space (the explicit
//               map, D = 1,151 + 7 at N = 3) when N <= --max-weight-space-joints;
//   pol+fri/nysM  Nystrom features of the fitted k_pol (M inducing states chosen by greedy
//               residual variance among the training rows, --nystrom) plus the friction
//               bases, weight space on every training row;
//   rbf, rbf+fri, rbfs, rbfs+fri  squared-exponential kernels with one length scale per
//               input (ARD) [+ friction], kernel form;
//   pol+rbf+fri k_pol + an ARD rbf + friction, kernel form (only when named in --models;
//               pol likewise).
//
// Targets: every GP model is fitted to the torques standardised per joint (training mean and
// standard deviation), and its predictions are mapped back; all joints share one kernel and
// one noise level (the library's single-posterior design). Hyper-parameters: type-II
// maximum likelihood (Ceres LBFGS) with at most --ml-iterations iterations and --ml-seconds
// of wall-clock time per fit; the kernel-form fits maximise the evidence of --ml-rows evenly
// spaced training rows, and the final kernel-form model uses at most --kernel-rows evenly
// spaced training rows (O(m^3) time, O(m^2) memory). The Nystrom models take the fitted
// k_pol parameters and friction prior of pol+fri, then fit their noise level by the
// weight-space evidence on all training rows.
//
// Reported per model: nMSE per joint = MSE_j / Var(test tau_j) and its mean, the mean of
// MSE_j / Var(train tau_j), fit time (wall-clock: every hyper-parameter fit, inducing-state
// selection and the final solve), prediction time for the whole test set and the CPU time
// of both. Also the coverage of the test part: per joint the fraction of test rows whose q,
// qd or qdd lies outside the training range, and the distance from test configurations to
// the nearest training configuration.
//
//   real_data [--data-dir=DIR] [--datasets=sarcos,ur10] [--models=a,b,...]
//             [--train-file=F --test-file=F --name=NAME] [--quick] [--check] [--verbose]
//             [--max-log-kernel-parameter=V] [--scale-rates] [--out=FILE.md] [--csv=FILE.csv]
//   (--help lists every flag; docs/real_data.md has the results.)
//
// --quick: a CI-size run on a tiny slice (300 training and 100 test rows, evenly spaced over
// each part; 10 LBFGS iterations; Nystrom M = 32). Exit status 77 when the data directory has
// none of the data sets (ctest marks the test skipped). --check exits with status 3 unless
// every model gives a finite error and pol+fri has a mean nMSE (by the training variance)
// below kCheckMaxNmse on every data set.

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iomanip>
#include <limits>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/QR>

#include "experiment_program.h"
#include "kernel_mean.h"
#include "structgp/core/status.h"
#include "structgp/core/types.h"
#include "structgp/feature/friction_feature_map.h"
#include "structgp/kernel/nystrom_feature_map.h"
#include "structgp/feature/pol_feature_map.h"
#include "structgp/feature/sum_feature_map.h"
#include "structgp/fit/fit_model.h"
#include "structgp/hyper/evidence.h"
#include "structgp/feature/feature_hyperparameters.h"
#include "structgp/hyper/marginal_likelihood.h"
#include "structgp/io/atomic_file.h"
#include "structgp/io/csv.h"
#include "structgp/io/robot_data.h"
#include "structgp/kernel/feature_kernel.h"
#include "structgp/kernel/pol_kernel.h"
#include "structgp/kernel/rbf_kernel.h"
#include "structgp/kernel/sum_kernel.h"
#include "structgp/model/model_spec.h"
#include "structgp/model/robot_model.h"
#include "structgp/model/sufficient_statistics.h"
#include "structgp/model/weight_space_gp.h"
#include "timing.h"

namespace structgp {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
// Exit status that ctest reads as "skipped" (SKIP_RETURN_CODE).
constexpr int kExitSkipped = 77;
// --check: largest mean nMSE (MSE_j / Var(train tau_j)) of pol+fri. Predicting the training
// mean scores about 1 or more; the --quick slices give about 0.14 (SARCOS) and 0.38 (UR10).
constexpr double kCheckMaxNmse = 0.6;

struct Flags {
  std::string data_dir = "../shared/data";
  std::vector<std::string> datasets = {"sarcos", "ur10"};
  std::string train_file, test_file, name = "custom";
  std::vector<std::string> models;  // empty = all
  std::vector<int> nystrom = {256, 512, 1024};
  int ml_rows = 1000;
  int kernel_rows = 4000;
  int ml_iterations = 100;
  double ml_seconds = 120.0;
  int max_weight_space_joints = 3;
  double max_log_kernel_parameter = 12.0;
  bool scale_rates = false;
  int max_train = 0;  // 0 = all
  int max_test = 0;
  bool quick = false;
  bool check = false;
  bool verbose = false;
  std::string out, csv;
};

// The flags of the program, bound to *f.
void AddFlags(CLI::App* app, Flags* f) {
  AddFlag(app, "--data-dir", &f->data_dir, "directory with sarcos/ and ur10-picknplace/");
  AddListFlag(app, "--datasets", &f->datasets, "sarcos, ur10 (default both)");
  AddFlag(app, "--train-file", &f->train_file, "a robot CSV file to train on instead");
  AddFlag(app, "--test-file", &f->test_file, "a robot CSV file to test on (with --train-file)");
  AddFlag(app, "--name", &f->name, "name of the --train-file/--test-file data set");
  AddListFlag(app, "--models", &f->models,
              "linear, motor+fri, pol, pol+fri, pol+fri/nys<M>, rbf, rbf+fri, rbfs, rbfs+fri, "
              "pol+rbf+fri (default all but pol and pol+rbf+fri)");
  AddFlag(app, "--nystrom", &f->nystrom, "inducing states of the Nystrom models")
      ->delimiter(',')
      ->check(GreaterThan(0));
  AddFlag(app, "--ml-rows", &f->ml_rows,
          "evenly spaced training rows for kernel-form ML-II (0 = all)")
      ->check(AtLeast(0));
  AddFlag(app, "--kernel-rows", &f->kernel_rows,
          "largest kernel-form training set, evenly spaced rows")
      ->check(AtLeast(0));
  AddFlag(app, "--ml-iterations", &f->ml_iterations, "LBFGS iterations per ML-II fit")
      ->check(AtLeast(0));
  AddFlag(app, "--ml-seconds", &f->ml_seconds, "wall-clock limit per ML-II fit")
      ->check(GreaterThan(0));
  AddFlag(app, "--max-weight-space-joints", &f->max_weight_space_joints,
          "pol in weight space up to this many joints")
      ->check(AtLeast(0));
  AddFlag(app, "--max-log-kernel-parameter", &f->max_log_kernel_parameter,
          "upper bound of every kernel-form log hyper-parameter");
  AddFlag(app, "--max-train", &f->max_train, "this many evenly spaced training rows only (0 = all)")
      ->check(AtLeast(0));
  AddFlag(app, "--max-test", &f->max_test, "this many evenly spaced test rows only (0 = all)")
      ->check(AtLeast(0));
  app->add_flag("--quick", f->quick, "tiny slice (300 / 100 rows, 10 iterations, M = 32)");
  app->add_flag("--check", f->check,
                "exit 3 unless all errors are finite and pol+fri has a mean nMSE (by the "
                "training variance) below 0.6");
  app->add_flag("--verbose", f->verbose, "print the fitted hyper-parameters of every model");
  app->add_flag("--scale-rates", f->scale_rates,
                "divide every qd and qdd column by its training std (q as is)");
  AddFlag(app, "--out", &f->out, "write the tables to this .md file (atomically)");
  AddFlag(app, "--csv", &f->csv, "write the results to this .csv file (atomically)");
}

// Applies --quick (where the flags it sets were not given) and checks the flags together.
// Throws std::invalid_argument naming the bad flag.
void FinishFlags(const CLI::App& app, Flags* f) {
  if (f->train_file.empty() != f->test_file.empty()) {
    throw std::invalid_argument("--train-file and --test-file go together");
  }
  if (f->quick) {
    if (f->max_train == 0) f->max_train = 300;
    if (f->max_test == 0) f->max_test = 100;
    if (app.count("--ml-iterations") == 0) f->ml_iterations = 10;
    if (app.count("--nystrom") == 0) f->nystrom = {32};
  }
  if (f->ml_iterations < 1 || f->kernel_rows < 10 || !(f->ml_seconds > 0.0)) {
    throw std::invalid_argument(
        "expected --ml-iterations >= 1, --kernel-rows >= 10 and --ml-seconds > 0");
  }
  if (!std::isfinite(f->max_log_kernel_parameter)) {
    throw std::invalid_argument("expected a finite --max-log-kernel-parameter");
  }
  for (const std::string& d : f->datasets) {
    if (d != "sarcos" && d != "ur10") {
      throw std::invalid_argument("--datasets: unknown data set '" + d + "' (sarcos, ur10)");
    }
  }
}

// ---- data ---------------------------------------------------------------------------------

// The rows 0, s, 2s, ... with the stride s chosen so that at most `count` rows are taken,
// spread over the whole set (count <= 0 or >= rows: all).
std::vector<int> EvenlySpaced(int rows, int count) {
  std::vector<int> index;
  if (count <= 0 || count >= rows) {
    for (int i = 0; i < rows; ++i) index.push_back(i);
    return index;
  }
  for (int k = 0; k < count; ++k) {
    index.push_back(static_cast<int>(static_cast<long long>(k) * rows / count));
  }
  return index;
}

Matrix TakeRows(const Matrix& A, const std::vector<int>& index) {
  Matrix B(static_cast<Eigen::Index>(index.size()), A.cols());
  for (size_t i = 0; i < index.size(); ++i) B.row(static_cast<Eigen::Index>(i)) = A.row(index[i]);
  return B;
}

// RobotData restricted to EvenlySpaced(data.size(), count).
RobotData EvenlySpacedRows(const RobotData& data, int count) {
  if (count <= 0 || count >= data.size()) return data;
  const std::vector<int> index = EvenlySpaced(data.size(), count);
  RobotData out;
  out.num_joints = data.num_joints;
  out.X = TakeRows(data.X, index);
  out.Y = TakeRows(data.Y, index);
  out.source = data.source;
  if (data.has_time()) {
    out.t.resize(static_cast<Eigen::Index>(index.size()));
    for (size_t i = 0; i < index.size(); ++i)
      out.t[static_cast<Eigen::Index>(i)] = data.t[index[i]];
  }
  if (data.line.size() > 0) {
    out.line.resize(static_cast<Eigen::Index>(index.size()));
    for (size_t i = 0; i < index.size(); ++i) {
      out.line[static_cast<Eigen::Index>(i)] = data.line[index[i]];
    }
  }
  return out;
}

Vector ColumnStd(const Matrix& X);

struct Split {
  std::string name;
  std::string description;
  RobotData train, test;
};

std::vector<Split> LoadSplits(const Flags& f) {
  std::vector<Split> splits;
  auto limit = [&](Split* s) {
    s->train = EvenlySpacedRows(s->train, f.max_train);
    s->test = EvenlySpacedRows(s->test, f.max_test);
    if (f.scale_rates) {
      const int n = s->train.num_joints;
      const Vector sd = ColumnStd(s->train.X).tail(2 * n);
      for (int c = 0; c < 2 * n; ++c) {
        s->train.X.col(n + c) /= sd[c];
        s->test.X.col(n + c) /= sd[c];
      }
      s->description += "; qd and qdd divided by their training std";
    }
  };
  if (!f.train_file.empty()) {
    Split s;
    s.name = f.name;
    s.train = ReadRobotCsv(f.train_file);
    s.test = ReadRobotCsv(f.test_file);
    if (s.train.num_joints != s.test.num_joints) {
      throw std::invalid_argument(f.test_file + ": " + std::to_string(s.test.num_joints) +
                                  " joints, but " + f.train_file + " has " +
                                  std::to_string(s.train.num_joints));
    }
    s.description = f.train_file + " / " + f.test_file;
    limit(&s);
    splits.push_back(std::move(s));
    return splits;
  }
  for (const std::string& d : f.datasets) {
    Split s;
    s.name = d;
    if (d == "sarcos") {
      const std::string path = f.data_dir + "/sarcos/sarcos_inv_test.csv.gz";
      if (!std::filesystem::exists(path)) continue;
      const RobotData all = ReadRobotCsv(path);
      // The split of the data set's README: rows 1..3,560 train, 3,561..4,449 test.
      const int train_rows = std::min(3560, all.size() - 1);
      s.train = all.Rows(0, train_rows);
      s.test = all.Rows(train_rows, all.size() - train_rows);
      s.description = "SARCOS (real, 7 joints): rows 1-" + std::to_string(train_rows) + " train, " +
                      std::to_string(train_rows + 1) + "-" + std::to_string(all.size()) + " test";
    } else {
      const std::string dir = f.data_dir + "/ur10-picknplace";
      if (!std::filesystem::exists(dir + "/train.csv.gz")) continue;
      s.train = ReadRobotCsv(dir + "/train.csv.gz");
      s.test = ReadRobotCsv(dir + "/test.csv.gz");
      s.description = "UR10 pick-and-place (real, 6 joints, 5 kg load): train.csv.gz (" +
                      std::to_string(s.train.size()) + " rows), test.csv.gz (" +
                      std::to_string(s.test.size()) + " rows, later in time)";
    }
    limit(&s);
    splits.push_back(std::move(s));
  }
  return splits;
}

// ---- models -------------------------------------------------------------------------------

struct Result {
  std::string model;
  std::string form;
  int train_rows = 0;  // rows the final model uses
  Vector nmse;         // per joint, by the test variance
  double mean_nmse = kNaN;
  double mean_nmse_train_var = kNaN;
  double fit_seconds = kNaN;
  double predict_seconds = kNaN;
  // CPU time of this process over the whole fit and prediction (all threads).
  double cpu_seconds = kNaN;
  std::string note;
};

// Per-joint standardisation of the torques by the training mean and standard deviation.
struct Standardizer {
  Eigen::RowVectorXd mean, std;
  explicit Standardizer(const Matrix& Y) {
    mean = Y.colwise().mean();
    std =
        ((Y.rowwise() - mean).colwise().squaredNorm() / static_cast<double>(Y.rows())).cwiseSqrt();
    for (Eigen::Index j = 0; j < std.size(); ++j) {
      if (!(std[j] > 0.0)) std[j] = 1.0;
    }
  }
  Matrix Forward(const Matrix& Y) const {
    return (Y.rowwise() - mean).array().rowwise() / std.array();
  }
  Matrix Backward(const Matrix& Z) const {
    return (Z.array().rowwise() * std.array()).matrix().rowwise() + mean;
  }
};

Eigen::RowVectorXd ColumnVariance(const Matrix& Y) {
  const Eigen::RowVectorXd mean = Y.colwise().mean();
  return (Y.rowwise() - mean).colwise().squaredNorm() / static_cast<double>(Y.rows());
}

void Score(const Split& s, const Matrix& prediction, Result* r) {
  const Matrix& Y = s.test.Y;
  const int n = static_cast<int>(Y.cols());
  const Eigen::RowVectorXd test_var = ColumnVariance(Y);
  const Eigen::RowVectorXd train_var = ColumnVariance(s.train.Y);
  r->nmse.resize(n);
  double sum = 0.0, sum_train = 0.0;
  for (int j = 0; j < n; ++j) {
    const double mse = (Y.col(j) - prediction.col(j)).squaredNorm() / static_cast<double>(Y.rows());
    r->nmse[j] = mse / test_var[j];
    sum += r->nmse[j];
    sum_train += mse / train_var[j];
  }
  r->mean_nmse = sum / n;
  r->mean_nmse_train_var = sum_train / n;
}

MaximumLikelihoodOptions MlOptions(const Flags& f) {
  MaximumLikelihoodOptions o;
  o.max_iterations = f.ml_iterations;
  // f = -log p / (m N) is of order one: a relative change of 1e-7 or a gradient of 1e-4 is far
  // below what moves the test error.
  o.gradient_tolerance = 1e-4;
  o.function_tolerance = 1e-7;
  o.max_seconds = f.ml_seconds;
  o.kernel_parameter_bounds.upper = f.max_log_kernel_parameter;
  return o;
}

std::string MlNote(const MaximumLikelihoodSummary& s) {
  std::ostringstream o;
  o << ToString(s.termination) << ", " << s.iterations << " it., " << std::fixed
    << std::setprecision(1) << s.elapsed_seconds << " s";
  return o.str();
}

Result FitLinear(const Split& s) {
  Result r;
  r.model = "linear";
  r.form = "least squares";
  const int n = s.train.num_joints;
  auto design = [n](const Matrix& X) {
    Matrix A(X.rows(), 4 * n + 1);
    A.leftCols(3 * n) = X;
    for (Eigen::Index i = 0; i < X.rows(); ++i) {
      for (int j = 0; j < n; ++j) {
        const double v = X(i, n + j);
        A(i, 3 * n + j) = static_cast<double>((v > 0.0) - (v < 0.0));
      }
    }
    A.col(4 * n).setOnes();
    return A;
  };
  const auto start = std::chrono::steady_clock::now();
  const Matrix coef = design(s.train.X).colPivHouseholderQr().solve(s.train.Y);
  r.fit_seconds = Seconds(start);
  r.train_rows = s.train.size();
  const auto predict_start = std::chrono::steady_clock::now();
  const Matrix prediction = design(s.test.X) * coef;
  r.predict_seconds = Seconds(predict_start);
  Score(s, prediction, &r);
  return r;
}

// Weight-space fit of a feature map on standardised targets Z: ML-II over the shape, block
// scales and noise from *hyper, which receives the result. Used by the Nystrom models, whose
// map (Nystrom features of a fitted k_pol plus friction) is not a ModelSpec that FitModel
// could build.
MaximumLikelihoodSummary FitWeightSpaceEvidence(std::shared_ptr<const FeatureMap> map,
                                                const Matrix& Phi, const Matrix& Z,
                                                Hyperparameters* hyper, const Flags& f,
                                                bool noise_only = false) {
  SufficientStatistics stats(map->dim(), static_cast<int>(Z.cols()));
  stats.Accumulate(Phi, Z);
  WeightSpaceEvidence evidence(map, stats);
  MaximumLikelihoodOptions options = MlOptions(f);
  if (noise_only) {
    options.optimize_shape = false;
    options.optimize_block_scales = false;
  }
  return FitHyperparameters(evidence, options, hyper);
}

// Prediction of a weight-space model for every row of X.
Matrix PredictWeightSpace(const FeatureMap& map, const WeightSpaceGP& gp, const Matrix& X) {
  Matrix prediction(X.rows(), gp.num_outputs());
  Vector phi(map.dim()), mean(gp.num_outputs());
  WeightSpaceGP::Workspace workspace = gp.MakeWorkspace();
  for (Eigen::Index i = 0; i < X.rows(); ++i) {
    map.Evaluate(X.row(i).transpose(), phi);
    gp.Predict(phi, mean, workspace);
    prediction.row(i) = mean.transpose();
  }
  return prediction;
}

// motor+fri, or pol(+fri) with the explicit map, in weight space: the library's FitModel (ML-II
// over the shape, block scales and noise from the default hyper-parameters of the
// standardised targets, output scales held).
Result FitRobotModelWeightSpace(const Split& s, const std::string& model_name, const Flags& f) {
  Result r;
  r.model = model_name;
  const Standardizer standardizer(s.train.Y);
  const Matrix Z = standardizer.Forward(s.train.Y);
  const auto start = std::chrono::steady_clock::now();
  FitOptions options;
  options.model.form = Form::kWeightSpace;
  options.method = HyperparameterMethod::kEvidence;
  options.evidence = MlOptions(f);
  options.profile_noise_and_scales = false;
  const FittedModel fit = FitModel(ParseModelSpec(model_name), s.train.X, Z, Vector(), options);
  r.form = "weight space, D = " + std::to_string(fit.model.feature_map()->dim());
  std::ostringstream note;
  note << "ML-II " << ToString(fit.summary.termination) << ", " << fit.summary.iterations
       << " it., " << std::fixed << std::setprecision(1) << fit.summary.hyperparameter_seconds
       << " s";
  r.note = note.str();
  if (!fit.summary.IsUsable()) {
    r.note += ": " + fit.summary.message;
    return r;
  }
  r.fit_seconds = Seconds(start);
  r.train_rows = s.train.size();
  const auto predict_start = std::chrono::steady_clock::now();
  Matrix prediction;
  fit.model.PredictRows(s.test.X, &prediction);
  r.predict_seconds = Seconds(predict_start);
  Score(s, standardizer.Backward(prediction), &r);
  return r;
}

Vector ColumnStd(const Matrix& X) {
  const Eigen::RowVectorXd mean = X.colwise().mean();
  Vector sd = ((X.rowwise() - mean).colwise().squaredNorm() / static_cast<double>(X.rows()))
                  .cwiseSqrt()
                  .transpose();
  for (Eigen::Index i = 0; i < sd.size(); ++i) {
    if (!(sd[i] > 1e-9)) sd[i] = 1.0;
  }
  return sd;
}

std::shared_ptr<const FrictionFeatureMap> FrictionMap(int n) {
  return std::make_shared<FrictionFeatureMap>(n, RobotModelOptions().friction_width);
}

// The kernel of a kernel-form model with starting values from the (standardised) data: pol
// at its defaults; rbf length scales = the inputs' spreads (1 for the angles of rbfs), unit
// signal std; friction with a unit prior std of its coefficients.
std::unique_ptr<Kernel> MakeKernel(const std::string& base, bool friction, const Matrix& X, int n) {
  std::unique_ptr<Kernel> k;
  const Vector spread = ColumnStd(X);
  if (base == "pol+rbf") {
    // The structured kernel plus an ARD rbf for what it cannot express; the rbf starts small.
    const PolFormulaKernel pol(n);
    RbfKernel rbf(3 * n, /*ard=*/true);
    Vector theta(3 * n + 1);
    theta << spread.array().log().matrix(), std::log(0.3);
    rbf = Reparameterized(rbf, theta);
    k = std::make_unique<SumKernel>(std::vector<const Kernel*>{&pol, &rbf});
  } else if (base == "pol") {
    k = std::make_unique<PolFormulaKernel>(n);
  } else if (base == "rbf") {
    auto rbf = std::make_unique<RbfKernel>(3 * n, /*ard=*/true);
    Vector theta(3 * n + 1);
    theta << spread.array().log().matrix(), 0.0;
    k = rbf->WithParameters(theta);
  } else {
    auto rbfs = std::make_unique<RbfsKernel>(n, /*ard=*/true);
    Vector theta(3 * n + 1);
    theta << Vector::Zero(n), spread.tail(2 * n).array().log().matrix(), 0.0;
    k = rbfs->WithParameters(theta);
  }
  if (!friction) return k;
  const auto map = FrictionMap(n);
  const FeatureKernel fri(map, DefaultHyperparameters(*map, n));
  return std::make_unique<SumKernel>(std::vector<const Kernel*>{k.get(), &fri});
}

// The kernel-form fits stay here rather than in FitModel: ARD rbf/rbfs kernels started from
// the inputs' spreads, pol+rbf sums and a friction prior fixed at unit std are comparisons
// this experiment makes, not models the library's ModelSpec offers.

// What a kernel-form fit leaves for the Nystrom models.
struct KernelFit {
  std::unique_ptr<Kernel> kernel;
  Hyperparameters hyper;
  double ml_seconds = 0.0;
  bool ok = false;
};

Result FitKernelForm(const Split& s, const std::string& model_name, const Flags& f,
                     KernelFit* keep) {
  Result r;
  r.model = model_name;
  const int n = s.train.num_joints;
  const bool friction =
      model_name.size() > 4 && model_name.compare(model_name.size() - 4, 4, "+fri") == 0;
  const std::string base = friction ? model_name.substr(0, model_name.size() - 4) : model_name;
  const Standardizer standardizer(s.train.Y);
  const Matrix Z = standardizer.Forward(s.train.Y);
  const auto start = std::chrono::steady_clock::now();
  std::unique_ptr<Kernel> kernel = MakeKernel(base, friction, s.train.X, n);
  Hyperparameters hyper = DefaultHyperparameters(*kernel, n);
  const std::vector<int> ml_index = EvenlySpaced(s.train.size(), f.ml_rows);
  const Matrix X_ml = TakeRows(s.train.X, ml_index), Z_ml = TakeRows(Z, ml_index);
  const MaximumLikelihoodSummary ml =
      FitKernelHyperparameters(*kernel, X_ml, Z_ml, MlOptions(f), &hyper);
  const double ml_seconds = Seconds(start);
  std::ostringstream note;
  note << "ML-II on " << ml_index.size() << " rows: " << MlNote(ml);
  r.note = note.str();
  if (!ml.usable()) return r;
  kernel = kernel->WithParameters(hyper.shape);
  if (f.verbose) {
    const std::vector<std::string> names = kernel->parameter_names();
    std::printf("%s fitted:", model_name.c_str());
    for (size_t i = 0; i < names.size(); ++i) {
      std::printf(" %s=%.4g", names[i].c_str(),
                  hyper.shape[static_cast<Eigen::Index>(i)]);
    }
    std::printf(" log_noise_std=%.4g; %s\n", hyper.log_noise_std, ml.BriefReport().c_str());
  }

  const std::vector<int> index = EvenlySpaced(s.train.size(), f.kernel_rows);
  const Matrix X = TakeRows(s.train.X, index), Y = TakeRows(Z, index);
  r.train_rows = static_cast<int>(index.size());
  r.form = "kernel form";
  if (r.train_rows < s.train.size()) r.form += ", evenly spaced rows";
  // Outputs share the kernel; output j has prior s_j^2 k and noise s_j^2 sigma_n^2, so the
  // posterior mean of every output uses the same (K + sigma_n^2 I)^{-1}.
  Matrix alpha;
  if (!SolveKernelSystem(*kernel, X, Y, std::exp(2.0 * hyper.log_noise_std), &alpha)) {
    r.note += "; K + sigma_n^2 I not positive definite";
    return r;
  }
  r.fit_seconds = Seconds(start);

  const auto predict_start = std::chrono::steady_clock::now();
  const Matrix prediction = KernelMean(*kernel, X, alpha, s.test.X);
  r.predict_seconds = Seconds(predict_start);
  Score(s, standardizer.Backward(prediction), &r);
  if (keep != nullptr) {
    keep->kernel = std::move(kernel);
    keep->hyper = hyper;
    keep->ml_seconds = ml_seconds;
    keep->ok = true;
  }
  return r;
}

// pol+fri with M Nystrom features of the k_pol part of a fitted pol+fri kernel, plus the
// friction bases; the noise level by the weight-space evidence on every training row.
Result FitNystrom(const Split& s, int M, const KernelFit& pol_fri, const Flags& f) {
  Result r;
  r.model = "pol+fri/nys" + std::to_string(M);
  const int n = s.train.num_joints;
  if (!pol_fri.ok) {
    r.note = "needs the pol+fri kernel-form fit, which failed";
    return r;
  }
  const Standardizer standardizer(s.train.Y);
  const Matrix Z = standardizer.Forward(s.train.Y);
  const auto start = std::chrono::steady_clock::now();
  const auto& sum = dynamic_cast<const SumKernel&>(*pol_fri.kernel);
  const Kernel& pol = sum.part(0);
  const Matrix inducing = SelectInducingStates(pol, s.train.X, M);
  auto nystrom = std::make_shared<NystromFeatureMap>(pol, inducing);
  const auto friction = FrictionMap(n);
  auto map = std::make_shared<SumFeatureMap>(
      std::vector<std::shared_ptr<const FeatureMap>>{nystrom, friction});
  r.form = "weight space, D = " + std::to_string(map->dim());
  // Start: the kernel-form fit's friction prior and noise.
  Hyperparameters hyper = DefaultHyperparameters(*map, n);
  const Vector kp = pol_fri.hyper.shape;
  const int fri_begin = pol.num_parameters();
  const int fri_blocks = static_cast<int>(hyper.log_block_scale.size()) - 1;
  for (int b = 0; b < fri_blocks; ++b) {
    hyper.log_block_scale[1 + b] = kp[fri_begin + b];
  }
  hyper.log_noise_std = pol_fri.hyper.log_noise_std;
  hyper.log_output_scale = pol_fri.hyper.log_output_scale;
  Matrix Phi;
  map->EvaluateRows(s.train.X, &Phi);
  // The Nystrom model approximates the fitted kernel-form model: it keeps its kernel and
  // friction prior and refits the noise only (the approximation drops some variance).
  const MaximumLikelihoodSummary ml =
      FitWeightSpaceEvidence(map, Phi, Z, &hyper, f, /*noise_only=*/true);
  std::ostringstream note;
  note << static_cast<int>(inducing.rows()) << " inducing states; k_pol from pol+fri ("
       << std::fixed << std::setprecision(1) << pol_fri.ml_seconds
       << " s, included); noise by ML-II " << MlNote(ml);
  r.note = note.str();
  if (!ml.usable()) return r;
  WeightSpaceGP gp(PriorVariance(*map, hyper), hyper.noise_variance(), n, hyper.output_scales());
  if (gp.Fit(Phi, Z) != Status::kOk) {
    r.note += "; fit failed";
    return r;
  }
  r.fit_seconds = Seconds(start) + pol_fri.ml_seconds;
  r.train_rows = s.train.size();
  const auto predict_start = std::chrono::steady_clock::now();
  const Matrix prediction = PredictWeightSpace(*map, gp, s.test.X);
  r.predict_seconds = Seconds(predict_start);
  Score(s, standardizer.Backward(prediction), &r);
  return r;
}

// ---- output -------------------------------------------------------------------------------

std::string Num(double v, int precision = 3) {
  if (!std::isfinite(v)) return "—";
  std::ostringstream o;
  o << std::setprecision(precision) << v;
  return o.str();
}

std::string Fixed(double v, int decimals) {
  if (!std::isfinite(v)) return "—";
  std::ostringstream o;
  o << std::fixed << std::setprecision(decimals) << v;
  return o.str();
}

// Per joint: the fraction of test rows with q_j, resp. qd_j, outside the training range.
std::string CoverageTable(const Split& s) {
  const int n = s.train.num_joints;
  std::ostringstream o;
  o << "| joint |";
  for (int j = 1; j <= n; ++j) o << ' ' << j << " |";
  o << "\n|---|";
  for (int j = 0; j < n; ++j) o << "---|";
  o << '\n';
  for (int block = 0; block < 3; ++block) {
    const char* label[] = {"test q outside train range", "test qd outside train range",
                           "test qdd outside train range"};
    o << "| " << label[block] << " |";
    for (int j = 0; j < n; ++j) {
      const int c = block * n + j;
      const double lo = s.train.X.col(c).minCoeff(), hi = s.train.X.col(c).maxCoeff();
      int outside = 0;
      for (Eigen::Index i = 0; i < s.test.X.rows(); ++i) {
        const double v = s.test.X(i, c);
        if (v < lo || v > hi) ++outside;
      }
      o << ' ' << Fixed(100.0 * outside / static_cast<double>(s.test.size()), 1) << "% |";
    }
    o << '\n';
  }
  // Joint-space coverage: distance (rad, Euclidean over the N angles) from each test
  // configuration to the nearest training configuration, against the same for training
  // rows to their nearest other training row more than 50 rows away in time.
  auto nearest = [&](const Matrix& A, int i, const Matrix& B, int skip_near) {
    double best = std::numeric_limits<double>::infinity();
    for (Eigen::Index k = 0; k < B.rows(); ++k) {
      if (skip_near >= 0 && std::abs(static_cast<int>(k) - i) <= skip_near) continue;
      best = std::min(best, (A.row(i) - B.row(k)).squaredNorm());
    }
    return std::sqrt(best);
  };
  const Matrix q_train = s.train.X.leftCols(n), q_test = s.test.X.leftCols(n);
  std::vector<double> test_d, train_d;
  for (int i = 0; i < q_test.rows(); ++i) test_d.push_back(nearest(q_test, i, q_train, -1));
  const std::vector<int> probe = EvenlySpaced(static_cast<int>(q_train.rows()), 500);
  for (int i : probe) train_d.push_back(nearest(q_train, i, q_train, 50));
  auto quantile = [](std::vector<double> v, double p) {
    std::sort(v.begin(), v.end());
    return v.empty() ? kNaN : v[static_cast<size_t>(p * static_cast<double>(v.size() - 1))];
  };
  o << "\nNearest training configuration q (rad, all joints): test rows median "
    << Num(quantile(test_d, 0.5)) << ", 90% " << Num(quantile(test_d, 0.9)) << ", max "
    << Num(quantile(test_d, 1.0)) << "; training rows (500 evenly spaced, to rows more than 50 "
    << "steps away) median " << Num(quantile(train_d, 0.5)) << ", 90% "
    << Num(quantile(train_d, 0.9)) << ".\n";
  return o.str();
}

std::string Table(const Split& s, const std::vector<Result>& results) {
  const int n = s.train.num_joints;
  std::ostringstream o;
  o << "### " << s.name << "\n\n"
    << s.description << "; " << s.train.size() << " training and " << s.test.size()
    << " test rows.\n\n";
  o << "| model | form | rows used |";
  for (int j = 1; j <= n; ++j) o << " nMSE " << j << " |";
  o << " mean nMSE | mean (train var) | fit s | predict s | CPU s | note |\n|---|---|---|";
  for (int j = 0; j < n; ++j) o << "---|";
  o << "---|---|---|---|---|---|\n";
  for (const Result& r : results) {
    o << "| " << r.model << " | " << r.form << " | " << r.train_rows << " |";
    for (int j = 0; j < n; ++j) o << ' ' << (r.nmse.size() > j ? Num(r.nmse[j]) : "—") << " |";
    o << ' ' << Num(r.mean_nmse) << " | " << Num(r.mean_nmse_train_var) << " | "
      << Fixed(r.fit_seconds, 2) << " | " << Fixed(r.predict_seconds, 3) << " | "
      << Fixed(r.cpu_seconds, 1) << " | " << r.note << " |\n";
  }
  o << "\nCoverage of the test part by the training part:\n\n" << CoverageTable(s) << '\n';
  return o.str();
}

std::string CsvRows(const Split& s, const std::vector<Result>& results) {
  std::ostringstream o;
  o << std::setprecision(6);
  for (const Result& r : results) {
    o << s.name << ',' << r.model << ',' << r.train_rows << ',' << r.mean_nmse << ','
      << r.mean_nmse_train_var << ',' << r.fit_seconds << ',' << r.predict_seconds << ','
      << r.cpu_seconds << ',';
    for (Eigen::Index j = 0; j < r.nmse.size(); ++j) o << (j ? ";" : "") << r.nmse[j];
    o << '\n';
  }
  return o.str();
}

bool Selected(const Flags& f, const std::string& model) {
  if (f.models.empty()) return model != "pol" && model != "pol+rbf+fri";
  return std::find(f.models.begin(), f.models.end(), model) != f.models.end();
}

int Run(const Flags& f, const std::string& command) {
  const std::vector<Split> splits = LoadSplits(f);
  if (splits.empty()) {
    std::printf("real_data: no data set found under %s; skipped\n", f.data_dir.c_str());
    return kExitSkipped;
  }
  std::ostringstream md, csv;
  md << "Command: `" << command << "`\n\n";
  csv << "dataset,model,train_rows,mean_nmse,mean_nmse_train_var,fit_seconds,predict_seconds,"
         "cpu_seconds,nmse_per_joint\n";
  bool check_ok = true;
  for (const Split& s : splits) {
    const int n = s.train.num_joints;
    std::printf("== %s: %s; %d train, %d test rows\n", s.name.c_str(), s.description.c_str(),
                s.train.size(), s.test.size());
    std::fflush(stdout);
    std::vector<Result> results;
    auto run = [&](const std::string& name, auto fit) {
      if (!Selected(f, name)) return;
      Result r;
      const double cpu_start = CpuSeconds();
      try {
        r = fit();
      } catch (const std::exception& e) {
        r.model = name;
        r.note = std::string("error: ") + e.what();
      }
      r.cpu_seconds = CpuSeconds() - cpu_start;
      std::printf(
          "%-16s mean nMSE %-9s (train var %-9s) fit %8.2f s predict %7.3f s cpu %8.2f s  %s\n",
          r.model.c_str(), Num(r.mean_nmse).c_str(), Num(r.mean_nmse_train_var).c_str(),
          r.fit_seconds, r.predict_seconds, r.cpu_seconds, r.note.c_str());
      std::fflush(stdout);
      if (f.check && !std::isfinite(r.mean_nmse)) check_ok = false;
      results.push_back(std::move(r));
    };
    run("linear", [&] { return FitLinear(s); });
    run("motor+fri", [&] { return FitRobotModelWeightSpace(s, "motor+fri", f); });
    const bool weight_space_pol = n <= f.max_weight_space_joints;
    // The Nystrom models reuse the kernel-form pol+fri hyper-parameters.
    KernelFit pol_fri;
    for (const char* pol : {"pol", "pol+fri"}) {
      KernelFit* keep = std::string(pol) == "pol+fri" ? &pol_fri : nullptr;
      run(pol, [&] {
        return weight_space_pol ? FitRobotModelWeightSpace(s, pol, f)
                                : FitKernelForm(s, pol, f, keep);
      });
    }
    bool any_nystrom = false;
    for (int M : f.nystrom) {
      any_nystrom = any_nystrom || Selected(f, "pol+fri/nys" + std::to_string(M));
    }
    if (any_nystrom) {
      if (!pol_fri.ok) {
        try {
          FitKernelForm(s, "pol+fri", f, &pol_fri);
        } catch (const std::exception& e) {
          std::printf("pol+fri kernel fit for the Nystrom models failed: %s\n", e.what());
        }
      }
      for (int M : f.nystrom) {
        run("pol+fri/nys" + std::to_string(M), [&] { return FitNystrom(s, M, pol_fri, f); });
      }
    }
    for (const char* name : {"rbf", "rbf+fri", "rbfs", "rbfs+fri", "pol+rbf+fri"}) {
      run(name, [&] { return FitKernelForm(s, name, f, nullptr); });
    }
    if (f.check) {
      for (const Result& r : results) {
        if (r.model == "pol+fri" && !(r.mean_nmse_train_var < kCheckMaxNmse)) check_ok = false;
      }
    }
    md << Table(s, results);
    csv << CsvRows(s, results);
  }
  std::printf("\n%s", md.str().c_str());
  if (!f.out.empty()) WriteTextAtomically(f.out, md.str());
  if (!f.csv.empty()) WriteTextAtomically(f.csv, csv.str());
  if (f.check && !check_ok) {
    std::fprintf(stderr,
                 "real_data --check: a model failed or pol+fri has a mean nMSE (train "
                 "variance) >= %g\n",
                 kCheckMaxNmse);
    return 3;
  }
  return 0;
}

}  // namespace
}  // namespace structgp

int main(int argc, char** argv) {
  CLI::App app(
      "The models of the library on real robot logs (SARCOS, UR10) with contiguous time "
      "splits; docs/real_data.md has the results.",
      "real_data");
  structgp::Flags f;
  structgp::AddFlags(&app, &f);
  return structgp::RunProgram(&app, argc, argv, [&]() {
    structgp::FinishFlags(app, &f);
    return structgp::Run(f, structgp::CommandLine("real_data", argc, argv));
  });
}
