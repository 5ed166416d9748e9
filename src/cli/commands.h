#ifndef STRUCTGP_SRC_CLI_COMMANDS_H_
#define STRUCTGP_SRC_CLI_COMMANDS_H_

// The subcommands of the structgp program. Each registers its options on the application and,
// when it is the one given, runs: it returns the exit code or throws (main maps the exception
// to a message and an exit code, see common.h).

#include <CLI/CLI.hpp>
#include <memory>

namespace structgp {
namespace cli {

class Command {
 public:
  virtual ~Command() = default;
  /// Adds the subcommand and its options to app; returns the subcommand.
  virtual CLI::App* Register(CLI::App* app) = 0;
  /// Runs the subcommand with the parsed options.
  virtual int Run() = 0;
};

std::unique_ptr<Command> MakeFitCommand();
std::unique_ptr<Command> MakePredictCommand();
std::unique_ptr<Command> MakeEvaluateCommand();
std::unique_ptr<Command> MakeDiagnoseCommand();
std::unique_ptr<Command> MakeCompareCommand();
std::unique_ptr<Command> MakeDemoCommand();
std::unique_ptr<Command> MakePrepareCommand();
std::unique_ptr<Command> MakeReplayCommand();
std::unique_ptr<Command> MakeIdentifyCommand();

}  // namespace cli
}  // namespace structgp

#endif  // STRUCTGP_SRC_CLI_COMMANDS_H_
