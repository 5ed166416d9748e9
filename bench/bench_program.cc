#include "bench_program.h"

#include <cstdio>
#include <exception>
#include <sstream>
#include <stdexcept>

#include "structgp/io/data_error.h"

namespace structgp {
namespace {

// Thrown by ForEachFlag for --help; RunProgram prints the usage.
struct HelpRequested {};

int ToInt(const std::string& text, size_t* used) { return std::stoi(text, used); }

double ToDouble(const std::string& text, size_t* used) { return std::stod(text, used); }

std::uint64_t ToUint64(const std::string& text, size_t* used) {
  // std::stoull accepts a leading '-' (and wraps around): refused here.
  if (!text.empty() && text[0] == '-') throw std::invalid_argument("negative");
  return std::stoull(text, used);
}

// The value of `flag` converted by `convert` (all of it) and accepted by `ok`; otherwise throws
// std::invalid_argument("flag <name>: expected <what>, got '<value>'").
template <typename T, typename Ok>
T Converted(const Flag& flag, T (*convert)(const std::string&, size_t*), Ok ok, const char* what) {
  const std::string& value = flag.Value();
  size_t used = 0;
  T v{};
  try {
    v = convert(value, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used != value.size() || !ok(v)) {
    throw std::invalid_argument("flag " + flag.name() + ": expected " + what + ", got '" + value +
                                "'");
  }
  return v;
}

}  // namespace

Flag::Flag(const std::string& arg) : arg_(arg) {
  const size_t eq = arg.find('=');
  name_ = arg.substr(0, eq);
  has_value_ = eq != std::string::npos;
  if (has_value_) value_ = arg.substr(eq + 1);
}

const std::string& Flag::Value() const {
  if (!has_value_ || value_.empty()) {
    throw std::invalid_argument("flag " + name_ + " needs a value (" + name_ + "=...)");
  }
  return value_;
}

int Flag::Int() const {
  return Converted(
      *this, ToInt, [](int) { return true; }, "an integer");
}

int Flag::NonNegativeInt() const {
  return Converted(
      *this, ToInt, [](int v) { return v >= 0; }, "a non-negative integer");
}

std::uint64_t Flag::Uint64() const {
  return Converted(
      *this, ToUint64, [](std::uint64_t) { return true; }, "a non-negative integer");
}

double Flag::Number() const {
  return Converted(
      *this, ToDouble, [](double) { return true; }, "a number");
}

double Flag::PositiveNumber() const {
  return Converted(
      *this, ToDouble, [](double v) { return v > 0.0; }, "a positive number");
}

std::vector<std::string> Flag::List() const {
  std::vector<std::string> items;
  std::stringstream list(Value());
  for (std::string item; std::getline(list, item, ',');) {
    if (!item.empty()) items.push_back(item);
  }
  return items;
}

void ForEachFlag(int argc, char** argv, const std::function<bool(const Flag&)>& handle) {
  for (int i = 1; i < argc; ++i) {
    const Flag flag(argv[i]);
    if (flag.name() == "--help") throw HelpRequested();
    if (!handle(flag)) throw std::invalid_argument("unknown flag '" + flag.arg() + "'");
  }
}

std::string CommandLine(const std::string& name, int argc, char** argv) {
  std::string command = name;
  for (int i = 1; i < argc; ++i) command += std::string(" ") + argv[i];
  return command;
}

int RunProgram(const char* name, const char* usage, int (*run)(int, char**), int argc,
               char** argv) {
  try {
    return run(argc, argv);
  } catch (const HelpRequested&) {
    std::printf("%s", usage);
    return 0;
  } catch (const std::invalid_argument& e) {
    std::fprintf(stderr, "%s: %s\n%s", name, e.what(), usage);
    return 2;
  } catch (const DataError& e) {
    std::fprintf(stderr, "%s: %s\n", name, e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s: %s\n", name, e.what());
    return 1;
  }
}

}  // namespace structgp
