// structgp compare: errors of two or more models on the same data, per joint.

#include <cstdio>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "commands.h"
#include "common.h"
#include "structgp/fit/fit_check.h"
#include "structgp/io/model_file.h"
#include "structgp/report/report.h"

namespace structgp {
namespace cli {
namespace {

class CompareCommand : public Command {
 public:
  CLI::App* Register(CLI::App* app) override {
    CLI::App* cmd = app->add_subcommand(
        "compare", "Errors of two models (before/after) on the same data, per joint");
    cmd->add_option("--model", models_,
                    "Model files, given twice or more: --model A --model B (A is the baseline)")
        ->required();
    cmd->add_option("--data", data_, "Test data: CSV with q, qd, qdd and tau columns")->required();
    cmd->add_option("--json", json_,
                    "Also write the errors as JSON (replaced atomically; - for stdout)");
    cmd->add_option("--report", report_,
                    "Also write an HTML report with the models' predictions overlaid (- for "
                    "stdout)");
    cmd->footer(
        "The change column is the relative change of the RMS from the first model; the 2 sigma\n"
        "band columns the fraction of the measured torques within 2 standard deviations of\n"
        "each model's noisy prediction (about 95% when calibrated; see 'evaluate').\n"
        "Example:\n"
        "  structgp compare --model before.json --model after.json --data test.csv "
        "--report compare.html");
    AddLoadThreadsFlag(cmd, &load_, ThreadsDefault::kMachine);
    return cmd;
  }

  int Run() override {
    if (models_.size() < 2) {
      throw UsageError("--model: give at least two model files (--model A --model B), got " +
                       std::to_string(models_.size()));
    }
    if (!json_.empty()) CheckOutputPath("--json", json_);
    if (!report_.empty()) CheckOutputPath("--report", report_);
    std::FILE* const text_out = TextStream({{"--json", json_}, {"--report", report_}});
    std::vector<RobotModel> models;
    for (const auto& path : models_) {
      models.push_back(LoadModelFile(path, load_));
      if (models.back().num_joints() != models.front().num_joints()) {
        throw UsageError("--model '" + path + "': has " +
                         std::to_string(models.back().num_joints()) + " joints, '" +
                         models_.front() + "' has " + std::to_string(models.front().num_joints()));
      }
    }
    const RobotData data = ReadData(data_, models.front().num_joints());
    const int N = data.num_joints;
    std::vector<std::pair<std::string, Predictions>> predictions;
    std::vector<Errors> errors;
    std::vector<Vector> coverage;  // per model, per joint: the 2 sigma band's
    std::vector<std::string> labels;
    for (size_t k = 0; k < models.size(); ++k) {
      std::string label = ModelLabel(models[k].spec());
      for (const auto& other : labels) {
        if (other == label) label += " (" + models_[k] + ")";
      }
      labels.push_back(label);
      predictions.emplace_back(label, Predict(models[k], data, load_.num_threads));
      const Predictions& p = predictions.back().second;
      errors.push_back(ComputeErrors(p.mean, data.Y));
      coverage.push_back(
          BandCoverage(p.mean, p.std, models[k].hyperparameters().noise_stds(), data.Y));
    }

    std::vector<std::vector<std::string>> rows = {{"joint"}};
    for (size_t k = 0; k < models.size(); ++k) {
      rows[0].push_back(Format("RMS %c", static_cast<char>('A' + k)));
      if (k > 0) rows[0].push_back("change");
    }
    for (size_t k = 0; k < models.size(); ++k) {
      rows[0].push_back(Format("2 sigma band %c", static_cast<char>('A' + k)));
    }
    nlohmann::json doc;
    doc["data"] = data_;
    doc["num_samples"] = data.size();
    doc["models"] = nlohmann::json::array();
    for (size_t k = 0; k < models.size(); ++k) {
      nlohmann::json m;
      m["file"] = models_[k];
      m["label"] = labels[k];
      m["joints"] = nlohmann::json::array();
      for (int j = 0; j < N; ++j) {
        nlohmann::json entry = {{"joint", j + 1},
                                {"rms", errors[k].rms[j]},
                                {"nmse", errors[k].nmse[j]},
                                {"coverage", coverage[k][j]}};
        if (k > 0) {
          entry["relative_rms_change"] = (errors[k].rms[j] - errors[0].rms[j]) / errors[0].rms[j];
        }
        m["joints"].push_back(entry);
      }
      m["overall"] = {{"rms", errors[k].overall_rms},
                      {"nmse", errors[k].overall_nmse},
                      {"coverage", coverage[k].mean()}};
      doc["models"].push_back(m);
    }
    for (int j = 0; j <= N; ++j) {
      std::vector<std::string> row = {j < N ? std::to_string(j + 1) : "all"};
      for (size_t k = 0; k < models.size(); ++k) {
        const double rms = j < N ? errors[k].rms[j] : errors[k].overall_rms;
        const double base = j < N ? errors[0].rms[j] : errors[0].overall_rms;
        row.push_back(Format("%.4g", rms));
        if (k > 0) row.push_back(RelativeChange(base, rms));
      }
      for (size_t k = 0; k < models.size(); ++k) {
        row.push_back(Percent(j < N ? coverage[k][j] : coverage[k].mean()));
      }
      rows.push_back(row);
    }

    std::vector<OutputFile> outputs;
    if (!json_.empty()) outputs.push_back({"--json", json_, doc.dump(2) + "\n"});
    if (!report_.empty()) {
      report::ReportData r;
      r.title = "structgp comparison on " + data_;
      r.data_source = data_;
      r.joints = ReportJoints(data, predictions);
      for (size_t k = 0; k < models.size(); ++k) {
        r.errors.push_back(ReportErrors(labels[k], errors[k], coverage[k]));
        r.notes.push_back(Format("model %c: %s (%s)", static_cast<char>('A' + k), labels[k].c_str(),
                                 models_[k].c_str()));
        const std::string bands = report::CalibratedBandsNote(models[k]);
        if (!bands.empty()) {
          r.notes.push_back(Format("model %c: ", static_cast<char>('A' + k)) + bands);
        }
      }
      outputs.push_back({"--report", report_, report::RenderHtml(r)});
    }
    for (size_t k = 0; k < models.size(); ++k) {
      std::fprintf(text_out, "model %c  %s (%s)\n", static_cast<char>('A' + k), labels[k].c_str(),
                  models_[k].c_str());
    }
    std::fprintf(text_out, "data     %s: %d samples\n", data_.c_str(), data.size());
    std::fputs(Table(rows).c_str(), text_out);
    WriteOutputs(outputs);
    PrintWritten(text_out, outputs);
    return kExitOk;
  }

 private:
  std::vector<std::string> models_;
  LoadOptions load_;
  std::string data_, json_, report_;
};

}  // namespace

std::unique_ptr<Command> MakeCompareCommand() { return std::make_unique<CompareCommand>(); }

}  // namespace cli
}  // namespace structgp
