// structgp prepare: turns a raw log (joint positions against time, torques or motor currents)
// into a robot data file with q, qd, qdd and tau, by zero-phase low-pass filtering and
// central differences (structgp/prepare/prepare.h).

#include "structgp/prepare/prepare.h"

#include <cstdio>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "commands.h"
#include "common.h"
#include "structgp/io/csv.h"
#include "structgp/prepare/butterworth.h"
#include "structgp/prepare/raw_log.h"

namespace structgp {
namespace cli {
namespace {

// The library names PrepareOptions fields in its messages; the program names its flags.
std::string WithFlagNames(std::string message) {
  const std::pair<const char*, const char*> names[] = {
      {"PrepareOptions::cutoff_hz", "--cutoff"},
      {"PrepareOptions::order", "--order"},
      {"PrepareOptions::sample_rate_hz", "--rate"},
      {"PrepareOptions::current_gains", "--current-gains"},
      {"PrepareOptions::max_time_jitter", "--max-jitter"},
      {"PrepareOptions::trim_edges", "--trim-edges"},
  };
  for (const auto& [field, flag] : names) {
    const std::string from = field;
    for (std::size_t at = message.find(from); at != std::string::npos; at = message.find(from)) {
      message.replace(at, from.size(), flag);
    }
  }
  return message;
}

class PrepareCommand : public Command {
 public:
  CLI::App* Register(CLI::App* app) override {
    CLI::App* cmd = app->add_subcommand(
        "prepare",
        "Derive qd and qdd from a raw log of joint positions (zero-phase Butterworth low-pass, "
        "central differences) and write a data file for 'structgp fit'");
    cmd->add_option("--in", in_,
                    "Raw log: CSV with q1..qN, tau1..tauN or i1..iN (motor currents), and "
                    "optionally t (s); other columns are ignored")
        ->required();
    cmd->add_option("--out", out_,
                    "Data file to write: t, q1..qN (filtered), qd1..qdN, qdd1..qddN, tau1..tauN "
                    "(replaced atomically; - for stdout)")
        ->required();
    cmd->add_option("--cutoff", options_.cutoff_hz,
                    "Low-pass cut-off frequency in Hz (default: 10 Hz, or a fifth of the "
                    "sampling rate when that is lower); must be below half the sampling rate")
        ->check(CLI::PositiveNumber);
    cmd->add_option("--order", options_.order,
                    "Butterworth order of each of the two (forward, backward) passes")
        ->check(CLI::Range(1, kMaxButterworthOrder))
        ->capture_default_str();
    cmd->add_option("--current-gains", gains_,
                    "Torque per unit of motor current for each joint, comma separated "
                    "(g1,g2,...): tau_j = g_j * i_j from the columns i1..iN")
        ->delimiter(',');
    cmd->add_option("--rate", options_.sample_rate_hz,
                    "Sampling rate in Hz: required when the log has no t column; otherwise "
                    "checked against the median time step (1% tolerance)")
        ->check(CLI::PositiveNumber);
    cmd->add_option("--max-jitter", options_.max_time_jitter,
                    "Largest accepted deviation of a time step from the median step, as a "
                    "fraction (0.1 = 10%)")
        ->check(CLI::Range(1e-9, 1e9))
        ->capture_default_str();
    cmd->add_flag("--filter-torque", options_.filter_torque,
                  "Also smooth the torques with the same zero-phase filter");
    cmd->add_flag("--trim-edges", options_.trim_edges,
                  "Drop one cut-off period of samples (rate / cutoff) at each end, where the "
                  "filter's edge transient biases qd and qdd");
    cmd->add_flag("-q,--quiet", quiet_, "No progress lines on stderr");
    cmd->footer(
        "Example:\n"
        "  structgp prepare --in log.csv --out train.csv --cutoff 15 --current-gains 0.9,1.1\n"
        "The positions are filtered forward and backward (zero phase), qd and qdd are the\n"
        "three-point central differences of the filtered positions. The time column must\n"
        "strictly increase with near-uniform steps (see --max-jitter); logs with gaps must be\n"
        "split first. See docs/cli.md.");
    return cmd;
  }

  int Run() override {
    CheckOutputPath("--out", out_);
    std::FILE* const text_out = TextStream({{"--out", out_}});
    const Progress progress("prepare", quiet_);
    progress.Line("reading " + in_);
    const RawLog log = ReadRawLogCsv(in_);
    if (!gains_.empty() && static_cast<int>(gains_.size()) != log.num_joints) {
      throw UsageError("--current-gains: expected " + std::to_string(log.num_joints) +
                       " gains (one per joint; '" + in_ + "' has q1..q" +
                       std::to_string(log.num_joints) + "), got " + std::to_string(gains_.size()));
    }
    if (!gains_.empty() && !log.has_current()) {
      throw UsageError("--current-gains: '" + in_ + "' has no current columns i1..i" +
                       std::to_string(log.num_joints));
    }
    if (gains_.empty() && !log.has_torque()) {
      throw UsageError("'" + in_ + "' has motor currents i1..i" + std::to_string(log.num_joints) +
                       " but no torques: give --current-gains to convert them");
    }
    options_.current_gains = gains_;
    PrepareSummary summary;
    RobotData data;
    try {
      data = PrepareRawLog(log, options_, &summary);
    } catch (const std::invalid_argument& e) {
      throw UsageError(WithFlagNames(e.what()));
    }
    progress.Line("filtered and differentiated " + std::to_string(log.size()) + " samples");
    const std::vector<OutputFile> outputs = {{"--out", out_, RobotCsvText(data)}};
    WriteOutputs(outputs);
    std::fprintf(
        text_out, "%s",
        Table(
            {{"joints", std::to_string(summary.num_joints)},
             {"samples written",
              std::to_string(summary.num_samples) +
                  (options_.trim_edges ? Format(" (%d dropped at each end)", summary.edge_samples)
                                       : std::string())},
             {"sampling rate", Format("%.6g Hz (%s)", summary.sample_rate_hz,
                                      summary.rate_from_time ? "median step of t" : "--rate")},
             {"time step jitter", Format("%.3g%% at most", 100.0 * summary.max_time_jitter)},
             {"low-pass", Format("Butterworth order %d, cut-off %.6g Hz, "
                                 "forward-backward (zero phase)",
                                 summary.order, summary.cutoff_hz)},
             {"edge samples", Format("%d at each end (bias in qd, qdd there%s)",
                                     summary.edge_samples, options_.trim_edges ? ", dropped" : "")},
             {"torque", std::string(summary.torque_from_current ? "currents x --current-gains"
                                                                : "tau columns") +
                            (summary.torque_filtered ? ", filtered" : "")}},
            0)
            .c_str());
    PrintWritten(text_out, outputs);
    return kExitOk;
  }

 private:
  std::string in_, out_;
  std::vector<double> gains_;
  PrepareOptions options_;
  bool quiet_ = false;
};

}  // namespace

std::unique_ptr<Command> MakePrepareCommand() { return std::make_unique<PrepareCommand>(); }

}  // namespace cli
}  // namespace structgp
