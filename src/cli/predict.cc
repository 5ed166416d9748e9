// structgp predict: predicted torques (mean and standard deviation, optionally split into
// physical components) for every row of a data file.

#include <cstdio>
#include <string>
#include <vector>

#include "commands.h"
#include "common.h"
#include "structgp/io/csv.h"
#include "structgp/io/model_file.h"

namespace structgp {
namespace cli {
namespace {

class PredictCommand : public Command {
 public:
  CLI::App* Register(CLI::App* app) override {
    CLI::App* cmd =
        app->add_subcommand("predict", "Predict the joint torques of a data file with a model");
    cmd->add_option("--model", model_, "Model file written by 'structgp fit'")->required();
    cmd->add_option("--data", data_,
                    "States: CSV with q1..qN, qd1..qdN, qdd1..qddN, tau1..tauN (tau is "
                    "required by the reader but not used), and t when the model uses time")
        ->required();
    cmd->add_option("--out", out_, "Predictions CSV to write (replaced atomically; - for stdout)")
        ->required();
    cmd->add_flag("--components", components_,
                  "Also write each physical component of the mean (inertial, coriolis, "
                  "gravity, friction, each effect); weight-space pol/motor models only");
    cmd->footer(
        "Columns: t (when the data have it), tau1_mean, tau1_std, ..., tauN_mean, tauN_std,\n"
        "then with --components tau1_<component> for every component and joint. tauJ_std is\n"
        "the posterior standard deviation of the mean torque (without measurement noise).\n"
        "Example:\n"
        "  structgp predict --model model.json --data test.csv --out pred.csv --components");
    AddLoadThreadsFlag(cmd, &load_, ThreadsDefault::kMachine);
    return cmd;
  }

  int Run() override {
    CheckOutputPath("--out", out_);
    std::FILE* const text_out = TextStream({{"--out", out_}});
    const RobotModel model = LoadModelFile(model_, load_);
    if (components_ && !model.has_components()) {
      throw UsageError("--components: needs a weight-space pol or motor model, or rbd or lag; '" + model_ +
                       "' is " + ModelLabel(model.spec()) + " in " + ToString(model.gp().form()) +
                       " form");
    }
    const RobotData data = ReadData(data_, model.num_joints());
    const Predictions p = Predict(model, data, load_.num_threads);
    const int N = model.num_joints();
    const Eigen::Index m = data.size();

    std::vector<std::string> header;
    if (data.has_time()) header.push_back("t");
    for (int j = 1; j <= N; ++j) {
      header.push_back(data.target_prefix() + std::to_string(j) + "_mean");
      header.push_back(data.target_prefix() + std::to_string(j) + "_std");
    }
    const std::vector<std::string> names =
        components_ ? model.ComponentNames() : std::vector<std::string>();
    for (int j = 1; j <= N; ++j) {
      for (const auto& name : names) header.push_back(data.target_prefix() + std::to_string(j) + "_" + name);
    }
    Matrix values(m, static_cast<Eigen::Index>(header.size()));
    const Eigen::Index offset = data.has_time() ? 1 : 0;
    if (data.has_time()) values.col(0) = data.t;
    for (Eigen::Index j = 0; j < N; ++j) {
      values.col(offset + 2 * j) = p.mean.col(j);
      values.col(offset + 2 * j + 1) = p.std.col(j);
    }
    if (components_) {
      std::vector<ComponentRows> parts;
      try {
        parts = model.PredictComponentRows(ModelInputs(model, data));
      } catch (const std::runtime_error& e) {
        if (dynamic_cast<const DataError*>(&e) != nullptr) throw;
        throw NumericalError(std::string("components could not be computed: ") + e.what());
      }
      const Eigen::Index begin = offset + 2 * static_cast<Eigen::Index>(N);
      const auto C = static_cast<Eigen::Index>(names.size());
      for (Eigen::Index c = 0; c < C; ++c) {
        for (int j = 0; j < N; ++j) {
          values.col(begin + j * C + c) = parts[static_cast<size_t>(c)].mean.col(j);
        }
      }
    }
    WriteOutputs({{"--out", out_, CsvText(header, values, /*precision=*/0)}});
    if (IsStdout(out_)) return kExitOk;
    std::fprintf(text_out, "wrote %s: %d rows, %d columns (%s)\n", out_.c_str(), static_cast<int>(m),
                static_cast<int>(header.size()),
                components_ ? "mean, std and components per joint" : "mean and std per joint");
    return kExitOk;
  }

 private:
  std::string model_, data_, out_;
  LoadOptions load_;
  bool components_ = false;
};

}  // namespace

std::unique_ptr<Command> MakePredictCommand() { return std::make_unique<PredictCommand>(); }

}  // namespace cli
}  // namespace structgp
