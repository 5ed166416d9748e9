#include "experiment_program.h"

#include <algorithm>
#include <cstdio>
#include <exception>
#include <sstream>
#include <stdexcept>

#include "structgp/io/data_error.h"

namespace structgp {
namespace {

// A validator of numbers for which accept(value) holds; `what` completes "expected a number ".
template <typename Accept>
CLI::Validator NumberCheck(const std::string& what, Accept accept) {
  return CLI::Validator(
      [what, accept](std::string& text) -> std::string {
        double value = 0.0;
        if (CLI::detail::lexical_cast(text, value) && accept(value)) return std::string();
        return "expected a number " + what + ", got '" + text + "'";
      },
      what);
}

std::string Number(double value) {
  std::ostringstream text;
  text << value;
  return text.str();
}

}  // namespace

CLI::Validator AtLeast(double bound) {
  return NumberCheck(">= " + Number(bound), [bound](double v) { return v >= bound; });
}

CLI::Validator GreaterThan(double bound) {
  return NumberCheck("> " + Number(bound), [bound](double v) { return v > bound; });
}

CLI::Option* AddListFlag(CLI::App* app, const std::string& name, std::vector<std::string>* items,
                         const std::string& description) {
  return app
      ->add_option_function<std::vector<std::string>>(
          name,
          [items](const std::vector<std::string>& given) {
            items->clear();
            std::copy_if(given.begin(), given.end(), std::back_inserter(*items),
                         [](const std::string& item) { return !item.empty(); });
          },
          description)
      ->delimiter(',');
}

std::string CommandLine(const std::string& name, int argc, char** argv) {
  std::string command = name;
  for (int i = 1; i < argc; ++i) command += std::string(" ") + argv[i];
  return command;
}

int RunProgram(CLI::App* app, int argc, char** argv, const std::function<int()>& run) {
  const std::string name = app->get_name();
  const auto fail = [&name](const char* what, bool hint, int status) {
    std::fprintf(stderr, "%s: %s\n", name.c_str(), what);
    if (hint) std::fprintf(stderr, "run '%s --help' for the flags\n", name.c_str());
    return status;
  };
  try {
    app->parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app->exit(e);
  } catch (const CLI::ParseError& e) {
    return fail(e.what(), true, kExitUsage);
  }
  try {
    return run();
  } catch (const std::invalid_argument& e) {
    return fail(e.what(), true, kExitUsage);
  } catch (const DataError& e) {
    return fail(e.what(), false, kExitUsage);
  } catch (const std::exception& e) {
    return fail(e.what(), false, kExitFailure);
  }
}

}  // namespace structgp
