#ifndef STRUCTGP_SRC_CLI_COMMON_H_
#define STRUCTGP_SRC_CLI_COMMON_H_

// Shared pieces of the structgp program: exit codes and the errors that map to them, reading
// data for a model, the library's fit with progress lines, errors per joint, tables, and
// writing every output only after all of them have been computed.

#include <CLI/CLI.hpp>

#include <chrono>
#include <cstdio>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "structgp/core/types.h"
#include "structgp/diagnose/diagnosis.h"
#include "structgp/diagnose/diagnosis_report.h"
#include "structgp/fit/fit_model.h"
#include "structgp/internal/text.h"
#include "structgp/io/model_file.h"
#include "structgp/io/robot_data.h"
#include "structgp/model/robot_model.h"
#include "structgp/report/report.h"
#include "structgp/report/report_data.h"
#include "structgp/rigid_body/rigid_body_chain.h"

namespace structgp {
namespace cli {

/// Exit codes of the program.
inline constexpr int kExitOk = 0;
/// A numerical failure: a factorisation failed, the evidence could not be evaluated.
inline constexpr int kExitNumerical = 1;
/// A mistake in the command line or an input file (also an output that cannot be written).
inline constexpr int kExitUsage = 2;

/// A command-line mistake found after parsing ("--effects 'x': unknown effect"): exit 2.
class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// A numerical failure: exit 1.
class NumericalError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Progress lines on stderr, "structgp fit: <text> [1.2 s]"; silent when quiet.
class Progress {
 public:
  Progress(std::string command, bool quiet);
  void Line(const std::string& text) const;
  double seconds() const;

