#include "common.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <sstream>
#include <thread>

#include "structgp/io/atomic_file.h"
#include "structgp/io/csv.h"

namespace structgp {
namespace cli {
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

RobotData ReadData(const std::string& path, int expected_joints) {
  CsvOptions options;
  options.expected_joints = expected_joints;
  RobotData data = ReadRobotCsv(path, options);
  if (data.size() == 0) throw DataError(path, 0, 0, "no data rows after the header");
  return data;
}

Matrix ModelInputs(const RobotModel& model, const RobotData& data) {
  if (model.uses_time() && !data.has_time()) {
    throw DataError(data.source, 1, 0,
                    "the model uses the time (effects '" + ToString(model.spec().effects) +
                        "'), but the file has no 't' column");
  }
  return structgp::ModelInputs(model, data.X, data.t);
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

void AddRobotFlags(CLI::App* command, RobotFlags* flags) {
  command->add_option("--urdf", flags->urdf,
                      "The robot's URDF (model rbd: its kinematic chain and the prior on its "
                      "inertial parameters; 'structgp identify' finds one from a torque log)");
  command->add_option("--root", flags->root, "Base link of the chain (default: the URDF's root)");
  command->add_option("--tip", flags->tip,
                      "Last link of the chain (default: the single leaf below --root)");
  command->add_option("--gravity", flags->gravity,
                      "Gravitational acceleration in the root frame, m/s^2, as X,Y,Z")
      ->capture_default_str();
}

int MachineThreads() {
  const unsigned n = std::thread::hardware_concurrency();  // 0 when unknown
  return static_cast<int>(std::clamp(n, 1u, static_cast<unsigned>(kMaxThreads)));
}

void AddLoadThreadsFlag(CLI::App* command, LoadOptions* options,
                        ThreadsDefault default_threads) {
  std::string help =
      "Threads that refactorise a lagk model through its inducing states on load and predict "
      "the log's rows (the same result for any number)";
  if (default_threads == ThreadsDefault::kMachine) {
    options->num_threads = MachineThreads();
    help += "; default: this machine's hardware threads";
  }
  command->add_option("--threads", options->num_threads, help)
      ->check(CLI::Range(1, kMaxThreads))
      ->capture_default_str();
}

std::shared_ptr<const RigidBodyChain> LoadRobot(const RobotFlags& flags) {
  if (flags.urdf.empty()) {
    if (!flags.root.empty() || !flags.tip.empty()) {
      throw UsageError("--root/--tip: they select a chain of --urdf, which is not given");
    }
    return nullptr;
  }
  UrdfOptions options;
  options.root = flags.root;
  options.tip = flags.tip;
  std::vector<double> g;
  std::stringstream in(flags.gravity);
  std::string item;
  while (std::getline(in, item, ',')) {
    char* end = nullptr;
    const double v = std::strtod(item.c_str(), &end);
    if (item.empty() || end != item.c_str() + item.size() || !std::isfinite(v)) {
      throw UsageError("--gravity: expected three numbers X,Y,Z (m/s^2), got '" + flags.gravity +
                       "'");
    }
    g.push_back(v);
  }
  if (g.size() != 3) {
    throw UsageError("--gravity: expected three numbers X,Y,Z (m/s^2), got '" + flags.gravity +
                     "'");
  }
  options.gravity = Eigen::Vector3d(g[0], g[1], g[2]);
  try {
    return std::make_shared<const RigidBodyChain>(RigidBodyChain::FromUrdfFile(flags.urdf, options));
  } catch (const std::invalid_argument& e) {
    throw UsageError(std::string("--urdf: ") + e.what());
  }
}

std::string ModelSize(const RobotModel& model) {
  if (model.regressor_map()) return Format("P = %d parameters", model.regressor_map()->dim());
  if (model.feature_map()) return Format("D = %d features", model.feature_map()->dim());
  return "kernel model (no finite feature map)";
}

HyperparameterMethod ParseHyperMethod(const std::string& text) {
  HyperparameterMethod method;
  if (!FromString(text, &method)) {
    throw UsageError("--hyper: expected ml, cv or fixed, got '" + text + "'");
  }
  return method;
}

FitSummary FitModel(const RobotData& data, const FitOptions& options, const Progress& progress,
                    RobotModel* model) {
  ModelInputs(*model, data);  // a file without the times the model needs: DataError
  FitOptions o = options;
  o.callback = [&progress](const FitProgress& p) {
    if (!p.message.empty()) progress.Line(p.message);
    return FitCallbackReturn::kContinue;
  };
  FitSummary summary;
  try {
    summary = structgp::FitModel(o, data.X, data.Y, data.t, model);
  } catch (const std::invalid_argument& e) {
    throw UsageError(std::string("--hyper ") + ToString(options.method) + ": " + e.what());
  }
  if (!summary.IsUsable()) throw NumericalError(summary.message);
  return summary;
}

std::string FitSummaryText(const RobotModel& model, const RobotData& data,
                           const FitSummary& summary) {
  std::ostringstream os;
  const int N = model.num_joints();
  os << "model        " << ModelLabel(model.spec()) << "\n";
  os << "data         " << data.source << ": " << data.size() << " samples, " << N
     << (N == 1 ? " joint" : " joints") << (data.has_time() ? ", with time" : "") << "\n";
  os << FitReport(model, summary);
  return os.str();
}

std::string FitJson(const RobotModel& model, const RobotData& data, const FitSummary& summary) {
  nlohmann::ordered_json doc = nlohmann::ordered_json::parse(ToJson(model, summary));
  doc["data"] = data.source;
  doc["num_samples"] = data.size();
  return doc.dump(2) + "\n";
}

Predictions Predict(const RobotModel& model, const RobotData& data, int num_threads) {
  Predictions p;
  try {
    model.PredictRows(ModelInputs(model, data), &p.mean, &p.std, num_threads);
  } catch (const std::runtime_error& e) {
    if (dynamic_cast<const DataError*>(&e) != nullptr) throw;
    throw NumericalError(std::string("prediction failed: ") + e.what());
  }
  return p;
}

report::ModelErrors ReportErrors(const std::string& label, const Errors& errors,
                                 const Vector& coverage) {
  return report::ToModelErrors(label, errors, coverage);
}

std::string Percent(double fraction) { return Format("%.1f%%", 100.0 * fraction); }

std::string RelativeChange(double before, double after) {
  if (!(before > 0.0) || !std::isfinite(before) || !std::isfinite(after)) return "n/a";
  return Format("%+.1f%%", 100.0 * (after - before) / before);
}

std::string DiagnosisSummary(const Diagnosis& d, const ModelSpec& spec,
                             const DiagnosisOptions& options) {
  std::string text = DiagnosisReport(d, spec, options);
  if (d.suggestions.empty()) return text;
  const ModelSpec fixed = WithSuggestions(spec, d);
  // Models on a chain need its URDF again (for one 'structgp identify' wrote, identified again
  // with the effects: the diagnose command says so).
  const bool chain = fixed.base == BaseModel::kRbd || fixed.rigid_body_features;
  return text + "to refit with every suggestion:\n  structgp fit --data TRAIN.csv --model " +
         ToString(fixed) + (chain ? " --urdf ROBOT.urdf" : "") + " --effects '" +
         ToString(fixed.effects) + "' --out MODEL\n";
}

std::vector<report::JointData> ReportJoints(
    const RobotData& data, const std::vector<std::pair<std::string, Predictions>>& models) {
  std::vector<report::ModelPredictions> series;
  for (const auto& [label, p] : models) series.push_back({label, p.mean, p.std});
  return report::JointSeries(data, series);
}

void CheckOutputPath(const std::string& flag, const std::string& path) {
  namespace fs = std::filesystem;
  if (path.empty()) throw UsageError(flag + ": empty path");
  if (IsStdout(path)) return;
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

void AddModelFile(std::vector<OutputFile>* outputs, const std::string& flag,
                  const std::string& path, const RobotModel& model, bool posterior_file) {
  if (!IsStdout(path)) {
    std::string bytes = posterior_file ? PosteriorFileBytes(model) : std::string();
    OutputFile posterior{flag, PosteriorFilePath(path), std::move(bytes)};
    posterior.remove = posterior.contents.empty();
    outputs->push_back(std::move(posterior));
  }
  outputs->push_back({flag, path, ModelFileText(model)});
}

RobotModel LoadModelFile(const std::string& path, const LoadOptions& options) {
  LoadSummary summary;
  RobotModel model = LoadModel(path, options, &summary);
  if (!summary.posterior_file_note.empty()) {
    std::fprintf(stderr, "note: %s: %s; the posterior was computed from the model's rows\n",
                 PosteriorFilePath(path).c_str(), summary.posterior_file_note.c_str());
  }
  return model;
}

void WriteOutputs(const std::vector<OutputFile>& files) {
  for (const auto& f : files) {
    if (!f.remove) CheckOutputPath(f.flag, f.path);
  }
  for (const auto& f : files) {
    if (!f.remove && !IsStdout(f.path)) WriteTextAtomically(f.path, f.contents);
  }
  for (const auto& f : files) {
    if (!f.remove) continue;
    std::error_code ec;
    std::filesystem::remove(f.path, ec);  // a stale file; nothing lost if it cannot go
  }
  for (const auto& f : files) {
    if (f.remove || !IsStdout(f.path)) continue;
    std::fflush(stderr);
    if (std::fwrite(f.contents.data(), 1, f.contents.size(), stdout) != f.contents.size() ||
        std::fflush(stdout) != 0) {
      throw UsageError(f.flag + " -: could not write to stdout");
    }
  }
}

void PrintWritten(std::FILE* stream, const std::vector<OutputFile>& files) {
  for (const auto& f : files) {
    if (!f.remove && !IsStdout(f.path)) std::fprintf(stream, "wrote %s\n", f.path.c_str());
  }
}

std::FILE* TextStream(const std::vector<std::pair<std::string, std::string>>& outputs) {
  std::string flags;
  int count = 0;
  for (const auto& [flag, path] : outputs) {
    if (!IsStdout(path)) continue;
    flags += (flags.empty() ? "" : " and ") + flag;
    ++count;
  }
  if (count > 1) {
    throw UsageError(flags + ": only one output can be '-' (stdout), got " +
                     std::to_string(count));
  }
  return count == 1 ? stderr : stdout;
}

}  // namespace cli
}  // namespace structgp
