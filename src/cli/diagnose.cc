// structgp diagnose: where a model fails on a data file and which physical effect it misses.

#include <cstdio>
#include <optional>
#include <string>

#include "commands.h"
#include "common.h"
#include "structgp/diagnose/diagnosis_loop.h"
#include "structgp/io/data_error.h"
#include "structgp/io/model_file.h"
#include "structgp/rigid_body/dh_chain.h"
#include "structgp/rigid_body/rigid_body_chain.h"
#include "structgp/report/report.h"
#include "structgp/report/report_data.h"

namespace structgp {
namespace cli {
namespace {

// Largest --significance: beyond it, a "significant" suggestion is a coin toss.
constexpr double kMaxSignificance = 0.5;

// A model on a URDF that 'structgp identify' wrote, unchanged (the loop identifies it again).
bool IdentifiedChain(const RobotModel& model) {
  const RigidBodyChain* chain = model.options().rigid_body.get();
  return chain != nullptr && ChainKinematicsOf(*chain).has_value();
}

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
    cmd->add_option("--autocorrelation", autocorrelation_,
                    "How the evidence is corrected for autocorrelated residuals: bartlett "
                    "(Bartlett's factor of the two autocorrelations), prewhitening (residual and "
                    "candidate filtered by an AR model of the residual), or none (every row an "
                    "independent sample)")
        ->check(CLI::IsMember({"bartlett", "prewhitening", "none"}))
        ->capture_default_str();
    cmd->add_option("--train", train_,
                    "The model's training data (CSV as --data): candidates are then scored on "
                    "the training data and --data together (a sharper test: a model refitted on "
                    "one log alone can bend along it), and the findings say how far --data is "
                    "from the training states");
    cmd->add_option("--rounds", rounds_,
                    "Run the diagnosis loop (with --train and --out): add the suggestions, "
                    "refit on the training data with the fit's defaults, diagnose again, up "
                    "to this many diagnoses; --json then holds every round")
        ->check(CLI::Range(1, 100))
        ->capture_default_str();
    cmd->add_option("--out", out_,
                    "With --rounds: the model with every added effect, refitted (the model as "
                    "given when nothing is added)");
    cmd->add_flag("--no-reidentify", no_reidentify_,
                  "With --train, rbd on a URDF that 'structgp identify' wrote: keep that chain "
                  "as it is. By default the diagnosis identifies the chain again on --train and "
                  "--data together (a local search from the model's own) and, when that chain "
                  "explains --data better, diagnoses the model on it (a chain found from slow "
                  "motion can be wrong where only faster motion shows it); and with --rounds "
                  "the chain is identified again from --train with the added effects beside it "
                  "before each refit, so that a torque the first identification did not know "
                  "no longer bends its kinematics (its starts on --threads threads, by default "
                  "on the machine's)");
    cmd->add_option("--out-urdf", out_urdf_,
                    "With --train, on a model whose chain 'structgp identify' wrote: the chain "
                    "identified again, as a URDF (with --rounds: the chain of --out's model, "
                    "which holds it too; without: the one identified on --train and --data "
                    "together)");
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
        "--report report.html\n"
        "  structgp diagnose --model model.json --data test.csv --train train.csv --rounds 3 "
        "--out improved.json --json loop.json");
    AddLoadThreadsFlag(cmd, &load_);
    command_ = cmd;
    return cmd;
  }

