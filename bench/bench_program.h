// The command line of a bench program: --name[=value] flags and a main() that turns the
// program's exceptions into a message and an exit status.
//
//   int Run(int argc, char** argv) {
//     Flags f;
//     ForEachFlag(argc, argv, [&](const Flag& flag) {
//       if (flag.name() == "--train") {
//         f.train = flag.Int();
//       } else {
//         return false;  // unknown flag
//       }
//       return true;
//     });
//     ...
//   }
//   int main(int argc, char** argv) {
//     return structgp::RunProgram("name", kUsage, Run, argc, argv);
//   }

#ifndef STRUCTGP_BENCH_BENCH_PROGRAM_H_
#define STRUCTGP_BENCH_BENCH_PROGRAM_H_

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace structgp {

// One argument "--name" or "--name=value". The typed getters throw std::invalid_argument
// naming the flag when the value is missing, empty or not of the type.
class Flag {
 public:
  explicit Flag(const std::string& arg);

  // The whole argument as given.
  const std::string& arg() const { return arg_; }
  // The part before '=' ("--name").
  const std::string& name() const { return name_; }

  // The text after '='; throws unless there is a non-empty value.
  const std::string& Value() const;
  // An integer (any sign).
  int Int() const;
  // An integer >= 0.
  int NonNegativeInt() const;
  // A 64-bit unsigned integer (a seed).
  std::uint64_t Uint64() const;
  // A number (any sign).
  double Number() const;
  // A number > 0.
  double PositiveNumber() const;
  // The comma-separated items of the value, empty items dropped.
  std::vector<std::string> List() const;

 private:
  std::string arg_, name_, value_;
  bool has_value_ = false;
};

// Calls handle(flag) for argv[1..argc-1] in order. "--help" (with or without a value) stops the
// parse and makes RunProgram print the usage; a flag for which handle returns false throws
// std::invalid_argument("unknown flag '<arg>'").
void ForEachFlag(int argc, char** argv, const std::function<bool(const Flag&)>& handle);

// "<name> <argv[1]> <argv[2]> ...": the command as typed, for the files a program writes.
std::string CommandLine(const std::string& name, int argc, char** argv);

// The body of main(): returns run(argc, argv), or, when it throws,
//   --help (ForEachFlag):     prints `usage` on stdout, exit status 0;
//   std::invalid_argument:   "<name>: <what>" and `usage` on stderr, exit status 2;
//   DataError (bad input):   "<name>: <what>" on stderr, exit status 2;
//   any other std::exception: "<name>: <what>" on stderr, exit status 1.
int RunProgram(const char* name, const char* usage, int (*run)(int, char**), int argc, char** argv);

}  // namespace structgp

#endif  // STRUCTGP_BENCH_BENCH_PROGRAM_H_
