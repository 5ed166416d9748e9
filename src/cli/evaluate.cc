// structgp evaluate: errors of a model on a data file, per joint and overall.

#include <cstdio>
#include <nlohmann/json.hpp>
#include <string>

#include "commands.h"
#include "common.h"
#include "structgp/fit/fit_check.h"
#include "structgp/io/model_file.h"
#include "structgp/report/report_data.h"

namespace structgp {
namespace cli {
namespace {

class EvaluateCommand : public Command {
 public:
  CLI::App* Register(CLI::App* app) override {
    CLI::App* cmd = app->add_subcommand(
        "evaluate",
        "RMS, normalised MSE and 2 sigma band coverage of a model on a data file, per joint and "
        "overall");
    cmd->add_option("--model", model_, "Model file written by 'structgp fit'")->required();
    cmd->add_option("--data", data_, "Test data: CSV with q, qd, qdd and tau columns")->required();
    cmd->add_option("--json", json_,
                    "Also write the errors as JSON (replaced atomically; - for stdout)");
    cmd->footer(
        "nMSE of joint j is the mean squared error divided by the variance of the measured\n"
        "tau_j; 'all' is the RMS over every joint and sample and the mean nMSE of the joints.\n"
        "2 sigma band: the fraction of the measured tau_j within 2 standard deviations of the\n"
        "noisy prediction (the posterior's and the fitted noise), about 95% when the model's\n"
        "uncertainty is calibrated on these data; far below it, the model claims more\n"
        "certainty than it has ('all': the mean of the joints).\n"
        "Example:\n"
        "  structgp evaluate --model model.json --data test.csv --json errors.json");
    AddLoadThreadsFlag(cmd, &load_, ThreadsDefault::kMachine);
    return cmd;
  }

  int Run() override {
    if (!json_.empty()) CheckOutputPath("--json", json_);
    std::FILE* const text_out = TextStream({{"--json", json_}});
    const RobotModel model = LoadModelFile(model_, load_);
    const RobotData data = ReadData(data_, model.num_joints());
    const Predictions p = Predict(model, data, load_.num_threads);
    const Errors e = ComputeErrors(p.mean, data.Y);
    const Vector coverage =
        BandCoverage(p.mean, p.std, model.hyperparameters().noise_stds(), data.Y);
    const int N = model.num_joints();

    nlohmann::json doc;
    doc["model"] = model_;
    doc["label"] = ModelLabel(model.spec());
    doc["data"] = data_;
    doc["num_samples"] = data.size();
    doc["joints"] = nlohmann::json::array();
    std::vector<std::vector<std::string>> rows = {{"joint", "RMS", "nMSE", "2 sigma band"}};
    for (int j = 0; j < N; ++j) {
      doc["joints"].push_back(
          {{"joint", j + 1}, {"rms", e.rms[j]}, {"nmse", e.nmse[j]}, {"coverage", coverage[j]}});
      rows.push_back({std::to_string(j + 1), Format("%.4g", e.rms[j]), Format("%.4g", e.nmse[j]),
                      Percent(coverage[j])});
    }
    doc["overall"] = {
        {"rms", e.overall_rms}, {"nmse", e.overall_nmse}, {"coverage", coverage.mean()}};
    rows.push_back({"all", Format("%.4g", e.overall_rms), Format("%.4g", e.overall_nmse),
                    Percent(coverage.mean())});

    std::fprintf(text_out, "model  %s (%s)\ndata   %s: %d samples\n", ModelLabel(model.spec()).c_str(),
                model_.c_str(), data_.c_str(), data.size());
    const std::string bands = report::CalibratedBandsNote(model);
    if (!bands.empty()) std::fprintf(text_out, "bands  %s\n", bands.c_str());
    std::fputs(Table(rows).c_str(), text_out);
    if (!json_.empty()) {
      const std::vector<OutputFile> outputs = {{"--json", json_, doc.dump(2) + "\n"}};
      WriteOutputs(outputs);
      PrintWritten(text_out, outputs);
    }
    return kExitOk;
  }

 private:
  std::string model_, data_, json_;
  LoadOptions load_;
};

}  // namespace

std::unique_ptr<Command> MakeEvaluateCommand() { return std::make_unique<EvaluateCommand>(); }

}  // namespace cli
}  // namespace structgp