  int Run() override {
    CheckOutputPath("--json", json_);
    if (!report_.empty()) CheckOutputPath("--report", report_);
    const bool loop = rounds_ > 1 || !out_.empty();
    if (loop && (train_.empty() || out_.empty())) {
      throw UsageError("--rounds and --out go together, with --train: the loop refits the "
                       "model on the training data and writes it to --out");
    }
    if (loop) CheckOutputPath("--out", out_);
    if (!out_urdf_.empty()) {
      if (train_.empty()) throw UsageError("--out-urdf goes with --train");
      CheckOutputPath("--out-urdf", out_urdf_);
    }
    if (no_reidentify_ && train_.empty()) {
      throw UsageError("--no-reidentify goes with --train (the chain is identified again on the "
                       "training data)");
    }
    options_.reidentify_chain = !no_reidentify_;
    // The identification's starts on --threads threads when given, else on the machine's.
    options_.chain.num_threads =
        command_->count("--threads") > 0 ? load_.num_threads : MachineThreads();
    FromString(autocorrelation_, &options_.autocorrelation);  // checked by the flag
    std::FILE* const text_out = TextStream({{"--json", json_}, {"--report", report_}});
    const RobotModel model = LoadModelFile(model_, load_);
    if (!out_urdf_.empty() && (no_reidentify_ || !IdentifiedChain(model))) {
      throw UsageError("--out-urdf " + out_urdf_ + ": " +
                       (no_reidentify_ ? std::string("--no-reidentify keeps the chain as it is")
                                       : model_ + " is not a model on a URDF 'structgp identify' "
                                                  "wrote: there is no chain to identify again"));
    }
    const RobotData data = ReadData(data_, model.num_joints());
    const Matrix X = ModelInputs(model, data);  // also refuses a log without a time it needs
    RobotData train;
    if (!train_.empty()) {
      // Problems of the training file name it, and say it is the --train file.
      try {
        train = ReadData(train_, model.num_joints());
        if (data.has_time() && !train.has_time()) {
          throw DataError(train_, 1, 0,
                          "no 't' column, but --data " + data_ +
                              " has one: the training data need their times too (they are "
                              "scored with the log as separate trajectories)");
        }
        if (!loop) {  // the loop sets them from the training data itself
          options_.training_inputs = ModelInputs(model, train);
          options_.training_targets = train.Y;
          options_.training_times = train.t;
        }
      } catch (const DataError& e) {
        throw DataError(e.file(), e.line(), e.column(), "--train: " + e.message());
      }
    }
    if (loop) return RunLoop(model, data, train, text_out);
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
      outputs.push_back({"--report", report_, ReportHtml(model, data, diagnosis, "")});
    }
    if (!out_urdf_.empty()) {  // the chain identified on the training data and the log
      if (!diagnosis.chain || diagnosis.chain->urdf.empty()) {
        throw NumericalError("--out-urdf " + out_urdf_ + ": " +
                             (diagnosis.chain ? diagnosis.chain->message
                                              : std::string("the chain was not identified again")));
      }
      outputs.push_back({"--out-urdf", out_urdf_, diagnosis.chain->urdf});
    }
    std::fprintf(text_out, "diagnosis of %s (%s) on %s: %d samples\n", ModelLabel(model.spec()).c_str(),
                model_.c_str(), data_.c_str(), data.size());
    std::fputs(DiagnosisSummary(diagnosis, model.spec(), options_).c_str(), text_out);
    WriteOutputs(outputs);
    PrintWritten(text_out, outputs);
    if (!diagnosis.suggestions.empty() && IdentifiedChain(model)) {
      std::string effects = ToString(model.spec().effects);
      for (const Suggestion& s : diagnosis.suggestions) {
        effects += (effects.empty() ? "" : ",") + s.spec;
      }
      if (diagnosis.chain && diagnosis.chain->changed) {
        std::fprintf(text_out,
                     "the suggestions are against the chain identified again on the training "
                     "data and this log: fit on it with them (--out-urdf writes it):\n"
                     "  structgp fit --data %s --model %s --effects '%s' --urdf %s --out "
                     "model.json\n",
                     train_.c_str(), ToString(model.spec()).c_str(), effects.c_str(), out_urdf_.empty() ? "ROBOT.urdf" : out_urdf_.c_str());
      } else {
        std::fprintf(text_out,
                     "the model's chain was identified from torques ('structgp identify'): "
                     "identify it again with these effects before the refit (or run the loop: "
                     "--train, --rounds, --out):\n  structgp identify --data %s --effects '%s' "
                     "--out robot.urdf\n",
                     train_.empty() ? "TRAIN.csv" : train_.c_str(), effects.c_str());
      }
    }
    return kExitOk;
  }

 private:
  // The HTML report of a diagnosis of the model on the data; `note` follows the model file.
  std::string ReportHtml(const RobotModel& model, const RobotData& data,
                         const Diagnosis& diagnosis, const std::string& note) const {
    report::ReportData r;
    try {
      r = report::DiagnosisReportData(model, data, diagnosis);
    } catch (const std::runtime_error& e) {
      throw NumericalError(std::string("prediction failed: ") + e.what());
    }
    r.notes.push_back("model file: " + model_ + note);
    return report::RenderHtml(r);
  }

  // --rounds / --out: RunDiagnosisLoop on --data with the --train data, the fit's defaults.
  int RunLoop(const RobotModel& model, const RobotData& data, const RobotData& train,
              std::FILE* text_out) {
    DiagnosisLoopOptions loop;
    loop.max_rounds = rounds_;
    loop.diagnosis = options_;
    loop.reidentify_chain = !no_reidentify_;
    loop.chain.num_threads = options_.chain.num_threads;
    std::optional<RobotModel> improved;
    DiagnosisLoopSummary summary;
    try {
      summary = RunDiagnosisLoop(loop, model, train.X, train.Y, train.t, data.X, data.Y, data.t,
                                 &improved);
    } catch (const std::invalid_argument& e) {
      throw UsageError(data_ + " with --train " + train_ + ": " + e.what());
    }
    if (summary.termination == DiagnosisLoopTermination::kDiagnosisFailed) {
      throw NumericalError("the diagnosis failed on " + data_ + ": " + summary.message);
    }
    const RobotModel& result = improved ? *improved : model;
    std::vector<OutputFile> outputs = {{"--json", json_, ToJson(summary)}};
    if (!out_.empty()) AddModelFile(&outputs, "--out", out_, result);
    if (!out_urdf_.empty()) {  // the chain of --out's model (as given when nothing was added)
      outputs.push_back({"--out-urdf", out_urdf_, result.options().rigid_body->urdf()});
    }
    const Diagnosis& first = summary.rounds.front().diagnosis;
    if (!report_.empty()) {
      outputs.push_back({"--report", report_,
                         ReportHtml(model, data, first, " (the report shows round 1 of the loop)")});
    }
    std::fprintf(text_out, "diagnosis loop of %s (%s) on %s (%d samples), refitted on %s\n",
                 ModelLabel(model.spec()).c_str(), model_.c_str(), data_.c_str(), data.size(),
                 train_.c_str());
    std::fputs(DiagnosisSummary(first, model.spec(), loop.diagnosis).c_str(), text_out);
    std::fputs(summary.BriefReport().c_str(), text_out);
    if (!improved) std::fputs("nothing added: --out holds the model as given\n", text_out);
    WriteOutputs(outputs);
    PrintWritten(text_out, outputs);
    if (summary.termination == DiagnosisLoopTermination::kRefitFailed) {
      throw NumericalError(summary.message + " (--out holds the last usable model)");
    }
    return kExitOk;
  }

  CLI::App* command_ = nullptr;
  int rounds_ = 1;
  bool no_reidentify_ = false;
  std::string out_, out_urdf_;
  std::string model_, data_, json_, report_, train_;
  std::string autocorrelation_ = ToString(DiagnosisOptions().autocorrelation);
  LoadOptions load_;
  DiagnosisOptions options_;
};

}  // namespace

std::unique_ptr<Command> MakeDiagnoseCommand() { return std::make_unique<DiagnoseCommand>(); }

}  // namespace cli
}  // namespace structgp
