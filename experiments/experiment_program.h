// The command line of an experiment program (CLI11: "--name=value" and "--name value" alike;
// a value that is not of the flag's type, or out of its range, is refused) and a main() that
// turns the program's exceptions into a message and an exit status.
//
//   int main(int argc, char** argv) {
//     CLI::App app("what the program does", "name");
//     Flags f;
//     AddFlag(&app, "--train", &f.train, "training rows")->check(CLI::PositiveNumber);
//     return structgp::RunProgram(&app, argc, argv, [&] { return Run(f, argc, argv); });
//   }

#ifndef STRUCTGP_EXPERIMENTS_EXPERIMENT_PROGRAM_H_
#define STRUCTGP_EXPERIMENTS_EXPERIMENT_PROGRAM_H_

#include <CLI/CLI.hpp>
#include <functional>
#include <string>
#include <type_traits>
#include <vector>

namespace structgp {

// Exit status of a command line that cannot be used (an unknown flag, a bad value, a bad
// input file) and of a run that failed otherwise; the program's own statuses (3: a --check
// failed, 77: no data) are above these.
inline constexpr int kExitUsage = 2;
inline constexpr int kExitFailure = 1;

// Checks of a flag's value (option->check(AtLeast(1))): "expected a number >= 1, got '0'".
// Unlike CLI::Range they refuse "nan".
CLI::Validator AtLeast(double bound);
CLI::Validator GreaterThan(double bound);

// A flag with a value bound to *value; the help shows the default (the value on entry). An
// unsigned value refuses a sign (CLI11 alone would wrap "-1" around).
template <typename T>
CLI::Option* AddFlag(CLI::App* app, const std::string& name, T* value,
                     const std::string& description) {
  CLI::Option* option = app->add_option(name, *value, description)->capture_default_str();
  if constexpr (std::is_unsigned_v<T>) {
    CLI::Validator no_sign = AtLeast(0.0);
    no_sign.description("");  // "UINT" says it in the help
    option->check(no_sign);
  }
  return option;
}

// A comma-separated list ("--models=pol,rbf"); empty items are dropped.
CLI::Option* AddListFlag(CLI::App* app, const std::string& name, std::vector<std::string>* items,
                         const std::string& description);

// "<name> <argv[1]> <argv[2]> ...": the command as typed, for the files a program writes.
std::string CommandLine(const std::string& name, int argc, char** argv);

// The body of main(): parses argv with *app, then returns run(), or
//   --help:                                  prints the help on stdout, exit status 0;
//   a flag CLI11 refuses (unknown, bad value): "<name>: <what>" and a hint on stderr, kExitUsage;
//   std::invalid_argument from run:          "<name>: <what>" and a hint on stderr, kExitUsage;
//   DataError (a bad input file):            "<name>: <what>" on stderr, kExitUsage;
//   any other std::exception:                "<name>: <what>" on stderr, kExitFailure.
int RunProgram(CLI::App* app, int argc, char** argv, const std::function<int()>& run);

}  // namespace structgp

#endif  // STRUCTGP_EXPERIMENTS_EXPERIMENT_PROGRAM_H_
