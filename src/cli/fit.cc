// structgp fit: chooses hyper-parameters, fits a model to a data file and saves it.

#include <cstdio>
#include <string>
#include <vector>

#include "commands.h"
#include "common.h"
#include "structgp/io/model_file.h"

namespace structgp {
namespace cli {
namespace {

class FitCommand : public Command {
 public:
  CLI::App* Register(CLI::App* app) override {
    CLI::App* cmd = app->add_subcommand("fit", "Fit a model to a robot data file and save it");
    cmd->add_option("--data", data_,
                    "Training data: CSV with columns q1..qN, qd1..qdN, qdd1..qddN, tau1..tauN "
                    "and optionally t (s)")
        ->required();
    cmd->add_option("--model", model_,
                    "Base model: pol, rbf, rbfs, motor, rbd (the rigid-body regressor of "
                    "--urdf), lag or lagk (one GP of all joints on the Euler-Lagrange kernel, "
                    "no kinematics: for 4-7 joint arms), optionally with +fri (e.g. pol+fri)")
        ->required();
    cmd->add_option("--effects", effects_,
                    "Effects to add, e.g. 'coulomb@2', 'viscous,offset', "
                    "'cogging@3:period=0.3' (joints 1-based; no @ = every joint)");
    cmd->add_option("--hyper", hyper_,
                    "Hyper-parameters: ml (type-II maximum likelihood), cv (blocked "
                    "cross-validation on a grid, pol/motor only) or fixed (defaults)")
        ->check(CLI::IsMember({"ml", "cv", "fixed"}))
        ->capture_default_str();
    cmd->add_option("--out", out_,
                    "Model file to write (replaced atomically; - for stdout). A lagk model "
                    "through inducing states also writes OUT.posterior, which the commands that "
                    "load it read instead of computing its posterior from the rows again")
        ->required();
    cmd->add_option("--json", json_,
                    "Also write the summary as JSON: the fit's termination, evidence, starts, "
                    "check, noise and coefficients (- for stdout)");
    cmd->add_option("--prior", prior_,
                    "--hyper ml: prior on the log hyper-parameters, centred on the defaults "
                    "from the data: gaussian, student_t, or none (plain maximum likelihood)")
        ->check(CLI::IsMember({"gaussian", "student_t", "none"}))
        ->capture_default_str();
    cmd->add_option("--starts", options_.evidence.num_starts,
                    "--hyper ml: optimiser runs (the default start and perturbed copies); the "
                    "best is kept")
        ->check(CLI::Range(1, 100))
        ->capture_default_str();
    cmd->add_option("--prior-tightenings", options_.max_prior_tightenings,
                    "--hyper ml: refits with the prior's widths halved when no start passes "
                    "the held-out check")
        ->check(CLI::Range(0, 20))
        ->capture_default_str();
    cmd->add_flag("--per-joint", options_.per_joint,
                  "Each joint its own hyper-parameters (shape, block scales, noise, output "
                  "scale), searched on its torque alone: pol, motor, rbf, rbfs; about N times "
                  "the search time; the online learner (replay) needs the shared set");
    cmd->add_flag("--no-posterior-file", no_posterior_file_,
                  "Do not write OUT.posterior (a lagk model's posterior is then computed from "
                  "its rows on every load: minutes at 6-7 joints)");
    cmd->add_flag("--no-check", no_check_,
                  "Skip the check of the hyper-parameters on held-out blocks of the data (and "
                  "so the calibration of the bands)");
    cmd->add_flag("--no-calibrate-bands", no_calibrate_bands_,
                  "Keep the posterior's own 2 sigma bands: do not scale a joint's latent "
                  "variance so that its band covers 95% of the held-out blocks' torques");
    cmd->add_option("--band-coverage", options_.check.target_coverage,
                    "The held-out coverage the calibrated 2 sigma bands are scaled to (0.95: "
                    "what a Gaussian's 2 sigma band covers; higher for more cautious bands)")
        ->check(CLI::Range(0.5, 0.999))
        ->capture_default_str();
    cmd->add_option("--folds", options_.cv_folds, "Contiguous folds of --hyper cv")
        ->check(CLI::Range(2, 1000))
        ->capture_default_str();
    cmd->add_option("--ml-max-rows", options_.max_evidence_rows,
                    "Kernel-form models (rbf, rbfs, pol from 4 joints) with --hyper ml: rows "
                    "(evenly spaced) on which the kernel's hyper-parameters are fitted, "
                    "O(rows^3) per evaluation; the model then uses all rows")
        ->check(CLI::Range(10, 1000000))
        ->capture_default_str();
    cmd->add_option("--threads", options_.num_threads,
                    "Threads accumulating Phi^T Phi of feature-map models (large data sets), "
                    "evaluating lagk's evidence in its hyper-parameter search, and conditioning "
                    "lagk on every row through its inducing states")
        ->check(CLI::Range(1, kMaxThreads))
        ->capture_default_str();
    cmd->add_option("--max-kernel-rows", max_kernel_rows_,
                    "Function-space models (rbf, rbfs, pol from 4 joints, or pol/motor with more "
                    "features than rows) are fitted on at most this many evenly spaced rows; 0 = no limit")
        ->check(CLI::Range(0, 100000000))
        ->capture_default_str();
    cmd->add_option("--inducing-states", inducing_states_,
                    "lagk: with more rows, the posterior conditions on every row through this "
                    "many inducing states covering the training states (0 = exact on every "
                    "row: O((m N)^3))")
        ->check(CLI::Range(0, 1000000))
        ->capture_default_str();
    cmd->add_option("--lagk-sigmas", options_.euler_lagrange.sigmas,
                    "lagk with --hyper ml: the sigma grid of the kernel's trigonometric factors "
                    "(the best evidence wins)")
        ->delimiter(',')
        ->check(CLI::PositiveNumber)
        ->capture_default_str();
    cmd->add_option("--lagk-ml-values", options_.max_euler_lagrange_evidence_values,
                    "lagk with --hyper ml: torque values (rows x joints) of the evidence; its "
                    "cost grows with their cube")
        ->check(CLI::Range(10, 1000000))
        ->capture_default_str();
    cmd->add_option("--start-from", start_from_,
                    "lagk with --hyper ml: search the evidence from this model file's "
                    "hyper-parameters, at its sigma (the model the --effects are added to: "
                    "the rest of the model then stays where it was unless the evidence moves "
                    "it; as diagnose --rounds refits; only the file's hyper-parameters are "
                    "read)");
    AddRobotFlags(cmd, &robot_);
    cmd->add_flag("-q,--quiet", quiet_, "No progress lines on stderr");
    cmd->add_flag("-v,--verbose", options_.evidence.verbose, "One line per optimiser iteration");
    cmd->footer(
        "Example:\n"
        "  structgp fit --data train.csv --model pol --effects coulomb@2 --out model.json\n"
        "The summary (stdout) lists the hyper-parameters, the evidence and the fitted friction\n"
        "and effect coefficients with their posterior standard deviations.");
    return cmd;
  }

