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

// The closest candidates that were not suggested, and the bar each one failed.
std::string Refusals(const Diagnosis& d) {
  if (d.refused.empty()) return "";
  std::string text = "not suggested (the closest candidates, and the bar that refused each):\n";
  for (const Refusal& r : d.refused) {
    const Suggestion& c = r.candidate;
    text += Format("  joint %d: %s%s (%s): %s", c.joint, DescribeEffect(c).c_str(),
                   c.scope == "log" ? ", in this log only" : "", c.spec.c_str(), r.reason.c_str());
    if (r.bar != "evidence") {
      text += Format("; evidence %+.0f nats as white noise", c.score_uncorrected);
    }
    if (r.bar != "held_out") text += Format("; held-out mean fold ratio %.2f", c.fold_rms_ratio);
    text += Format("; residual RMS %.3g -> %.3g\n", c.residual_rms_before, c.residual_rms_after);
  }
  return text;
}

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
  const bool distances = !d.joints.empty() && d.joints.front().max_distance >= 0;
  std::vector<std::string> header = {"joint", "RMS", "nMSE", "noise est.", "refit RMS"};
  if (distances) header.push_back("outside training");
  header.push_back("error concentrates along");
  std::vector<std::vector<std::string>> rows = {header};
  for (const JointFinding& f : d.joints) {
    std::string where = "-";
    if (!f.concentrations.empty() && f.concentrations.front().explained >= kMinExplained) {
      const Concentration& c = f.concentrations.front();
      where =
          Format("%s (explains %.0f%%; worst bin %s in [%.3g, %.3g], RMS %.3g)", c.variable.c_str(),
                 100.0 * c.explained, c.variable.c_str(), c.bin_low, c.bin_high, c.bin_rms);
    }
    std::vector<std::string> row = {std::to_string(f.joint), Format("%.4g", f.rms),
                                    Format("%.4g", f.nmse), Format("%.4g", f.noise_std_estimate),
                                    Format("%.4g", f.refit_rms)};
    if (distances) {
      row.push_back(Format("%.0f%% (up to %.2g sd)", 100.0 * f.outside_fraction, f.max_distance));
    }
    row.push_back(where);
    rows.push_back(row);
  }
  os << Table(rows);
  if (d.chain) os << "chain: " << d.chain->message << "\n";
  os << "verdict: " << ToString(d.coverage.verdict) << ": " << d.coverage.message << "\n";
  if (!d.holding.message.empty()) os << "at rest: " << d.holding.message << "\n";
  if (d.suggestions.empty()) {
    os << Format(
        "no missing effect found: no candidate gains %.0f nats of evidence after the "
        "autocorrelation correction, passes the %s test at %.2g, lowers the joint's residual by "
        "%.0f%% with a change of %.2g times the noise, and cuts the held-out RMS by %.0f%%\n",
        options.min_log_evidence_gain,
        options.multiplicity == DiagnosisOptions::Multiplicity::kHolm ? "Holm"
        : options.multiplicity == DiagnosisOptions::Multiplicity::kBenjaminiHochberg
            ? "Benjamini-Hochberg"
            : "uncorrected",
        options.significance, 100.0 * options.min_residual_fall, options.min_effect_to_noise,
        100.0 * options.min_relative_rms_gain);
    os << Refusals(d);
    return os.str();
  }
  const std::string existing = ToString(spec.effects);
  // Effect parameters are separated by ';', which a shell would take as the end of a command.
  auto shell_word = [](const std::string& text) {
    return text.find_first_of("; ") == std::string::npos ? text : "'" + text + "'";
  };
  for (const Suggestion& s : d.suggestions) {
    // An effect of this log alone is confirmed on the log's own trajectories or blocks.
    const char* where = s.scope == "log" ? " of this log" : "";
    const std::string unseen =
        s.confirmation == "trajectories"
            ? Format("leave one trajectory%s out, %d folds", where, s.confirmation_folds)
            : Format("%d contiguous blocks%s, gap %d rows", s.confirmation_folds, where,
                     s.confirmation_gap);
    os << Format(
        "joint %d: missing %s%s (evidence %+.0f nats, %.0f without the autocorrelation "
        "correction; adjusted p %s; %.1f times the noise%s): residual RMS %.3g -> %.3g, "
        "held-out RMS (%s; better in %d, mean fold ratio %.2f) %.3g -> %.3g; add with --effects %s\n",
        s.joint, DescribeEffect(s).c_str(),
        s.scope == "log" ? ", in this log only (not in the training data: retrain with this log)" : "", s.score, s.score_uncorrected,
        (s.adjusted_p_value > 0 ? Format("%.2g", s.adjusted_p_value) : std::string("< 1e-300")).c_str(),
        s.effect_to_noise,
        (std::string(s.selection == "joint" ? "; chosen with the joint's other friction" : "") +
         (s.passed_by == "held_out" ? "; passed on its held-out fall, not on the evidence" : ""))
            .c_str(),
        s.residual_rms_before, s.residual_rms_after, unseen.c_str(), s.folds_improved,
        s.fold_rms_ratio, s.rms_before, s.rms_after,
        shell_word((existing.empty() ? "" : existing + ",") + s.spec).c_str());
    if (!s.alternatives.empty()) {
      std::string names;
      for (const AlternativeEffect& a : s.alternatives) {
        names += Format("%s%s%s (evidence %+.0f nats)", names.empty() ? "" : ", ", a.spec.c_str(),
                        a.scope == "log" ? ", in this log only" : "", a.score);
      }
      os << Format("  also passed every bar, and adding it explains them: %s\n", names.c_str());
    }
  }
  os << Refusals(d);
  return os.str();
}

}  // namespace structgp
