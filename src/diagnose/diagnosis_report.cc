#include "structgp/diagnose/diagnosis_report.h"

#include <sstream>
#include <stdexcept>
#include <vector>

#include "structgp/feature/effects.h"
#include "structgp/internal/text.h"

namespace structgp {
namespace {

using internal::Format;
using internal::Table;

// A variable along which the residual concentrates is shown when its bin means explain at
// least this fraction of the residual variance.
constexpr double kMinExplained = 0.05;

}  // namespace

std::string DescribeEffect(const Suggestion& s) {
  try {
    return MakeEffect(s.effect, s.params)->Describe();
  } catch (const std::invalid_argument&) {
    return s.effect;  // no longer registered: its name is all there is
  }
}

ModelSpec WithSuggestions(const ModelSpec& spec, const Diagnosis& diagnosis) {
  ModelSpec out = spec;
  for (const Suggestion& s : diagnosis.suggestions) {
    out.effects.push_back(EffectSpec{s.effect, {s.joint}, s.params});
  }
  return out;
}

std::string DiagnosisReport(const Diagnosis& d, const ModelSpec& spec,
                            const DiagnosisOptions& options) {
  std::ostringstream os;
  if (d.status != DiagnosisStatus::kOk) {
    os << "the diagnosis failed (" << ToString(d.status) << "): " << d.message << "\n";
    return os.str();
  }
  std::vector<std::vector<std::string>> rows = {
      {"joint", "RMS", "nMSE", "noise est.", "error concentrates along"}};
  for (const JointFinding& f : d.joints) {
    std::string where = "-";
    if (!f.concentrations.empty() && f.concentrations.front().explained >= kMinExplained) {
      const Concentration& c = f.concentrations.front();
      where =
          Format("%s (explains %.0f%%; worst bin %s in [%.3g, %.3g], RMS %.3g)", c.variable.c_str(),
                 100.0 * c.explained, c.variable.c_str(), c.bin_low, c.bin_high, c.bin_rms);
    }
    rows.push_back({std::to_string(f.joint), Format("%.4g", f.rms), Format("%.4g", f.nmse),
                    Format("%.4g", f.noise_std_estimate), where});
  }
  os << Table(rows);
  if (d.suggestions.empty()) {
    os << Format(
        "no missing effect found: no candidate gains %.0f nats of evidence and cuts "
        "the held-out RMS by %.0f%% on any joint\n",
        options.min_log_evidence_gain, 100.0 * options.min_relative_rms_gain);
    return os.str();
  }
  const std::string existing = ToString(spec.effects);
  // Effect parameters are separated by ';', which a shell would take as the end of a command.
  auto shell_word = [](const std::string& text) {
    return text.find_first_of("; ") == std::string::npos ? text : "'" + text + "'";
  };
  for (const Suggestion& s : d.suggestions) {
    os << Format(
        "joint %d: missing %s (evidence %+.0f nats): residual RMS %.3g -> %.3g, held-out "
        "RMS (%d contiguous blocks) %.3g -> %.3g; add with --effects %s\n",
        s.joint, DescribeEffect(s).c_str(), s.score, s.residual_rms_before, s.residual_rms_after,
        options.folds, s.rms_before, s.rms_after,
        shell_word((existing.empty() ? "" : existing + ",") + s.spec).c_str());
  }
  return os.str();
}

}  // namespace structgp
