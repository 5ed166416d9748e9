#include "structgp/diagnose/diagnosis_loop.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>

#include <nlohmann/json.hpp>

#include "structgp/internal/text.h"
#include "structgp/rigid_body/rigid_body_chain.h"

namespace structgp {
namespace {

double Seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

}  // namespace

bool DiagnosisLoopOptions::IsValid(std::string* error) const {
  std::string why;
  if (max_rounds < 1) {
    why = "DiagnosisLoopOptions.max_rounds must be >= 1, got " + std::to_string(max_rounds);
  } else if (!diagnosis.IsValid(&why)) {
    why = "DiagnosisLoopOptions.diagnosis: " + why;
  } else if (!fit.IsValid(&why)) {
    why = "DiagnosisLoopOptions.fit: " + why;
  }
  if (error != nullptr) *error = why;
  return why.empty();
}

const char* ToString(DiagnosisLoopTermination termination) {
  switch (termination) {
    case DiagnosisLoopTermination::kNothingNew: return "nothing_new";
    case DiagnosisLoopTermination::kMaxRounds: return "max_rounds";
    case DiagnosisLoopTermination::kDiagnosisFailed: return "diagnosis_failed";
    case DiagnosisLoopTermination::kRefitFailed: return "refit_failed";
  }
  return "unknown";
}

std::vector<EffectSpec> DiagnosisLoopSummary::Added() const {
  std::vector<EffectSpec> all;
  for (const DiagnosisRound& r : rounds) all.insert(all.end(), r.added.begin(), r.added.end());
  return all;
}

std::string DiagnosisLoopSummary::BriefReport() const {
  std::string text;
  for (size_t k = 0; k < rounds.size(); ++k) {
    const DiagnosisRound& r = rounds[k];
    text += internal::Format("round %d: %s: ", static_cast<int>(k + 1), r.model.c_str());
    if (r.diagnosis.status != DiagnosisStatus::kOk) {
      text += std::string(ToString(r.diagnosis.status)) + ": " + r.diagnosis.message + "\n";
      continue;
    }
    if (r.added.empty()) {
      text += "nothing to add\n";
      continue;
    }
    text += "add " + ToString(r.added);
    if (r.identification) {
      const ChainIdentificationSummary& id = *r.identification;
      text += internal::Format(
          "; chain identified again with them in %.1f s (cost %.4g, %d of %d kept starts at it)",
          r.identification_seconds, ChainIdentificationCost(id), id.starts_at_best,
          static_cast<int>(id.starts.size()));
    }
    if (r.refit) {
      text += internal::Format("; refitted in %.1f s", r.refit->total_seconds);
      if (!r.refit->IsUsable()) text += " (not usable: " + r.refit->message + ")";
    }
    text += "\n";
  }
  text += std::string("stopped: ") + ToString(termination);
  if (!message.empty()) text += ": " + message;
  text += internal::Format(" (%.1f s)\n", seconds);
  return text;
}

std::string ToJson(const DiagnosisLoopSummary& summary) {
  using Json = nlohmann::ordered_json;
  Json j;
  j["termination"] = ToString(summary.termination);
  j["message"] = summary.message;
  j["seconds"] = summary.seconds;
  j["model"] = ModelLabel(summary.spec);
  j["rounds"] = Json::array();
  for (const DiagnosisRound& r : summary.rounds) {
    Json round;
    round["model"] = r.model;
    round["added"] = r.added.empty() ? std::string() : ToString(r.added);
    if (r.identification) {
      Json id = {{"seconds", r.identification_seconds},
                 {"cost", ChainIdentificationCost(*r.identification)}};
      // The identification's own JSON (ChainIdentificationSummary), less the options' echo.
      ChainIdentificationOptions echo;
      Json full = Json::parse(ToJson(*r.identification, echo));
      for (const char* key : {"friction", "effects", "starts"}) full.erase(key);
      id.update(full);
      round["identification"] = std::move(id);
    } else {
      round["identification"] = nullptr;
    }
    if (r.refit) {
      round["refit"] = {{"usable", r.refit->IsUsable()},
                        {"message", r.refit->message},
                        {"seconds", r.refit->total_seconds}};
    } else {
      round["refit"] = nullptr;
    }
    round["findings"] = Json::parse(ToJson(r.diagnosis));
    j["rounds"].push_back(std::move(round));
  }
  return j.dump(2) + "\n";
}

DiagnosisLoopSummary RunDiagnosisLoop(const DiagnosisLoopOptions& options, const RobotModel& model,
                                      const ConstMatrixRef& train_states,
                                      const ConstMatrixRef& train_torques,
                                      const Vector& train_t, const ConstMatrixRef& log_states,
                                      const ConstMatrixRef& log_torques, const Vector& log_t,
                                      std::optional<RobotModel>* improved) {
  const auto start = std::chrono::steady_clock::now();
  std::string error;
  if (!options.IsValid(&error)) throw std::invalid_argument("RunDiagnosisLoop: " + error);
  if (!model.fitted()) throw std::invalid_argument("RunDiagnosisLoop: the model is not fitted");
  if ((train_t.size() == 0) != (log_t.size() == 0)) {
    throw std::invalid_argument(
        "RunDiagnosisLoop: times for both the training data and the log, or for neither");
  }
  if (improved != nullptr) improved->reset();
  DiagnosisLoopSummary summary;
  summary.spec = model.spec();
  FitOptions fit_options = options.fit;
  fit_options.model = model.options();
  fit_options.per_joint = model.per_joint();
  // The model of the current round: the one given, then each refit.
  std::optional<RobotModel> refitted;
  auto finish = [&](DiagnosisLoopTermination termination, std::string message) {
    summary.termination = termination;
    summary.message = std::move(message);
    summary.seconds = Seconds(start);
    if (improved != nullptr && refitted) *improved = std::move(*refitted);
    return summary;
  };
  for (int round = 1;; ++round) {
    const RobotModel& current = refitted ? *refitted : model;
    DiagnosisRound r;
    r.model = ModelLabel(current.spec());
    DiagnosisOptions diagnosis_options = options.diagnosis;
    diagnosis_options.training_inputs = ModelInputs(current, train_states, train_t);
    diagnosis_options.training_targets = train_torques;
    diagnosis_options.training_times = train_t;
    r.diagnosis = Diagnose(current, ModelInputs(current, log_states, log_t), log_torques, log_t,
                           diagnosis_options);
    if (r.diagnosis.status != DiagnosisStatus::kOk) {
      const std::string why = internal::Format("round %d: %s", round, r.diagnosis.message.c_str());
      summary.rounds.push_back(std::move(r));
      return finish(DiagnosisLoopTermination::kDiagnosisFailed, why);
    }
    for (const Suggestion& s : r.diagnosis.suggestions) {
      for (EffectSpec& e : ParseEffectList(s.spec)) r.added.push_back(std::move(e));
    }
    if (r.added.empty()) {
      summary.rounds.push_back(std::move(r));
      return finish(DiagnosisLoopTermination::kNothingNew, "");
    }
    ModelSpec spec = summary.spec;
    spec.effects.insert(spec.effects.end(), r.added.begin(), r.added.end());
    FitOptions round_fit = fit_options;
    round_fit.model.rigid_body = current.options().rigid_body;
    if (options.refit_from_model) StartFromModel(current, &round_fit);
    // A chain IdentifyChain found is found again with the effects beside it.
    const std::shared_ptr<const RigidBodyChain>& chain = current.options().rigid_body;
    const std::optional<ChainIdentificationOptions> again =
        options.reidentify_chain && chain
            ? SearchAgainOptions(*chain, spec, current.options().friction_width, options.chain)
            : std::nullopt;
    if (again) {
      const ChainIdentificationOptions& o = *again;
      const auto identify_start = std::chrono::steady_clock::now();
      try {  // options it refuses, too few rows for the effects' bases, no usable chain
        r.identification = IdentifyChain(train_states, train_t, train_torques, o);
      } catch (const std::exception& e) {
        summary.rounds.push_back(std::move(r));
        return finish(DiagnosisLoopTermination::kRefitFailed,
                      internal::Format("round %d: identifying the chain again with %s: %s", round,
                                       ToString(spec.effects).c_str(), e.what()));
      }
      r.identification_seconds = Seconds(identify_start);
      round_fit.model.rigid_body = std::make_shared<const RigidBodyChain>(
          RigidBodyChain::FromUrdfString(r.identification->urdf, {}, chain->source()));
    }
    FittedModel fit = FitModel(spec, train_states, train_torques, train_t, round_fit);
    r.refit = fit.summary;
    summary.rounds.push_back(std::move(r));
    if (!fit.summary.IsUsable()) {
      return finish(DiagnosisLoopTermination::kRefitFailed,
                    internal::Format("round %d: the refit of %s: %s", round,
                                     ModelLabel(spec).c_str(), fit.summary.message.c_str()));
    }
    summary.spec = spec;
    refitted.emplace(std::move(fit.model));
    if (round >= options.max_rounds) return finish(DiagnosisLoopTermination::kMaxRounds, "");
  }
}

}  // namespace structgp
