// structgp demo: the whole loop on simulated data, with nothing to download. A KDL robot with a
// hidden effect on one joint; fit pol on a slow log, evaluate on a fast one, diagnose, add the
// suggested effects, refit, and compare.

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "commands.h"
#include "common.h"
#include "structgp/fit/fit_check.h"
#include "structgp/io/csv.h"
#include "structgp/io/model_file.h"
#include "structgp/report/report.h"
#include "structgp/sim/hidden_effect.h"

namespace structgp {
namespace cli {
namespace {

class DemoCommand : public Command {
 public:
  CLI::App* Register(CLI::App* app) override {
    CLI::App* cmd = app->add_subcommand(
        "demo", "The whole loop on a simulated robot with a hidden effect (no data needed)");
    cmd->add_option("--out", dir_, "Directory for the data, models, findings and report")
        ->capture_default_str();
    cmd->add_option("--effect", effect_, "The hidden effect")
        ->check(
            CLI::IsMember({"coulomb", "viscous", "stribeck", "cogging", "drift", "spring", "none"}))
        ->capture_default_str();
    cmd->add_option("--joint", joint_, "Joint with the hidden effect (1-based)")
        ->check(CLI::Range(1, 7))
        ->capture_default_str();
    cmd->add_option("--robot", robot_, "Simulated robot (Orocos KDL)")
        ->check(CLI::IsMember({"two-link", "three-link"}))
        ->capture_default_str();
    cmd->add_option("--magnitude", magnitude_,
                    "Size of the hidden effect, relative to the joint's largest torque")
        ->check(CLI::Range(0.0, 10.0))
        ->capture_default_str();
    cmd->add_option("--noise", noise_, "Noise std, relative to each joint's largest torque")
        ->check(CLI::Range(0.0, 10.0))
        ->capture_default_str();
    cmd->add_option("--seed", seed_, "Seed of the trajectories and the noise")
        ->capture_default_str();
    cmd->add_option("--model", model_,
                    "Starting model (default: pol, or rbd when --urdf gives the robot)");
    AddRobotFlags(cmd, &urdf_);
    cmd->add_option("--hyper", hyper_, "Hyper-parameters of both fits: ml, cv or fixed")
        ->check(CLI::IsMember({"ml", "cv", "fixed"}))
        ->capture_default_str();
    cmd->add_flag("-q,--quiet", quiet_, "No progress lines on stderr");
    cmd->footer(
        "Writes DIR/train.csv (slow log), DIR/test.csv (the same path 2.5x faster),\n"
        "DIR/model_before.json, DIR/model_after.json, DIR/findings.json, DIR/comparison.json\n"
        "and DIR/report.html.\n"
        "Example:\n"
        "  structgp demo --effect cogging --joint 1 --out /tmp/cogging-demo\n"
        "  structgp demo --urdf data/urdf/puma560.urdf --effect coulomb --joint 2\n"
        "With --urdf the robot is the URDF's chain (--robot is ignored) and the starting model\n"
        "rbd, its rigid-body regressor, unless --model says otherwise.");
    return cmd;
  }

