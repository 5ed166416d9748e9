#include "common.h"

#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <filesystem>
#include <sstream>

#include "structgp/hyper/cross_validation.h"
#include "structgp/hyper/evidence.h"
#include "structgp/hyper/hyperparameter_layout.h"
#include "structgp/hyper/marginal_likelihood.h"
#include "structgp/io/atomic_file.h"
#include "structgp/io/csv.h"
#include "structgp/model/sufficient_statistics.h"

namespace structgp {
namespace cli {
namespace {

// A variable along which the residual concentrates is shown when its bin means explain at
// least this fraction of the residual variance.
constexpr double kMinExplained = 0.05;

// Grid of --hyper cv: the shape parameter (log sigma of pol) around its default, and the noise
// level relative to each joint's torque spread.
constexpr double kCvShapeOffsets[] = {-2.0, -1.0, 0.0, 1.0, 2.0};
constexpr double kCvNoiseLevels[] = {0.3, 0.1, 0.03, 0.01, 0.003, 0.001};

Matrix EvenlySpacedRows(const Matrix& a, int count) {
  if (a.rows() <= count) return a;
  Matrix out(count, a.cols());
  for (int i = 0; i < count; ++i) {
    out.row(i) = a.row(static_cast<Eigen::Index>(static_cast<double>(i) * (a.rows() - 1) /
                                                 std::max(1, count - 1)));
  }
  return out;
}

void FitFeatureMapByEvidence(const Matrix& X, const Matrix& Y, const FitSettings& settings,
                             const Progress& progress, RobotModel* model, Hyperparameters* h,
                             FitInfo* info) {
  const auto& map = model->feature_map();
  progress.Line(Format("accumulating Phi^T Phi over %d rows (D = %d)", static_cast<int>(X.rows()),
                       map->dim()));
  AccumulateOptions accumulate;
  accumulate.num_threads = settings.num_threads;
  SufficientStatistics stats = AccumulateStatistics(*map, X, Y, accumulate);
  const WeightSpaceEvidence evidence(map, std::move(stats));
  progress.Line("profiling the noise level and output scales by evidence");
  try {
    *h = ProfileNoiseAndScales(evidence, model->DefaultHyperparameters(Y));
  } catch (const std::runtime_error& e) {
    throw NumericalError(std::string("hyper-parameters by evidence: ") + e.what());
  }
  progress.Line("maximising the evidence over the shape, block scales and noise (Ceres LBFGS)");
  MaximumLikelihoodOptions options;
  options.verbose = settings.verbose;
  const MaximumLikelihoodSummary summary = FitHyperparameters(evidence, options, h);
  if (!summary.usable()) {
    throw NumericalError("type-II maximum likelihood: " + summary.message);
  }
  progress.Line(summary.BriefReport());
  info->method = Format("type-II maximum likelihood (%s, %d iterations)",
                        ToString(summary.termination), summary.iterations);
  if (!summary.at_bounds.empty()) {
    std::string names;
    for (const auto& n : summary.at_bounds) names += (names.empty() ? "" : ", ") + n;
    info->notes.push_back("at a bound of its search box (the optimum may lie beyond): " + names);
  }
}

void FitFeatureMapByCrossValidation(const Matrix& X, const Matrix& Y, const FitSettings& settings,
                                    const Progress& progress, RobotModel* model, Hyperparameters* h,
                                    FitInfo* info) {
  const FeatureMap& map = *model->feature_map();
  if (settings.cv_folds < 2 || settings.cv_folds > X.rows()) {
    throw UsageError(Format("--folds: need 2 <= folds <= %d (the number of rows), got %d",
                            static_cast<int>(X.rows()), settings.cv_folds));
  }
  progress.Line(Format("blocked %d-fold cross-validation statistics over %d rows (D = %d)",
                       settings.cv_folds, static_cast<int>(X.rows()), map.dim()));
  const FoldStatistics folds(map, X, Y, settings.cv_folds);
  const Hyperparameters base = model->DefaultHyperparameters(Y);
  std::vector<double> shape_values;
  if (map.num_shape_parameters() > 0) {
    for (double offset : kCvShapeOffsets) shape_values.push_back(base.shape[0] + offset);
  }
  std::vector<double> noise_values;
  for (double level : kCvNoiseLevels) noise_values.push_back(std::log(level));
  const std::vector<Hyperparameters> candidates =
      HyperparameterGrid(base, shape_values, noise_values, 0);
  progress.Line(Format("scoring %d candidates", static_cast<int>(candidates.size())));
  std::vector<CrossValidationResult> results;
  int best = -1;
  *h = SelectByCrossValidation(map, folds, candidates, &results, &best);
  if (best < 0) {
    throw NumericalError("cross-validation: every candidate failed to factorise");
  }
  std::string chosen = Format("noise std %.3g", std::exp(h->log_noise_std));
  if (!shape_values.empty()) {
    chosen = map.shape_parameter_names()[0] + Format(" %.3g, ", h->shape[0]) + chosen;
  }
  const bool shape_at_edge = !shape_values.empty() && (h->shape[0] == shape_values.front() ||
                                                       h->shape[0] == shape_values.back());
  const bool noise_at_edge =
      h->log_noise_std == noise_values.front() || h->log_noise_std == noise_values.back();
  if (shape_at_edge || noise_at_edge) {
    info->notes.push_back(
        "the best candidate lies on the edge of the grid; --hyper ml searches "
        "without a grid");
  }
  info->method = Format(
      "blocked %d-fold cross-validation over %d candidates (%s; held-out "
      "nMSE %.4g)",
      settings.cv_folds, static_cast<int>(candidates.size()), chosen.c_str(),
      results[static_cast<size_t>(best)].mean_nmse);
}

void FitKernelByEvidence(const Matrix& X, const Matrix& Y, const FitSettings& settings,
                         const Progress& progress, RobotModel* model, Hyperparameters* h,
                         FitInfo* info) {
  // *h holds the kernel's default parameters in shape (RobotModel::DefaultHyperparameters);
  // the fitted ones replace them, and RobotModel::Fit(X, Y, *h) then uses them.
  const int rows = std::max(1, std::min(settings.ml_max_rows, static_cast<int>(X.rows())));
  const Matrix Xs = EvenlySpacedRows(X, rows);
  const Matrix Ys = EvenlySpacedRows(Y, rows);
  progress.Line(
      Format("maximising the evidence of the kernel on %d of %d rows (Ceres LBFGS, "
             "O(m^3) per evaluation)",
             rows, static_cast<int>(X.rows())));
  MaximumLikelihoodOptions options;
  options.verbose = settings.verbose;
  const MaximumLikelihoodSummary summary =
      FitKernelHyperparameters(*model->kernel(), Xs, Ys, options, h);
  if (!summary.usable()) throw NumericalError("type-II maximum likelihood: " + summary.message);
  progress.Line(summary.BriefReport());
  info->method = Format("type-II maximum likelihood (%s, %d iterations)",
                        ToString(summary.termination), summary.iterations);
  if (rows < X.rows()) {
    info->notes.push_back(
        Format("kernel hyper-parameters fitted on %d evenly spaced rows "
               "(--ml-max-rows) of %d",
               rows, static_cast<int>(X.rows())));
  }
}

std::string Number(double value) { return Format("%.6g", value); }

}  // namespace

Progress::Progress(std::string command, bool quiet)
    : command_(std::move(command)), quiet_(quiet), start_(std::chrono::steady_clock::now()) {}

double Progress::seconds() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

void Progress::Line(const std::string& text) const {
  if (quiet_) return;
  std::fprintf(stderr, "structgp %s: %s [%.1f s]\n", command_.c_str(), text.c_str(), seconds());
  std::fflush(stderr);
}

std::string Format(const char* format, ...) {
  va_list args;
  va_start(args, format);
  va_list copy;
  va_copy(copy, args);
  const int n = std::vsnprintf(nullptr, 0, format, copy);
  va_end(copy);
  std::string out(static_cast<size_t>(std::max(n, 0)) + 1, '\0');
  std::vsnprintf(&out[0], out.size(), format, args);
  va_end(args);
  out.resize(static_cast<size_t>(std::max(n, 0)));
  return out;
}

RobotData ReadData(const std::string& path, int expected_joints) {
  CsvOptions options;
  options.expected_joints = expected_joints;
  RobotData data = ReadRobotCsv(path, options);
  if (data.size() == 0) throw DataError(path, 0, 0, "no data rows after the header");
  return data;
}

Matrix ModelInputs(const RobotModel& model, const RobotData& data) {
  if (!model.uses_time()) return data.X;
  if (!data.has_time()) {
    throw DataError(data.source, 1, 0,
                    "the model uses the time (effects '" + ToString(model.spec().effects) +
                        "'), but the file has no 't' column");
  }
  Matrix X(data.X.rows(), data.X.cols() + 1);
  X << data.X, data.t;
  return X;
}

std::string ModelLabel(const ModelSpec& spec) {
  return ToString(spec) + (spec.effects.empty() ? "" : " + " + ToString(spec.effects));
}

ModelSpec ParseSpecFlags(const std::string& model, const std::string& effects) {
  ModelSpec spec;
  try {
    spec = ParseModelSpec(model);
  } catch (const std::invalid_argument& e) {
    throw UsageError(std::string("--model: ") + e.what());
  }
  if (!effects.empty()) {
    try {
      spec.effects = ParseEffectList(effects);
    } catch (const std::invalid_argument& e) {
      throw UsageError(std::string("--effects: ") + e.what());
    }
  }
  return spec;
}

RobotModel MakeModel(const ModelSpec& spec, int num_joints, const RobotModelOptions& options) {
  try {
    return RobotModel(spec, num_joints, options);
  } catch (const std::invalid_argument& e) {
    throw UsageError(std::string("--model/--effects: ") + e.what());
  }
}

HyperMethod ParseHyperMethod(const std::string& text) {
  if (text == "ml") return HyperMethod::kMaximumLikelihood;
  if (text == "cv") return HyperMethod::kCrossValidation;
  if (text == "fixed") return HyperMethod::kFixed;
  throw UsageError("--hyper: expected ml, cv or fixed, got '" + text + "'");
}

void FitModel(const RobotData& data, const FitSettings& settings, const Progress& progress,
              RobotModel* model, FitInfo* info) {
  const Matrix X = ModelInputs(*model, data);
  const Matrix& Y = data.Y;
  const double start = progress.seconds();
  Hyperparameters h = model->DefaultHyperparameters(Y);
  const bool kernel_model = model->feature_map() == nullptr;
  switch (settings.method) {
    case HyperMethod::kMaximumLikelihood:
      if (kernel_model) {
        FitKernelByEvidence(X, Y, settings, progress, model, &h, info);
      } else {
        FitFeatureMapByEvidence(X, Y, settings, progress, model, &h, info);
      }
      break;
    case HyperMethod::kCrossValidation:
      if (kernel_model) {
        throw UsageError(
            "--hyper cv: cross-validation needs a model with an explicit feature map (motor, "
            "or pol up to 3 joints); '" +
            ToString(model->spec()) + "' for " + std::to_string(model->num_joints()) +
            " joints runs in function space (use --hyper ml or --hyper fixed)");
      }
      FitFeatureMapByCrossValidation(X, Y, settings, progress, model, &h, info);
      break;
    case HyperMethod::kFixed:
      info->method = "fixed defaults (output scale = torque RMS, noise 10% of it)";
      break;
  }
  progress.Line(Format("fitting the model to %d rows", static_cast<int>(X.rows())));
  const Status status = model->Fit(X, Y, h);
  if (status != Status::kOk) {
    throw NumericalError(std::string("fitting the model failed: ") + ToString(status) +
                         " (the posterior precision is not numerically positive definite; "
                         "try --hyper fixed, or check the data for duplicated rows)");
  }
  if (model->gp().subsampled()) {
    const std::string note = Format(
        "the function-space form was fitted on %d evenly spaced rows of %d (--max-kernel-rows; "
        "its fit costs O(m^3) time and O(m^2) memory); a model with an explicit feature map "
        "(motor, pol up to 3 joints) learns from every row",
        static_cast<int>(model->gp().fit_rows()), static_cast<int>(model->gp().data_rows()));
    progress.Line(note);
    info->notes.push_back(note);
  }
  info->seconds = progress.seconds() - start;
}

std::string FitSummary(const RobotModel& model, const RobotData& data, const FitInfo& info) {
  std::ostringstream os;
  const int N = model.num_joints();
  const GaussianProcess& gp = model.gp();
  os << "model        " << ModelLabel(model.spec()) << "\n";
  os << "data         " << data.source << ": " << data.size() << " samples, " << N
     << (N == 1 ? " joint" : " joints") << (data.has_time() ? ", with time" : "") << "\n";
  if (model.feature_map()) {
    os << "features     D = " << model.feature_map()->dim() << " (" << ToString(gp.form())
       << " form)\n";
  } else {
    os << "features     none: kernel model (" << ToString(gp.form()) << " form, "
       << gp.function_space()->size() << " stored points)\n";
  }
  os << "hyper        " << info.method << Format(", %.2f s", info.seconds) << "\n";
  for (const auto& note : info.notes) os << "             " << note << "\n";
  std::vector<std::vector<std::string>> rows = {{"parameter", "value"}};
  const Hyperparameters& h = model.hyperparameters();
  if (model.feature_map()) {
    FreeHyperparameters all;
    all.output_scales = true;
    const HyperparameterLayout layout(*model.feature_map(), N, all);
    const Vector values = layout.Flatten(h);
    for (int i = 0; i < layout.size(); ++i) {
      rows.push_back({layout.names()[static_cast<size_t>(i)], Number(values[i])});
    }
  } else {
    const Vector theta = model.kernel()->parameters();
    const auto names = model.kernel()->parameter_names();
    for (Eigen::Index i = 0; i < theta.size(); ++i) {
      rows.push_back({names[static_cast<size_t>(i)], Number(theta[i])});
    }
    rows.push_back({"log_noise_std", Number(h.log_noise_std)});
    for (int j = 0; j < N; ++j) {
      rows.push_back({Format("log_output_scale_%d", j + 1), Number(h.log_output_scale[j])});
    }
  }
  os << Table(rows, 4);
  os << "noise std   ";
  for (int j = 0; j < N; ++j) {
    os << Format(" tau%d %.4g", j + 1, std::exp(h.log_noise_std + h.log_output_scale[j]));
  }
  os << "  (sigma_n times the output scale)\n";
  os << "log marginal likelihood " << Format("%.6g", gp.LogMarginalLikelihood()) << " nats\n";
  const auto names = model.ParametricFeatureNames();
  if (gp.weight_space() != nullptr && !names.empty()) {
    os << "coefficients (posterior mean +- std, per joint torque):\n";
    std::vector<std::vector<std::string>> coef = {{"feature"}};
    for (int j = 1; j <= N; ++j) coef[0].push_back(Format("tau%d", j));
    for (const auto& name : names) {
      std::vector<std::string> row = {name};
      for (int j = 1; j <= N; ++j) {
        const auto [value, std] = model.Coefficient(name, j);
        row.push_back(Format("%.4g +- %.2g", value, std));
      }
      coef.push_back(row);
    }
    os << Table(coef, 4);
  }
  return os.str();
}

Errors ComputeErrors(const Matrix& predicted, const Matrix& measured) {
  const Eigen::Index m = measured.rows();
  const Eigen::Index N = measured.cols();
  Errors e;
  e.rms.resize(N);
  e.nmse.resize(N);
  double total = 0.0;
  for (Eigen::Index j = 0; j < N; ++j) {
    const double sse = (predicted.col(j) - measured.col(j)).squaredNorm();
    const double mean = measured.col(j).mean();
    const double var = (measured.col(j).array() - mean).square().sum() / static_cast<double>(m);
    e.rms[j] = std::sqrt(sse / static_cast<double>(m));
    e.nmse[j] = var > 0.0 ? sse / static_cast<double>(m) / var : HUGE_VAL;
    total += sse;
  }
  e.overall_rms = std::sqrt(total / static_cast<double>(m * N));
  e.overall_nmse = e.nmse.mean();
  return e;
}

Predictions Predict(const RobotModel& model, const RobotData& data) {
  Predictions p;
  try {
    model.PredictRows(ModelInputs(model, data), &p.mean, &p.std);
  } catch (const std::runtime_error& e) {
    if (dynamic_cast<const DataError*>(&e) != nullptr) throw;
    throw NumericalError(std::string("prediction failed: ") + e.what());
  }
  return p;
}

std::vector<double> ToStd(const Vector& v) {
  return std::vector<double>(v.data(), v.data() + v.size());
}

report::ModelErrors ReportErrors(const std::string& label, const Errors& errors) {
  return report::ModelErrors{label, ToStd(errors.rms), ToStd(errors.nmse)};
}

std::string Table(const std::vector<std::vector<std::string>>& rows, int indent) {
  std::vector<size_t> width;
  for (const auto& row : rows) {
    if (width.size() < row.size()) width.resize(row.size(), 0);
    for (size_t c = 0; c < row.size(); ++c) width[c] = std::max(width[c], row[c].size());
  }
  // Columns of numbers are right-aligned; the first column and columns of text (or with no
  // number at all) left-aligned. "-" and "n/a" mark missing values and count as neither.
  std::vector<bool> numeric(width.size(), false), text(width.size(), false);
  for (size_t r = 1; r < rows.size(); ++r) {
    for (size_t c = 0; c < rows[r].size(); ++c) {
      const std::string& cell = rows[r][c];
      if (cell.empty() || cell == "-" || cell == "n/a") continue;
      const bool number = std::string("0123456789+-.").find(cell[0]) != std::string::npos;
      (number ? numeric : text)[c] = true;
    }
  }
  std::vector<bool> left(width.size());
  for (size_t c = 0; c < width.size(); ++c) left[c] = c == 0 || text[c] || !numeric[c];
  std::string out;
  for (const auto& row : rows) {
    std::string line(static_cast<size_t>(indent), ' ');
    for (size_t c = 0; c < row.size(); ++c) {
      const std::string pad(width[c] - row[c].size(), ' ');
      line += left[c] ? row[c] + pad : pad + row[c];
      if (c + 1 < row.size()) line += "  ";
    }
    while (!line.empty() && line.back() == ' ') line.pop_back();
    out += line + "\n";
  }
  return out;
}

std::string RelativeChange(double before, double after) {
  if (!(before > 0.0) || !std::isfinite(before) || !std::isfinite(after)) return "n/a";
  return Format("%+.1f%%", 100.0 * (after - before) / before);
}

std::string DescribeEffect(const Suggestion& s) {
  if (s.effect == "viscous") return "viscous friction";
  if (s.effect == "coulomb") return "Coulomb friction";
  if (s.effect == "stribeck") return "Stribeck friction";
  if (s.effect == "offset") return "a torque offset";
  if (s.effect == "spring") return "a spring";
  if (s.effect == "drift") return "drifting friction";
  if (s.effect == "cogging") {
    const auto it = s.params.find("period");
    return it == s.params.end() ? "cogging" : Format("cogging (period %.3g rad)", it->second);
  }
  return s.effect;
}

ModelSpec WithSuggestions(const ModelSpec& spec, const Diagnosis& diagnosis) {
  ModelSpec out = spec;
  for (const Suggestion& s : diagnosis.suggestions) {
    out.effects.push_back(EffectSpec{s.effect, {s.joint}, s.params});
  }
  return out;
}

std::string DiagnosisSummary(const Diagnosis& d, const ModelSpec& spec,
                             const DiagnosisOptions& options) {
  std::ostringstream os;
  std::vector<std::vector<std::string>> rows = {
      {"joint", "RMS", "nMSE", "noise est.", "error concentrates along"}};
  for (const JointFinding& f : d.joints) {
    std::string where = "-";
    if (!f.concentrations.empty() && f.concentrations.front().explained >= kMinExplained) {
      const Concentration& c = f.concentrations.front();
      where =
          Format("%s (explains %.0f%%; worst bin %s in [%.3g, %.3g], RMS %.3g)", c.variable.c_str(),
                 100.0 * c.explained, c.variable.c_str(), c.bin_low, c.bin_high, c.bin_rms);
    }
    rows.push_back({std::to_string(f.joint), Format("%.4g", f.rms), Format("%.4g", f.nmse),
                    Format("%.4g", f.noise_std_estimate), where});
  }
  os << Table(rows);
  if (d.suggestions.empty()) {
    os << Format(
        "no missing effect found: no candidate gains %.0f nats of evidence and cuts "
        "the held-out RMS by %.0f%% on any joint\n",
        options.min_log_evidence_gain, 100.0 * options.min_relative_rms_gain);
    return os.str();
  }
  const std::string existing = ToString(spec.effects);
  // Effect parameters are separated by ';', which a shell would take as the end of a command.
  auto shell_word = [](const std::string& text) {
    return text.find_first_of("; ") == std::string::npos ? text : "'" + text + "'";
  };
  for (const Suggestion& s : d.suggestions) {
    os << Format(
        "joint %d: missing %s (evidence %+.0f nats): residual RMS %.3g -> %.3g, held-out "
        "RMS (%d contiguous blocks) %.3g -> %.3g; add with --effects %s\n",
        s.joint, DescribeEffect(s).c_str(), s.score, s.residual_rms_before, s.residual_rms_after,
        options.folds, s.rms_before, s.rms_after,
        shell_word((existing.empty() ? "" : existing + ",") + s.spec).c_str());
  }
  const ModelSpec fixed = WithSuggestions(spec, d);
  os << "to refit with every suggestion:\n  structgp fit --data TRAIN.csv --model "
     << ToString(fixed) << " --effects '" << ToString(fixed.effects) << "' --out MODEL\n";
  return os.str();
}

std::vector<report::JointData> ReportJoints(
    const RobotData& data, const std::vector<std::pair<std::string, Predictions>>& models) {
  const int N = data.num_joints;
  const Eigen::Index m = data.size();
  auto column = [m](const auto& a, Eigen::Index c) {
    std::vector<double> v(static_cast<size_t>(m));
    for (Eigen::Index i = 0; i < m; ++i) v[static_cast<size_t>(i)] = a(i, c);
    return v;
  };
  std::vector<report::JointData> joints;
  for (int j = 0; j < N; ++j) {
    report::JointData jd;
    jd.joint = j + 1;
    jd.t.resize(static_cast<size_t>(m));
    for (Eigen::Index i = 0; i < m; ++i) {
      jd.t[static_cast<size_t>(i)] = data.has_time() ? data.t[i] : static_cast<double>(i);
    }
    jd.q = column(data.X, j);
    jd.qd = column(data.X, N + j);
    jd.measured = column(data.Y, j);
    for (const auto& [label, p] : models) {
      report::PredictionSeries s;
      s.label = label;
      s.mean = column(p.mean, j);
      s.std = column(p.std, j);
      jd.predictions.push_back(std::move(s));
    }
    joints.push_back(std::move(jd));
  }
  return joints;
}

void CheckOutputPath(const std::string& flag, const std::string& path) {
  namespace fs = std::filesystem;
  if (path.empty()) throw UsageError(flag + ": empty path");
  std::error_code ec;
  if (fs::is_directory(path, ec)) {
    throw UsageError(flag + " '" + path + "': is a directory, expected a file path");
  }
  fs::path parent = fs::path(path).parent_path();
  if (parent.empty()) parent = ".";
  if (!fs::is_directory(parent, ec)) {
    throw UsageError(flag + " '" + path + "': directory '" + parent.string() + "' does not exist");
  }
}

void WriteOutputs(const std::vector<OutputFile>& files) {
  for (const auto& f : files) CheckOutputPath(f.flag, f.path);
  for (const auto& f : files) WriteTextAtomically(f.path, f.contents);
}

}  // namespace cli
}  // namespace structgp
