#ifndef STRUCTGP_TESTS_CLI_RUNNER_H_
#define STRUCTGP_TESTS_CLI_RUNNER_H_

// Runs the structgp program (path in the compile definition STRUCTGP_CLI_PATH) through the
// shell, capturing its exit code, stdout and stderr.

#include <sys/wait.h>

#include <cstdlib>
#include <string>
#include <vector>

#include "temp_files.h"

#ifndef STRUCTGP_CLI_PATH
#error "STRUCTGP_CLI_PATH must name the structgp program"
#endif

namespace structgp {
namespace testing {

// The argument in single quotes for the shell.
inline std::string ShellQuote(const std::string& arg) {
  std::string out = "'";
  for (char c : arg) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

struct CliResult {
  int code = -1;  // exit status, -1 when the program did not exit normally
  std::string out;
  std::string err;
};

// Runs the program with the arguments; stdout and stderr go through files in `dir`.
inline CliResult RunCli(const TempDir& dir, const std::vector<std::string>& args) {
  std::string command = ShellQuote(STRUCTGP_CLI_PATH);
  for (const auto& a : args) command += " " + ShellQuote(a);
  const std::string out = dir.File("stdout.txt");
  const std::string err = dir.File("stderr.txt");
  command += " > " + ShellQuote(out) + " 2> " + ShellQuote(err);
  const int status = std::system(command.c_str());
  CliResult r;
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.out = ReadFile(out);
  r.err = ReadFile(err);
  return r;
}

inline bool Contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

}  // namespace testing
}  // namespace structgp

#endif  // STRUCTGP_TESTS_CLI_RUNNER_H_
