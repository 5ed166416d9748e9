// structgp identify: a robot's kinematic chain found from a torque log, written as a URDF for
// the rbd models (fit/chain_identification.h).

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "commands.h"
#include "common.h"
#include "structgp/fit/chain_identification.h"

namespace structgp {
namespace cli {
namespace {

class IdentifyCommand : public Command {
 public:
  CLI::App* Register(CLI::App* app) override {
    CLI::App* cmd = app->add_subcommand(
        "identify",
        "Find the robot's kinematic chain (where each joint axis lies) from a torque log and "
        "write it as a URDF, for rbd models of a robot whose URDF is not at hand");
    cmd->add_option("--data", data_,
                    "Data: CSV with columns q1..qN, qd1..qdN, qdd1..qddN, tau1..tauN; several "
                    "files (--data A --data B: a slow training log and a faster one, say) are "
                    "searched together")
        ->required();
    cmd->add_option("--out", out_, "URDF file to write (replaced atomically; - for stdout)")
        ->required();
    cmd->add_option("--json", json_,
                    "Also write the summary as JSON: the kinematic parameters, each start's "
                    "cost and the residual per joint (- for stdout)");
    cmd->add_flag("--no-friction", no_friction_,
                  "Fit the rigid body alone (by default the friction of +fri, viscous, Coulomb "
                  "and an offset per joint, is fitted beside it, so that friction does not bend "
                  "the kinematics)");
    cmd->add_option("--effects", effects_,
                    "Effects fitted beside the chain, as fit's --effects takes them (e.g. "
                    "'cogging@1:period=0.3' from a diagnosis): a torque no chain makes then "
                    "does not bend the kinematics");
    cmd->add_option("--starts", options_.starts,
                    "Random starts of the search, each screened by a few iterations on few rows")
        ->check(CLI::Range(1, 100000))
        ->capture_default_str();
    cmd->add_option("--kept-starts", options_.kept_starts,
                    "Screened starts of least cost searched to the end; the best of them wins")
        ->check(CLI::Range(1, 100000))
        ->capture_default_str();
    cmd->add_option("--rows", options_.search_rows,
                    "Evenly spaced rows of the search from each start (each costs a regressor "
                    "per row and cost evaluation)")
        ->check(CLI::Range(2, 1000000))
        ->capture_default_str();
    cmd->add_option("--refine-rows", options_.refine_rows,
                    "Evenly spaced rows on which the best start is searched again")
        ->check(CLI::Range(0, 1000000))
        ->capture_default_str();
    cmd->add_option("--rounds", options_.max_rounds,
                    "Rounds of --starts starts at most: another round is drawn while fewer than "
                    "two kept starts have reached the least cost, or while the best chain leaves "
                    "more than 1.5 times its residual's white noise on a joint")
        ->check(CLI::Range(1, 1000))
        ->capture_default_str();
    cmd->add_option("--seed", options_.seed, "Seed of the random starts")->capture_default_str();
    cmd->add_option("--name", options_.robot_name, "Robot name in the URDF")
        ->capture_default_str();
    cmd->add_option("--threads", options_.num_threads,
                    "Starts searched at once (the result is the same for any number; default: "
                    "the machine's hardware threads)")
        ->check(CLI::Range(1, kMaxThreads));
    cmd->add_flag("-q,--quiet", quiet_, "No progress lines on stderr");
    cmd->footer(
        "The search: Levenberg-Marquardt on the 4N - 4 kinematic parameters (modified\n"
        "Denavit-Hartenberg, and the lean of joint 1's axis from gravity along -z), the\n"
        "inertial parameters and friction by least squares at each step; several random starts.\n"
        "The URDF's inertial values are placeholders: fit them with rbd. Example:\n"
        "  structgp identify --data train.csv --out robot.urdf\n"
        "  structgp fit --data train.csv --model rbd+fri --urdf robot.urdf --out model.json\n"
        "When a diagnosis of that model names an effect, identify again with it:\n"
        "  structgp identify --data train.csv --effects cogging@1:period=0.3 --out robot.urdf");
    return cmd;
  }