  int Run() override {
    namespace fs = std::filesystem;
    const Progress progress("demo", quiet_);
    const std::shared_ptr<const RigidBodyChain> chain = LoadRobot(urdf_);
    const sim::Robot robot = chain                    ? sim::Robot::FromRigidBodyChain(*chain)
                             : robot_ == "three-link" ? sim::ThreeLinkArm()
                                                      : sim::TwoLinkArm();
    const std::string robot_name = chain ? urdf_.urdf : robot_ + " arm";
    const int N = robot.num_joints();
    if (joint_ > N) {
      throw UsageError(
          Format("--joint: the %s has %d joints, got %d", robot_name.c_str(), N, joint_));
    }
    RobotModelOptions model_options;
    model_options.rigid_body = chain;
    const std::string start = model_.empty() ? (chain ? "rbd" : "pol") : model_;
    FitOptions settings;
    settings.method = ParseHyperMethod(hyper_);
    sim::HiddenEffectOptions o;
    o.effect = sim::ParseHiddenEffect(effect_);
    o.joint = joint_;
    o.magnitude = magnitude_;
    o.noise_std = noise_;
    o.seed = seed_;
    progress.Line("simulating the " + robot_name + " with Orocos KDL");
    const sim::HiddenEffectScenario scenario = sim::MakeHiddenEffectScenario(robot, o);
    const fs::path dir(dir_);
    const std::string train_path = (dir / "train.csv").string();
    const std::string test_path = (dir / "test.csv").string();
    const RobotData train = sim::ToRobotData(scenario.train, train_path);
    const RobotData test = sim::ToRobotData(scenario.test, test_path);

    std::printf("structgp demo: %s\n", scenario.description.c_str());
    if (o.effect != sim::HiddenEffect::kNone) {
      const double scale = scenario.train.torque_scale[joint_ - 1];
      std::printf(
          "hidden torque on joint %d: up to %.3g N m (its largest rigid-body torque is "
          "%.3g N m)\n",
          joint_, magnitude_ * scale, scale);
    }
    // What the starting model knows: the URDF only when it uses the chain (rbd, rbd+...).
    const ModelSpec before_spec = ParseSpecFlags(start, "");
    const bool knows_chain =
        chain && (before_spec.base == BaseModel::kRbd || before_spec.rigid_body_features);
    std::printf(knows_chain ? "the model knows the URDF's kinematics and inertias, nothing about "
                              "friction or other effects\n\n"
                            : "the model is told nothing about the robot: no masses, lengths or "
                              "friction\n\n");

    // 1. The rigid-body model alone.
    RobotModel before = MakeModel(before_spec, N, model_options);
    progress.Line("fitting " + start + " on the slow log");
    const FitSummary before_info = FitModel(train, settings, progress, &before);
    const Predictions before_pred = Predict(before, test);
    const Errors before_err = ComputeErrors(before_pred.mean, test.Y);
    std::printf("1. fit %s on train.csv (%d slow samples): %s, %s\n",
                ModelLabel(before_spec).c_str(), train.size(), ModelSize(before).c_str(),
                before_info.method_description.c_str());

    std::printf("   test error on test.csv (%d fast samples), RMS per joint:", test.size());
    for (int j = 0; j < N; ++j) std::printf(" tau%d %.4g N m", j + 1, before_err.rms[j]);
    std::printf("\n");

    // 2. What is it missing? Diagnose on the model's own (slow) log, so that the fast log
    // stays unseen until the final comparison.
    progress.Line("diagnosing on the slow log");
    const DiagnosisOptions diagnosis_options;
    const Diagnosis diagnosis =
        Diagnose(before, ModelInputs(before, train), train.Y, train.t, diagnosis_options);
    if (diagnosis.status != DiagnosisStatus::kOk) {
      throw NumericalError("the diagnosis failed: " + diagnosis.message);
    }
    std::printf("2. diagnose %s on train.csv:\n", ModelLabel(before_spec).c_str());
    std::string summary = DiagnosisSummary(diagnosis, before_spec, diagnosis_options);
    // The refit hint of the summary names TRAIN.csv and MODEL; the demo does it itself.
    summary = summary.substr(0, summary.find("to refit with every suggestion"));
    std::fputs(Indent(summary).c_str(), stdout);

    // 3. Add the suggestions and refit on the same slow log.
    std::vector<OutputFile> outputs;
    const std::string before_path = (dir / "model_before.json").string();
    const std::string after_path = (dir / "model_after.json").string();
    outputs.push_back({"--out", before_path, ModelFileText(before)});
    std::vector<std::pair<std::string, Predictions>> series = {
        {ModelLabel(before_spec), before_pred}};
    std::vector<report::ModelErrors> report_errors = {
        ReportErrors(ModelLabel(before_spec), before_err,
                     BandCoverage(before_pred.mean, before_pred.std,
                                  before.hyperparameters().noise_stds(), test.Y))};
    nlohmann::json comparison;
    comparison["robot"] = chain ? urdf_.urdf : robot_;
    comparison["hidden_effect"] = effect_;
    comparison["hidden_joint"] = joint_;
    comparison["before"] = {{"label", ModelLabel(before_spec)}, {"file", before_path}};
    Errors after_err = before_err;
    if (!diagnosis.suggestions.empty()) {
      const ModelSpec after_spec = WithSuggestions(before_spec, diagnosis);
      RobotModel after = MakeModel(after_spec, N, model_options);
      progress.Line("fitting " + ModelLabel(after_spec) + " on the slow log");
      FitModel(train, settings, progress, &after);
      const Predictions after_pred = Predict(after, test);
      after_err = ComputeErrors(after_pred.mean, test.Y);
      std::printf("3. refit %s on train.csv: %s\n", ModelLabel(after_spec).c_str(),
                  ModelSize(after).c_str());
      for (const FeatureCoefficient& c : after.Coefficients()) {
        // Features of one joint, on its torque (a coefficient shared by every joint is left
        // to the model file).
        if (c.joint < 1 || c.name.find('@') == std::string::npos) continue;
        std::printf("   fitted %s on tau%d: %.4g +- %.2g N m\n", c.name.c_str(), c.joint, c.value,
                    c.std);
      }
      outputs.push_back({"--out", after_path, ModelFileText(after)});
      series.emplace_back(ModelLabel(after_spec), after_pred);
      report_errors.push_back(
          ReportErrors(ModelLabel(after_spec), after_err,
                       BandCoverage(after_pred.mean, after_pred.std,
                                    after.hyperparameters().noise_stds(), test.Y)));
      comparison["after"] = {{"label", ModelLabel(after_spec)}, {"file", after_path}};
    } else {
      std::printf("3. nothing to add: the model is kept as it is\n");
    }

    // 4. Before and after, on the fast log.
    std::vector<std::vector<std::string>> rows = {{"joint", "RMS before", "RMS after", "change"}};
    comparison["joints"] = nlohmann::json::array();
    for (int j = 0; j <= N; ++j) {
      const double b = j < N ? before_err.rms[j] : before_err.overall_rms;
      const double a = j < N ? after_err.rms[j] : after_err.overall_rms;
      rows.push_back({j < N ? std::to_string(j + 1) : "all", Format("%.4g", b), Format("%.4g", a),
                      RelativeChange(b, a)});
      if (j < N) {
        comparison["joints"].push_back({{"joint", j + 1},
                                        {"rms_before", b},
                                        {"rms_after", a},
                                        {"relative_change", (a - b) / b},
                                        {"nmse_before", before_err.nmse[j]},
                                        {"nmse_after", after_err.nmse[j]}});
      }
    }
    comparison["overall"] = {{"rms_before", before_err.overall_rms},
                             {"rms_after", after_err.overall_rms}};
    std::printf("4. test error on test.csv (fast log, unseen), RMS in N m:\n%s",
                Table(rows, 3).c_str());

    report::ReportData r;
    r.title = "structgp demo: " + scenario.description;
    r.data_source = train_path + " (diagnosis), " + test_path + " (errors and plots)";
    r.joints = ReportJoints(test, series);
    r.has_diagnosis = true;
    r.diagnosis = diagnosis;
    r.diagnosed_states = report::JointStatesOf(train);  // the suggestions' residual plots
    r.errors = report_errors;
    r.notes.push_back("Simulated " + scenario.description + ".");
    r.notes.push_back(
        "Both models were fitted on the slow log (train.csv), which the diagnosis "
        "also used; the plots and errors are on the fast log (test.csv), which "
        "neither model nor diagnosis saw.");
    outputs.push_back({"--out", (dir / "findings.json").string(), ToJson(diagnosis)});
    outputs.push_back({"--out", (dir / "comparison.json").string(), comparison.dump(2) + "\n"});
    outputs.push_back({"--out", (dir / "report.html").string(), report::RenderHtml(r)});

    // Everything is computed: now write.
    std::error_code ec;
    fs::create_directories(dir, ec);
    if (!fs::is_directory(dir)) {
      throw UsageError("--out '" + dir_ + "': cannot create the directory" +
                       (ec ? ": " + ec.message() : std::string()));
    }
    CheckOutputPath("--out", train_path);
    CheckOutputPath("--out", test_path);
    WriteRobotCsv(train_path, train);
    WriteRobotCsv(test_path, test);
    WriteOutputs(outputs);
    std::printf("wrote %s: train.csv test.csv", dir_.c_str());
    for (const auto& f : outputs) std::printf(" %s", fs::path(f.path).filename().c_str());
    std::printf("\nnext: open %s; or run the steps yourself:\n",
                (dir / "report.html").string().c_str());
    std::printf("  structgp diagnose --model %s --data %s --json findings.json\n",
                before_path.c_str(), train_path.c_str());
    if (!diagnosis.suggestions.empty()) {
      std::printf("  structgp compare --model %s --model %s --data %s\n", before_path.c_str(),
                  after_path.c_str(), test_path.c_str());
    }
    return kExitOk;
  }

 private:
  static std::string Indent(const std::string& text) {
    std::string out;
    size_t begin = 0;
    while (begin < text.size()) {
      const size_t end = text.find('\n', begin);
      const std::string line = text.substr(begin, end == std::string::npos ? end : end - begin);
      out += "   " + line + "\n";
      if (end == std::string::npos) break;
      begin = end + 1;
    }
    return out;
  }

  std::string dir_ = "structgp-demo";
  std::string effect_ = "coulomb";
  int joint_ = 2;
  std::string robot_ = "two-link";
  std::string model_;
  RobotFlags urdf_;
  double magnitude_ = 0.1;
  double noise_ = 0.01;
  unsigned long seed_ = 1;
  std::string hyper_ = "ml";
  bool quiet_ = false;
};

}  // namespace

std::unique_ptr<Command> MakeDemoCommand() { return std::make_unique<DemoCommand>(); }

}  // namespace cli
}  // namespace structgp
