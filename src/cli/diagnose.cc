// structgp diagnose: where a model fails on a data file and which physical effect it misses.

#include <cstdio>
#include <string>

#include "commands.h"
#include "common.h"
#include "structgp/io/data_error.h"
#include "structgp/io/model_file.h"
#include "structgp/report/report.h"
#include "structgp/report/report_data.h"

namespace structgp {
namespace cli {
namespace {

// Largest --significance: beyond it, a "significant" suggestion is a coin toss.
constexpr double kMaxSignificance = 0.5;

class DiagnoseCommand : public Command {
 public:
  CLI::App* Register(CLI::App* app) override {
    CLI::App* cmd = app->add_subcommand(
        "diagnose", "Find the physical effects a model is missing, from its errors on data");
    cmd->add_option("--model", model_, "Model file written by 'structgp fit'")
        ->required();
    cmd->add_option("--data", data_,
                    "Data in time order: CSV with q, qd, qdd and tau columns, and t to try "
                    "drift")
        ->required();
    cmd->add_option("--json", json_,
                    "Findings to write as JSON (replaced atomically; - for stdout)")
        ->required();
    cmd->add_option("--report", report_,
                    "Also write a self-contained HTML report (- for stdout)");
    cmd->add_option("--folds", options_.folds, "Contiguous folds of the held-out check")
        ->check(CLI::Range(2, 1000))
        ->capture_default_str();
    cmd->add_option("--min-evidence", options_.min_log_evidence_gain,
                    "Minimum gain in log evidence (nats) for a suggestion")
        ->check(CLI::Range(0.0, 1e9))
        ->capture_default_str();
    cmd->add_option("--significance", options_.significance,
                    "Family-wise error rate (Holm) over every candidate on every joint")
        ->check(CLI::Validator(
            [](std::string& text) -> std::string {
              double value = 0;
              if (!CLI::detail::lexical_cast(text, value)) {
                return "expected a number in (0, 0.5], e.g. 0.01, got '" + text + "'";
              }
              if (!(value > 0.0 && value <= kMaxSignificance)) {
                return "expected a level in (0, 0.5] (the chance of a false suggestion that "
                       "is accepted), e.g. 0.01, got " + text;
              }
              return "";
            },
            "in (0, 0.5]"))
        ->capture_default_str();
    cmd->add_option("--train", train_,
                    "The model's training data (CSV as --data): candidates are then scored on "
                    "the training data and --data together (a sharper test: a model refitted on "
                    "one log alone can bend along it), and the findings say how far --data is "
                    "from the training states");
    cmd->add_option("--nystrom", options_.nystrom_features,
                    "Function-space models (rbf, rbfs, pol from 4 joints): Nystrom features of "
                    "the model's kernel the candidates are scored against")
        ->check(CLI::Range(1, 100000))
        ->capture_default_str();
    cmd->footer(
        "Every candidate effect (viscous, coulomb, stribeck, offset, cogging, spring, drift)\n"
        "on every joint is scored by the gain in log evidence of the joint's torque\n"
        "(corrected for autocorrelated residuals), a multiplicity-controlled test, its effect\n"
        "size and the error on unseen trajectories or blocks; suggestions need all of them.\n"
        "The verdict says whether the error is a missing effect or motions the training data\n"
        "did not cover (docs/diagnosis.md).\n"
        "Example:\n"
        "  structgp diagnose --model model.json --data test.csv --json findings.json "
        "--report report.html");
    AddLoadThreadsFlag(cmd, &load_);
    return cmd;
  }

  int Run() override {
    CheckOutputPath("--json", json_);
    if (!report_.empty()) CheckOutputPath("--report", report_);
    std::FILE* const text_out = TextStream({{"--json", json_}, {"--report", report_}});
    const RobotModel model = LoadModel(model_, load_);
    const RobotData data = ReadData(data_, model.num_joints());
    const Matrix X = ModelInputs(model, data);
    if (!train_.empty()) {
      // Problems of the training file name it, and say it is the --train file.
      try {
        const RobotData train = ReadData(train_, model.num_joints());
        if (data.has_time() && !train.has_time()) {
          throw DataError(train_, 1, 0,
                          "no 't' column, but --data " + data_ +
                              " has one: the training data need their times too (they are "
                              "scored with the log as separate trajectories)");
        }
        options_.training_inputs = ModelInputs(model, train);
        options_.training_targets = train.Y;
        options_.training_times = train.t;
      } catch (const DataError& e) {
        throw DataError(e.file(), e.line(), e.column(), "--train: " + e.message());
      }
    }
    Diagnosis diagnosis;
    try {
      diagnosis = Diagnose(model, X, data.Y, data.t, options_);
    } catch (const std::invalid_argument& e) {
      // The library names what it refuses; say which file that came from.
      const std::string what = e.what();
      const bool training = !train_.empty() && what.find("training_") != std::string::npos;
      throw UsageError((training ? "--train " + train_ : data_) + ": " + what);
    }
    if (diagnosis.status != DiagnosisStatus::kOk) {
      throw NumericalError("the diagnosis failed on " + data_ + ": " + diagnosis.message);
    }
    std::vector<OutputFile> outputs = {{"--json", json_, ToJson(diagnosis)}};
    if (!report_.empty()) {
      report::ReportData r;
      try {
        r = report::DiagnosisReportData(model, data, diagnosis);
      } catch (const std::runtime_error& e) {
        throw NumericalError(std::string("prediction failed: ") + e.what());
      }
      r.notes.push_back("model file: " + model_);
      outputs.push_back({"--report", report_, report::RenderHtml(r)});
    }
    std::fprintf(text_out, "diagnosis of %s (%s) on %s: %d samples\n", ModelLabel(model.spec()).c_str(),
                model_.c_str(), data_.c_str(), data.size());
    std::fputs(DiagnosisSummary(diagnosis, model.spec(), options_).c_str(), text_out);
    WriteOutputs(outputs);
    PrintWritten(text_out, outputs);
    return kExitOk;
  }

 private:
  std::string model_, data_, json_, report_, train_;
  LoadOptions load_;
  DiagnosisOptions options_;
};

}  // namespace

std::unique_ptr<Command> MakeDiagnoseCommand() { return std::make_unique<DiagnoseCommand>(); }

}  // namespace cli
}  // namespace structgp
