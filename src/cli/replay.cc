// structgp replay: a log streamed through the online learner as a control loop would run it
// (predict each sample, then learn it), from a fitted model or from zero. The workflow is the
// library's Replay (online/replay.h); this file parses, prints and writes.

#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "commands.h"
#include "common.h"
#include "structgp/io/model_file.h"
#include "structgp/online/replay.h"
#include "structgp/report/report.h"
#include "structgp/report/report_data.h"

namespace structgp {
namespace cli {
namespace {

class ReplayCommand : public Command {
 public:
  CLI::App* Register(CLI::App* app) override {
    CLI::App* cmd = app->add_subcommand(
        "replay",
        "Stream a log through the online learner in time order (predict, then learn each "
        "sample): one-step-ahead errors, latencies, the learned model");
    cmd->add_option("--data", data_, "Log: CSV with q, qd, qdd and tau columns (t optional)")
        ->required();
    auto* model = cmd->add_option("--model", model_,
                                  "Start from this model file (weight-space or rbd/lag)");
    auto* spec = cmd->add_option("--model-spec", spec_,
                                 "Start from zero with this model (pol+fri, rbd+fri, ...), its "
                                 "default prior from the first 1000 samples' torques");
    model->excludes(spec);
    spec->excludes(model);
    cmd->add_option("--effects", effects_, "Effects of --model-spec (as for fit)");
    cmd->add_option("--forgetting", forgetting_, "Forgetting factor per sample, in (0, 1]")
        ->check(CLI::Range(0.0, 1.0))
        ->capture_default_str();
    cmd->add_option("--window", window_, "Keep only the newest N samples (0: no window)")
        ->check(CLI::NonNegativeNumber)
        ->capture_default_str();
    cmd->add_option("--out", out_, "One-step-ahead error per joint and sample (CSV)");
    cmd->add_option("--save", save_, "Save the learned model (replaced atomically)");
    cmd->add_option("--json", json_, "Summary as JSON (replaced atomically)");
    cmd->add_option("--report", report_,
                    "HTML report: the one-step-ahead error per joint over time, measured vs "
                    "predicted, the errors of the first and last fifth (self-contained)");
    AddRobotFlags(cmd, &robot_);
    cmd->footer(
        "Exactly one of --model and --model-spec. Rows are replayed in file order; a time\n"
        "that starts again begins a new trajectory (reported, the learner carries on).\n"
        "Example:\n"
        "  structgp replay --data log.csv --model model.json --forgetting 0.999 \\\n"
        "      --out errors.csv --json replay.json --save model2.json --report replay.html");
    return cmd;
  }

  int Run() override {
    if (model_.empty() == spec_.empty()) {
      throw UsageError("give exactly one of --model FILE and --model-spec TEXT");
    }
    if (!(forgetting_ > 0.0)) {
      throw UsageError("--forgetting: expected a value in (0, 1], got " +
                       Format("%g", forgetting_));
    }
    for (const auto& [flag, path] : {std::pair<std::string, std::string>{"--out", out_},
                                     {"--save", save_},
                                     {"--json", json_},
                                     {"--report", report_}}) {
      if (!path.empty()) CheckOutputPath(flag, path);
    }
    std::unique_ptr<RobotModel> start;
    RobotData data;
    if (!model_.empty()) {
      if (!effects_.empty()) throw UsageError("--effects goes with --model-spec, not --model");
      start = std::make_unique<RobotModel>(LoadModelFile(model_));
      data = ReadData(data_, start->num_joints());
    } else {
      const ModelSpec spec = ParseSpecFlags(spec_, effects_);
      data = ReadData(data_);
      RobotModelOptions options;
      options.rigid_body = LoadRobot(robot_);
      start = std::make_unique<RobotModel>(MakeModel(spec, data.num_joints, options));
    }
    ReplayOptions options;
    options.forgetting = forgetting_;
    options.window_length = window_;
    ReplaySummary s;
    try {
      s = Replay(*start, ModelInputs(*start, data), data.Y, data.t, options);
    } catch (const std::invalid_argument& e) {
      throw UsageError(e.what());
    }
    const int N = start->num_joints();
    std::printf("model  %s (%s)\ndata   %s: %d samples\n", ModelLabel(start->spec()).c_str(),
                model_.empty() ? "from zero" : model_.c_str(), data_.c_str(), data.size());
    std::fputs(s.Report().c_str(), stdout);

    std::vector<OutputFile> files;
    if (!out_.empty()) files.push_back({"--out", out_, ErrorsCsv(s, data, N)});
    if (!json_.empty()) files.push_back({"--json", json_, Json(s, N).dump(2) + "\n"});
    if (!save_.empty()) AddModelFile(&files, "--save", save_, *s.model);
    if (!report_.empty()) {
      const std::string label =
          ModelLabel(start->spec()) + (model_.empty() ? " from zero" : " from " + model_);
      files.push_back(
          {"--report", report_, report::RenderHtml(report::ReplayReportData(s, data, label))});
    }
    WriteOutputs(files);
    for (const OutputFile& f : files) std::printf("wrote %s\n", f.path.c_str());
    return kExitOk;
  }

 private:
  static std::string ErrorsCsv(const ReplaySummary& s, const RobotData& data, int N) {
    std::ostringstream os;
    os.precision(9);
    os << "step,t,trajectory";
    for (int j = 1; j <= N; ++j) os << ",err" << j;
    os << ",update_us,predict_us\n";
    size_t segment = 0;
    for (long i = 0; i < s.steps; ++i) {
      while (segment + 1 < s.segment_starts.size() &&
             s.segment_starts[segment + 1] <= static_cast<int>(i)) {
        ++segment;
      }
      os << i << ",";
      if (data.has_time()) os << data.t[i];
      os << "," << segment + 1;
      for (int j = 0; j < N; ++j) {
        os << ",";
        if (std::isfinite(s.errors(i, j))) os << s.errors(i, j);
      }
      os << "," << s.update_us[i] << "," << s.predict_us[i] << "\n";
    }
    return os.str();
  }

  nlohmann::json Json(const ReplaySummary& s, int N) const {
    nlohmann::json doc;
    doc["data"] = data_;
    doc["model"] = model_.empty() ? spec_ : model_;
    doc["form"] = s.form;
    doc["num_features"] = s.num_features;
    doc["forgetting"] = forgetting_;
    doc["window"] = window_;
    doc["steps"] = s.steps;
    doc["trajectories"] = s.segment_starts.size();
    doc["bad_samples"] = s.bad_samples;
    doc["update_us_p50"] = s.update_us_p50;
    doc["update_us_p99"] = s.update_us_p99;
    doc["predict_us_p50"] = s.predict_us_p50;
    doc["predict_us_p99"] = s.predict_us_p99;
    doc["joints"] = nlohmann::json::array();
    for (int j = 0; j < N; ++j) {
      doc["joints"].push_back({{"joint", j + 1},
                               {"rms_first_fifth", s.rms_first_fifth[j]},
                               {"rms_last_fifth", s.rms_last_fifth[j]}});
    }
    return doc;
  }

  std::string data_, model_, spec_, effects_, out_, save_, json_, report_;
  double forgetting_ = 1.0;
  int window_ = 0;
  RobotFlags robot_;
};

}  // namespace

std::unique_ptr<Command> MakeReplayCommand() { return std::make_unique<ReplayCommand>(); }

}  // namespace cli
}  // namespace structgp
