#ifndef STRUCTGP_DIAGNOSE_DIAGNOSIS_LOOP_H_
#define STRUCTGP_DIAGNOSE_DIAGNOSIS_LOOP_H_

/// @file
/// The diagnosis loop as a user runs it, in one call: diagnose a fitted model on a log (with
/// its training data), add every effect it suggests, refit on the training data, and diagnose
/// the refitted model again, until a round suggests nothing or max_rounds diagnoses have run.
/// DiagnosisLoopOptions -> RunDiagnosisLoop -> DiagnosisLoopSummary.
///
///     structgp::DiagnosisLoopOptions options;               // 3 rounds, the defaults
///     std::optional<structgp::RobotModel> improved;
///     const structgp::DiagnosisLoopSummary s = structgp::RunDiagnosisLoop(
///         options, model, train_states, train_torques, train_t, log_states, log_torques,
///         log_t, &improved);
///     std::cout << s.BriefReport();                         // the rounds and what each added
///
/// Why more than one round: the diagnosis scores each candidate against the model's prior at
/// its fitted hyper-parameters. A model fitted without several effects has hyper-parameters
/// that absorb part of them (a more flexible prior, a larger noise level), so the first round
/// finds the largest effects and the others only show once those are in the model and its
/// hyper-parameters are fitted again (docs/diagnosis.md: lagk on the PUMA 560 with Coulomb,
/// viscous and Stribeck friction on every joint names 6, then 5, then 2 of the 18).

#include <optional>
#include <string>
#include <vector>

#include "structgp/core/types.h"
#include "structgp/diagnose/diagnosis.h"
#include "structgp/fit/chain_identification.h"
#include "structgp/fit/fit_model.h"
#include "structgp/model/model_spec.h"
#include "structgp/model/robot_model.h"

namespace structgp {

struct DiagnosisLoopOptions {
  /// At most this many diagnoses (>= 1; 1: one diagnosis and one refit with its suggestions).
  int max_rounds = 3;
  /// Each round's diagnosis; its training_inputs, training_targets and training_times are
  /// set by the loop from the training data.
  DiagnosisOptions diagnosis;
  /// The refits; FitOptions::model is replaced by the diagnosed model's own options (its
  /// friction width, inducing states, threads), and FitOptions::per_joint by whether the
  /// diagnosed model has per-joint hyper-parameters.
  FitOptions fit;
  /// lagk: each refit searches the evidence from the current model's hyper-parameters, at its
  /// sigma (FitOptions::euler_lagrange.start), so that adding an effect to one joint leaves
  /// the rest of the model where it was unless the evidence moves it; false: from the
  /// data-derived starts of the whole sigma grid, as a first fit. (lagk is one GP of every
  /// joint: a refit from scratch may take another sigma and change every joint.) Other models
  /// refit from their data-derived starts either way.
  bool refit_from_model = true;
  /// Models on a chain that IdentifyChain found (`structgp identify`'s URDF as written, read
  /// whole: ChainKinematicsOf; rbd, and rbd+pol, rbd+rbf with it as their mean): before each
  /// refit the chain is identified again from the training data with the friction and every
  /// effect the refitted model will have in its least squares, from where it was
  /// (ChainIdentificationOptions::initial_kinematics) and from `chain`'s random starts. A
  /// torque the first identification did not know (a cogging ripple, a friction) bends the
  /// kinematics towards explaining it; refitting only the inertial parameters on that chain
  /// keeps the bend (docs/diagnosis.md, "Without a URDF"). false: refit on the chain as it is.
  /// Models on any other URDF are refitted on their own chain either way.
  bool reidentify_chain = true;
  /// The identification's options; its friction, effects, friction_width, initial_kinematics
  /// and robot_name are set by the loop from the model (the training data's t is passed as X's
  /// last column when given, for effects that read it).
  ChainIdentificationOptions chain;
  /// True when usable; otherwise false with the reason in *error (may be null).
  bool IsValid(std::string* error) const;
};

/// Why the loop stopped.
enum class DiagnosisLoopTermination {
  kNothingNew,       ///< the last diagnosis suggested nothing the model does not have
  kMaxRounds,        ///< max_rounds diagnoses ran, the last one's suggestions refitted
  kDiagnosisFailed,  ///< a diagnosis returned a numerical failure (message says which)
  kRefitFailed,      ///< a refit with the suggestions was not usable (message says why)
};
const char* ToString(DiagnosisLoopTermination termination);

struct DiagnosisRound {
  std::string model;                // the diagnosed model's label (ModelLabel)
  Diagnosis diagnosis;
  std::vector<EffectSpec> added;    // the suggestions as effects (ParseEffectList of each spec)
  std::optional<FitSummary> refit;  // the refit with them on the training data, when any
  /// The chain identified again before the refit (DiagnosisLoopOptions::reidentify_chain), and
  /// the seconds it took; the refit is on identification->urdf.
  std::optional<ChainIdentificationSummary> identification;
  double identification_seconds = 0.0;
};

struct DiagnosisLoopSummary {
  DiagnosisLoopTermination termination = DiagnosisLoopTermination::kNothingNew;
  std::string message;  // why, for the failures
  std::vector<DiagnosisRound> rounds;
  /// The last usable model's spec: the diagnosed model's with every added effect.
  ModelSpec spec;
  double seconds = 0.0;

  /// Every effect added over the rounds, in order.
  std::vector<EffectSpec> Added() const;
  /// One line per round: the model, its suggestions and the refit; then why it stopped.
  std::string BriefReport() const;
};

/// model: fitted on the training data (train_states m x 3N, train_torques m x N, train_t m
/// times or empty). The log (log_states, log_torques, log_t, in time order) is diagnosed in
/// every round with the training data (DiagnosisOptions::training_*); t must be given for both
/// or neither. *improved (may be null) receives the last usable refit, and stays empty when
/// the first diagnosis suggests nothing. Throws std::invalid_argument on invalid options, bad
/// sizes or an unfitted model (as Diagnose and FitModel do); numerical trouble is the summary's
/// termination (an identification again that refuses its options or the data, or finds no
/// usable chain: kRefitFailed, *improved the last usable refit).
/// The loop as JSON: {"termination", "message", "seconds", "model" (the last usable model's
/// label), "rounds": [{"model", "added" (effect list text, "" when none), "identification":
/// {"seconds", "cost" (the final one), then the keys of ToJson(ChainIdentificationSummary)
/// other than the options' echo: "rounds", "kinematics", "kept_starts", "start_costs",
/// "best_start", "starts_at_best", "moved_cost", "moves_kept", "refined_cost",
/// "undetermined", "cost_change", "faster_change", "joints" (each "joint", "torque_rms",
/// "residual_rms", "noise")} or null, "refit": {"usable", "message", "seconds"} or null,
/// "findings": the round's diagnosis as ToJson writes it}]}.
std::string ToJson(const DiagnosisLoopSummary& summary);

DiagnosisLoopSummary RunDiagnosisLoop(const DiagnosisLoopOptions& options, const RobotModel& model,
                                      const ConstMatrixRef& train_states,
                                      const ConstMatrixRef& train_torques,
                                      const Vector& train_t, const ConstMatrixRef& log_states,
                                      const ConstMatrixRef& log_torques, const Vector& log_t,
                                      std::optional<RobotModel>* improved);

}  // namespace structgp

#endif  // STRUCTGP_DIAGNOSE_DIAGNOSIS_LOOP_H_