 private:
  std::string command_;
  bool quiet_;
  std::chrono::steady_clock::time_point start_;
};

/// Reads a robot CSV file (ReadRobotCsv); expected_joints > 0 requires that many joints.
RobotData ReadData(const std::string& path, int expected_joints = 0);

/// The model's inputs for the data: (q, qd, qdd), then t when the model uses time. Throws
/// DataError naming the file when the model needs t and the file has none.
Matrix ModelInputs(const RobotModel& model, const RobotData& data);

/// Builds the model of --model and --effects text; UsageError naming the flag when either
/// cannot be parsed or does not fit the robot.
ModelSpec ParseSpecFlags(const std::string& model, const std::string& effects);
RobotModel MakeModel(const ModelSpec& spec, int num_joints,
                     const RobotModelOptions& options = RobotModelOptions());

/// --urdf FILE, --root LINK, --tip LINK, --gravity X,Y,Z: the robot of `rbd` models (and of the
/// demo), read with kdl_parser.
struct RobotFlags {
  std::string urdf, root, tip, gravity = "0,0,-9.81";
};
/// Adds the four flags to a command.
void AddRobotFlags(CLI::App* command, RobotFlags* flags);
/// The chain of --urdf (null without --urdf). UsageError naming the flag for a bad --gravity,
/// and for a URDF that cannot be read or has no such chain (the message names the file).
std::shared_ptr<const RigidBodyChain> LoadRobot(const RobotFlags& flags);

/// The machine's hardware threads (std::thread::hardware_concurrency), in 1..kMaxThreads.
int MachineThreads();

/// Whether --threads defaults to one thread or to the machine's.
enum class ThreadsDefault {
  kOne,      // commands that refit (diagnose): the memory of a batch fit grows with its threads
  kMachine,  // commands that load and predict only: the same result for any number of threads
};

/// --threads of the commands that read a model file (LoadOptions::num_threads: a lagk model
/// through inducing states is factorised again on load). With kMachine, options->num_threads
/// is set to MachineThreads() first, and the help says so.
void AddLoadThreadsFlag(CLI::App* command, LoadOptions* options,
                        ThreadsDefault default_threads = ThreadsDefault::kOne);

/// "D = 134 features", "P = 42 parameters", "kernel model": the size of a model, for summaries.
std::string ModelSize(const RobotModel& model);

/// "ml", "cv", "fixed" (--hyper); UsageError for anything else.
HyperparameterMethod ParseHyperMethod(const std::string& text);

/// Fits the model with the library's workflow (FitModel), printing its progress lines.
/// UsageError (naming --hyper) when the method does not suit the model or the data,
/// NumericalError when the fit fails; the summary otherwise.
FitSummary FitModel(const RobotData& data, const FitOptions& options, const Progress& progress,
                    RobotModel* model);

/// The summary of `structgp fit`: model and data, then the library's FitReport.
std::string FitSummaryText(const RobotModel& model, const RobotData& data,
                           const FitSummary& summary);

/// The JSON of `structgp fit --json`: the library's ToJson of the model and its summary, with
/// "data" (the file) and "num_samples".
std::string FitJson(const RobotModel& model, const RobotData& data, const FitSummary& summary);

/// Errors of predictions against measurements, per joint and overall (report/report_data.h).
using Errors = report::PredictionErrors;
using report::ComputeErrors;

/// Predictions of a model on the data: mean and latent standard deviation (m x N).
struct Predictions {
  Matrix mean;
  Matrix std;
};
/// num_threads: RobotModel::PredictRows's (the same result for any number).
Predictions Predict(const RobotModel& model, const RobotData& data, int num_threads = 1);

/// The errors of one model for a report.
report::ModelErrors ReportErrors(const std::string& label, const Errors& errors,
                                 const Vector& coverage = Vector());

using internal::Format;
using internal::Table;
/// "-89.0%" style relative change from a to b.
std::string RelativeChange(double before, double after);
/// "94.3%": a fraction in percent (a band's coverage).
std::string Percent(double fraction);

/// The library's DiagnosisReport and the command that refits with every suggestion.
std::string DiagnosisSummary(const Diagnosis& diagnosis, const ModelSpec& spec,
                             const DiagnosisOptions& options);

/// The per-joint series of a report for these data and predictions (one entry per model).
std::vector<report::JointData> ReportJoints(
    const RobotData& data, const std::vector<std::pair<std::string, Predictions>>& models);

/// Files to write: path and contents. Every path is checked first (its directory exists, it is
/// not a directory), then the files are written one by one, each atomically. Throws
/// UsageError naming the flag when a check fails, so that nothing at all is written.
/// The path "-" is stdout: the contents are written there, after every file.
struct OutputFile {
  std::string flag;  // "--json"
  std::string path;
  std::string contents;
  bool remove = false;  // instead: remove the file at path if there is one (after the writes)
};
/// A model file as outputs: its posterior file first (io/model_file.h: lagk through inducing
/// states), then the model file. For a model without one, a posterior file left at its path
/// by an earlier model file is removed. posterior_file = false writes none.
void AddModelFile(std::vector<OutputFile>* outputs, const std::string& flag,
                  const std::string& path, const RobotModel& model, bool posterior_file = true);
/// LoadModel, saying on stderr why a posterior file next to the model file was not used.
RobotModel LoadModelFile(const std::string& path, const LoadOptions& options = LoadOptions());
/// The output path that means stdout.
inline constexpr const char* kStdoutPath = "-";
inline bool IsStdout(const std::string& path) { return path == kStdoutPath; }
void CheckOutputPath(const std::string& flag, const std::string& path);
void WriteOutputs(const std::vector<OutputFile>& files);
/// "wrote PATH" on `stream` for every output that is a file (not stdout).
void PrintWritten(std::FILE* stream, const std::vector<OutputFile>& files);

/// Where a command prints its summary: stdout, or stderr when one of its outputs (flag, path)
/// is "-" (stdout then carries that output alone). UsageError naming the flags when more than
/// one output is "-".
std::FILE* TextStream(const std::vector<std::pair<std::string, std::string>>& outputs);

}  // namespace cli
}  // namespace structgp

#endif  // STRUCTGP_SRC_CLI_COMMON_H_