  int Run() override {
    CheckOutputPath("--out", out_);  // before a long fit
    if (!json_.empty()) CheckOutputPath("--json", json_);
    std::FILE* const text_out = TextStream({{"--out", out_}, {"--json", json_}});
    const ModelSpec spec = ParseSpecFlags(model_, effects_);
    options_.method = ParseHyperMethod(hyper_);
    FromString(prior_, &options_.evidence.prior.family);  // checked by the flag
    options_.check.enabled = !no_check_;
    options_.calibrate_bands = !no_calibrate_bands_;
    const Progress progress("fit", quiet_);
    progress.Line("reading " + data_);
    const RobotData data = ReadData(data_);
    if (!start_from_.empty()) {
      // The file's hyper-parameters only: its posterior is not factorised.
      const ModelFileHeader from = ReadModelFileHeader(start_from_);
      if (spec.base != BaseModel::kLagk || options_.method != HyperparameterMethod::kEvidence ||
          from.form != Form::kEulerLagrange) {
        throw UsageError("--start-from: starts the evidence search of a lagk model (--model lagk, "
                         "--hyper ml) from a lagk model; got --model " + model_ + " --hyper " +
                         hyper_ + " and a " + ModelLabel(from.spec) + " model in " + start_from_);
      }
      if (from.num_joints != data.num_joints) {
        throw UsageError("--start-from: " + start_from_ + " has " +
                         std::to_string(from.num_joints) + " joints, " + data_ + " " +
                         std::to_string(data.num_joints));
      }
      const RobotModel layout(from.spec, from.num_joints);  // its effects' prior variances
      options_.euler_lagrange.start = EulerLagrangeFromHyperparameters(
          from.hyperparameters, from.num_joints, from.spec.friction,
          layout.effect_prior_variance());
    }
    RobotModelOptions options;
    options.batch.num_threads = options_.num_threads;
    options.batch.max_kernel_rows = max_kernel_rows_;
    options.batch.inducing_states = inducing_states_;
    options.rigid_body = LoadRobot(robot_);
    RobotModel model = MakeModel(spec, data.num_joints, options);
    const FitSummary summary = FitModel(data, options_, progress, &model);
    std::vector<OutputFile> outputs;
    AddModelFile(&outputs, "--out", out_, model, !no_posterior_file_);
    if (!json_.empty()) outputs.push_back({"--json", json_, FitJson(model, data, summary)});
    std::fputs(FitSummaryText(model, data, summary).c_str(), text_out);
    WriteOutputs(outputs);
    PrintWritten(text_out, outputs);
    return kExitOk;
  }

 private:
  std::string data_, model_, effects_, hyper_ = "ml", out_, json_, prior_ = "gaussian";
  std::string start_from_;
  bool no_check_ = false;
  bool no_calibrate_bands_ = false;
  bool no_posterior_file_ = false;
  FitOptions options_;
  RobotFlags robot_;
  int max_kernel_rows_ = kDefaultMaxKernelRows;
  int inducing_states_ = BatchFitOptions().inducing_states;
  bool quiet_ = false;
};

}  // namespace

std::unique_ptr<Command> MakeFitCommand() { return std::make_unique<FitCommand>(); }

}  // namespace cli
}  // namespace structgp
