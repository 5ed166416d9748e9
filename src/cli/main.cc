// The structgp program: fit, predict, evaluate, diagnose, compare, prepare, replay and demo.
//
// Exit codes: 0 success; 2 a mistake in the command line or an input file (the message names
// the flag, or the file with line and column); 1 a numerical failure. Outputs are written only
// once everything has been computed, each atomically, so a failed run leaves existing files
// untouched.

#include <CLI/CLI.hpp>
#include <cstdio>
#include <exception>
#include <memory>
#include <new>
#include <stdexcept>
#include <string>
#include <vector>

#include "commands.h"
#include "common.h"
#include "structgp/core/version.h"
#include "structgp/feature/effects.h"
#include "structgp/io/data_error.h"
#include "structgp/model/model_spec.h"

namespace structgp {
namespace cli {
namespace {

int Fail(const std::string& context, const std::string& message, int code) {
  std::fprintf(stderr, "%s: error: %s\n", context.c_str(), message.c_str());
  return code;
}

// One line per base model and per registered effect, from the library's lists (ModelSpec's
// BaseModels, the effect registry), for the top-level --help.
std::string ModelsAndEffectsHelp() {
  auto pad = [](std::string s, size_t width) {
    if (s.size() < width) s.append(width - s.size(), ' ');
    return s;
  };
  std::string text = "Models (--model BASE or BASE+fri; +fri adds viscous, Coulomb and offset "
                     "friction per joint):\n";
  for (BaseModel base : BaseModels()) {
    text += "  " + pad(ToString(base), 10) + Describe(base) + "\n";
  }
  text += "Effects (--effects NAME[@JOINTS][:KEY=VALUE;...], e.g. coulomb@2, "
          "cogging@3:period=0.3):\n";
  for (const std::string& name : EffectNames()) {
    std::string line = "  " + pad(name, 10) + MakeEffectPrototype(name)->Describe();
    std::string params;
    for (const EffectParameter& p : EffectParameterInfo(name)) {
      const std::string unit = p.unit.empty() ? std::string() : " " + p.unit;
      params += (params.empty() ? "" : ", ") + p.name +
                (p.required ? " (required" + (unit.empty() ? "" : "," + unit) + ")"
                            : "=" + Format("%g", p.default_value) + unit);
    }
    text += line + (params.empty() ? "" : "; " + params) + "\n";
  }
  return text;
}

int Main(int argc, char** argv) {
  CLI::App app(
      "structgp: Gaussian processes with structured kernels for robot inverse dynamics.\n"
      "Fits a model of the joint torques from logged (q, qd, qdd, tau), and tells you which\n"
      "physics it is missing (friction, cogging, offsets, drift).",
      "structgp");
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string("structgp ") + Version(),
                       "Print the version and exit");
  app.footer(ModelsAndEffectsHelp() +
             "\nStart with:  structgp demo\nEach subcommand has --help. Joints are 1-based. "
             "An output file given as - is written to stdout.");
  std::vector<std::unique_ptr<Command>> commands;
  commands.push_back(MakeDemoCommand());
  commands.push_back(MakeFitCommand());
  commands.push_back(MakePredictCommand());
  commands.push_back(MakeEvaluateCommand());
  commands.push_back(MakeDiagnoseCommand());
  commands.push_back(MakeCompareCommand());
  commands.push_back(MakePrepareCommand());
  commands.push_back(MakeReplayCommand());
  commands.push_back(MakeIdentifyCommand());
  std::vector<CLI::App*> subcommands;
  subcommands.reserve(commands.size());
  for (auto& c : commands) subcommands.push_back(c->Register(&app));

  // CLI11 reports a misspelt subcommand as a missing one; name it instead.
  if (argc > 1 && argv[1][0] != '-') {
    std::string names;
    bool known = false;
    for (const CLI::App* sub : subcommands) {
      known = known || sub->get_name() == argv[1];
      names += (names.empty() ? "" : ", ") + sub->get_name();
    }
    if (!known) {
      Fail("structgp",
           std::string("unknown subcommand '") + argv[1] + "' (expected one of " + names + ")",
           kExitUsage);
      std::fprintf(stderr, "run 'structgp --help' for the options\n");
      return kExitUsage;
    }
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::string context = "structgp";
    for (const CLI::App* sub : app.get_subcommands()) context += " " + sub->get_name();
    Fail(context, e.what(), kExitUsage);
    std::fprintf(stderr, "run '%s --help' for the options\n", context.c_str());
    return kExitUsage;
  }

  for (size_t i = 0; i < commands.size(); ++i) {
    if (!subcommands[i]->parsed()) continue;
    const std::string context = "structgp " + subcommands[i]->get_name();
    try {
      return commands[i]->Run();
    } catch (const UsageError& e) {
      return Fail(context, e.what(), kExitUsage);
    } catch (const DataError& e) {
      return Fail(context, e.what(), kExitUsage);
    } catch (const std::invalid_argument& e) {
      return Fail(context, e.what(), kExitUsage);
    } catch (const NumericalError& e) {
      return Fail(context, e.what(), kExitNumerical);
    } catch (const std::bad_alloc&) {
      return Fail(context, "out of memory", kExitNumerical);
    } catch (const std::exception& e) {
      return Fail(context, e.what(), kExitNumerical);
    }
  }
  return Fail("structgp", "no subcommand given", kExitUsage);
}

}  // namespace
}  // namespace cli
}  // namespace structgp

int main(int argc, char** argv) {
  try {
    return structgp::cli::Main(argc, argv);
  } catch (const std::exception& e) {
    // Setting up the command line itself failed (out of memory): nothing else to report.
    std::fprintf(stderr, "structgp: error: %s\n", e.what());
    return structgp::cli::kExitNumerical;
  }
}