  int Run() override {
    CheckOutputPath("--out", out_);
    if (!json_.empty()) CheckOutputPath("--json", json_);
    std::FILE* const text_out = TextStream({{"--out", out_}, {"--json", json_}});
    options_.friction = !no_friction_;
    if (!effects_.empty()) options_.effects = ParseSpecFlags("rbd", effects_).effects;
    if (options_.num_threads < 1) options_.num_threads = MachineThreads();
    const Progress progress("identify", quiet_);
    // Every file's rows, one after the other, with the same joints, all timed or none.
    RobotData data;
    std::string files;
    for (const std::string& path : data_) {
      progress.Line("reading " + path);
      const RobotData part = files.empty() ? ReadData(path) : ReadData(path, data.num_joints);
      if (part.target == RobotData::Target::kCurrent) {
        throw UsageError(path + ": has motor currents (cur1..cur" +
                         std::to_string(part.num_joints) +
                         "), identify needs joint torques (tau1..): the chain's inertial "
                         "parameters act on every joint's torque, and a current's gain per "
                         "joint is not known");
      }
      if (files.empty()) {
        data = part;
      } else {
        if (part.has_time() != data.has_time()) {
          throw DataError(path, 1, 0,
                          std::string(part.has_time() ? "has" : "has no") + " 't' column, but " +
                              data_.front() + (data.has_time() ? " has one" : " has none") +
                              ": the files are searched together, all with their times or none");
        }
        auto append = [](Matrix* to, const Matrix& rows) {
          to->conservativeResize(to->rows() + rows.rows(), Eigen::NoChange);
          to->bottomRows(rows.rows()) = rows;
        };
        append(&data.X, part.X);
        append(&data.Y, part.Y);
        if (data.has_time()) {
          data.t.conservativeResize(data.t.size() + part.t.size());
          data.t.tail(part.t.size()) = part.t;
        }
      }
      files += (files.empty() ? "" : ", ") + path;
    }
    const int N = data.num_joints;
    progress.Line("searching the kinematics of " + std::to_string(N) + " joints from " +
                  std::to_string(options_.starts) + " starts (" +
                  std::to_string(options_.num_threads) + " at once)");
    // With the time when the log has one (effects that use it read it).
    const ChainIdentificationSummary s = IdentifyChain(data.X, data.t, data.Y, options_);
    progress.Line("done");

    const std::vector<std::string> names = ChainKinematicNames(N);
    // The library's JSON of the search, after the data it ran on.
    nlohmann::ordered_json doc = {
        {"data", data_.size() == 1 ? nlohmann::ordered_json(data_.front())
                                   : nlohmann::ordered_json(data_)},
        {"num_samples", data.X.rows()}};
    doc.update(nlohmann::ordered_json::parse(ToJson(s, options_)));

    std::fprintf(text_out, "data   %s: %d samples, %d joints\n", files.c_str(),
                 static_cast<int>(data.X.rows()), N);
    const int kept = static_cast<int>(s.starts.size());
    if (kept < options_.starts * s.rounds) {
      std::fprintf(text_out, "search %d starts screened (%d iterations on %d rows), the %d best "
                             "searched on %d rows",
                   options_.starts * s.rounds, options_.screen_iterations,
                   std::min(data.size(), options_.screen_rows), kept,
                   std::min(data.size(), options_.search_rows));
      if (s.rounds > 1) std::fprintf(text_out, " (%d rounds)", s.rounds);
      std::fputs(": ", text_out);
    } else {
      std::fprintf(text_out, "search %d starts on %d rows: ", kept,
                   std::min(data.size(), options_.search_rows));
    }
    std::fprintf(text_out, "best cost %.4g (start %d), %d of %d reached it",
                 *std::min_element(s.start_costs.begin(), s.start_costs.end()), s.best_start + 1,
                 s.starts_at_best, kept);
    if (s.moves_kept > 0) {
      std::fprintf(text_out, "; %d length%s set to 0: %.4g", s.moves_kept,
                   s.moves_kept > 1 ? "s" : "", s.moved_cost);
    }
    if (std::isfinite(s.refined_cost)) {
      std::fprintf(text_out, "; refined on %d rows: %.4g",
                   std::min(data.size(), options_.refine_rows), s.refined_cost);
    }
    std::fprintf(text_out, "\n       (cost: the mean squared residual, each joint's torque divided "
                           "by its RMS)\n");
    std::vector<std::vector<std::string>> rows = {
        {"joint", "torque RMS", "residual RMS", "residual / torque", "noise", "residual / noise"}};
    // A residual well above the white noise in it: a smooth misfit the chain leaves.
    const double misfit_ratio = options_.misfit_ratio;
    std::string misfit;
    for (int j = 0; j < N; ++j) {
      const double ratio = s.residual_rms[j] / s.noise[j];
      rows.push_back({std::to_string(j + 1), Format("%.4g", s.torque_rms[j]),
                      Format("%.4g", s.residual_rms[j]),
                      Percent(s.residual_rms[j] / s.torque_rms[j]), Format("%.4g", s.noise[j]),
                      Format("%.3g", ratio)});
      if (!(ratio <= misfit_ratio)) misfit += (misfit.empty() ? "" : ", ") + std::to_string(j + 1);
    }
    std::fputs(Table(rows).c_str(), text_out);
    std::string kinematics;
    for (size_t k = 0; k < names.size(); ++k) {
      kinematics += (k ? " " : "") + names[k] + "=" +
                    Format("%.4g", s.kinematics[static_cast<Eigen::Index>(k)]);
    }
    std::fprintf(text_out, "kinematics (rad, m): %s\n", kinematics.c_str());
    if (!s.undetermined.empty()) {
      std::string list;
      for (int k : s.undetermined) {
        const Eigen::Index i = k;
        list += Format("\n  %-8s moved by 0.1 changes the cost by %.2g%%, the torques at twice "
                       "the speed by %.3g times the residual",
                       names[static_cast<size_t>(k)].c_str(), 100.0 * s.cost_change[i],
                       s.faster_change[i]);
      }
      std::fprintf(text_out,
                   "warning: this log does not determine %zu kinematic parameter%s that faster "
                   "motion would show:%s\n  their values are a guess; a model on this URDF may "
                   "predict other motion badly: identify on a log with faster and wider motion\n",
                   s.undetermined.size(), s.undetermined.size() > 1 ? "s" : "", list.c_str());
    }
    if (!misfit.empty()) {
      std::fprintf(text_out,
                   "warning: the residual is more than %.3g times its white noise on joint%s %s "
                   "(noise: from the residual's successive differences): the chain misses a "
                   "smooth part of those torques. Either the search stopped at a wrong chain "
                   "(try --rounds %d, or another --seed) or the log holds what no chain makes "
                   "(fit rbd+fri on this URDF, diagnose it, and identify again with the "
                   "--effects it names)\n",
                   misfit_ratio, misfit.find(',') == std::string::npos ? "" : "s", misfit.c_str(),
                   2 * options_.max_rounds);
    }
    if (s.starts_at_best < 2 && kept > 1) {
      std::fprintf(text_out,
                   "warning: only one start reached the least cost in %d round%s; the search may "
                   "not have found the best chain (try --rounds %d), or no chain explains the "
                   "torques (see the residuals above; diagnose rbd on this URDF and identify "
                   "again with the --effects it names)\n",
                   s.rounds, s.rounds > 1 ? "s" : "", 2 * options_.max_rounds);
    }
    const std::vector<OutputFile> outputs = [&] {
      std::vector<OutputFile> o = {{"--out", out_, s.urdf}};
      if (!json_.empty()) o.push_back({"--json", json_, doc.dump(2) + "\n"});
      return o;
    }();
    WriteOutputs(outputs);
    PrintWritten(text_out, outputs);
    if (!IsStdout(out_)) {
      const std::string effects =
          options_.effects.empty() ? "" : " --effects '" + ToString(options_.effects) + "'";
      std::fprintf(text_out,
                   "next: structgp fit --data %s --model rbd%s --urdf %s%s --out model.json\n",
                   data_.front().c_str(), options_.friction ? "+fri" : "", out_.c_str(),
                   effects.c_str());
    }
    return kExitOk;
  }

 private:
  std::vector<std::string> data_;
  std::string out_, json_, effects_;
  bool no_friction_ = false;
  bool quiet_ = false;
  ChainIdentificationOptions options_ = [] {
    ChainIdentificationOptions o;
    o.num_threads = 0;  // the machine's, unless --threads
    return o;
  }();
};

}  // namespace

std::unique_ptr<Command> MakeIdentifyCommand() { return std::make_unique<IdentifyCommand>(); }

}  // namespace cli
}  // namespace structgp
