#ifndef STRUCTGP_DIAGNOSE_DIAGNOSIS_H_
#define STRUCTGP_DIAGNOSE_DIAGNOSIS_H_

/// @file
/// Where a model fails on measured data, and which physical effect it is missing.
///
/// Per joint: the residual RMS and nMSE of the model on the data, a model-free estimate of
/// the measurement noise, and the variables (q, qd, qdd of each joint, t) along which the
/// residual concentrates.
///
/// Which effect is missing: every candidate effect (effects.h) on every joint is added to the
/// model's own features with a broad prior, and scored by the gain in log marginal likelihood
/// of that joint's torque on the data (exact, by a Schur complement on the model's factor:
/// O(D^2 k) per candidate) and by blocked cross-validation on contiguous folds (the RMS it
/// would leave). A candidate is suggested only when both say so: the evidence gain exceeds
/// DiagnosisOptions::min_log_evidence_gain and the held-out RMS falls by at least
/// min_relative_rms_gain. Suggestions are chosen greedily (after the best is added, the others
/// are scored again), so two names for one effect are not both suggested. Effects that the
/// model already spans (a sinusoidal spring or a payload under pol) gain nothing and are not
/// suggested. Each effect proposes its own parameters from the residual of a refit
/// (Effect::ProposeParameters: cogging period, Stribeck velocity, drift time origin and span),
/// so a user's registered effect gets parameter estimation too; effects the model contains
/// (same name on the joint, or a block of Effect::spanned_by) are not tried.

#include <map>
#include <string>
#include <vector>

#include "structgp/core/types.h"
#include "structgp/feature/effect_parameter.h"
#include "structgp/model/robot_model.h"

namespace structgp {

struct DiagnosisOptions {
  /// Candidate effect names; empty (the default): every registered effect, in EffectNames()
  /// order (the built-in ones, then those added with RegisterEffect).
  std::vector<std::string> candidates;
  /// Contiguous folds of the blocked cross-validation.
  int folds = 5;
  /// Minimum gain in log evidence of the joint's torque, nats (about e^10 : 1 odds).
  double min_log_evidence_gain = 10.0;
  /// Minimum relative fall of the held-out RMS of the joint.
  double min_relative_rms_gain = 0.02;
  /// At most this many suggestions.
  int max_suggestions = 6;
  /// Quantile bins for "where the error concentrates".
  int bins = 10;
  /// Where ProposeParameters searches a parameter, by "effect.parameter", overriding the
  /// parameter's own search range (EffectParameter::search; cogging's period: [0.02, 3] rad),
  /// e.g. {{"cogging.period", {0.05, 1.0}}}. Read by effects that search a range (among the
  /// built-in ones, cogging's period; Stribeck and drift derive theirs from the data).
  std::map<std::string, ParameterRange> search_ranges;
  /// Models in function space (rbf, rbfs, pol beyond its explicit map): the candidates are
  /// scored against this many Nystrom features of the model's kernel (at most half the rows),
  /// inducing states chosen among the rows by greedy residual variance.
  int nystrom_features = 512;

  /// True when the options are usable; otherwise false with the reason in *error (may be
  /// null).
  bool IsValid(std::string* error) const;
};

/// A variable along which a joint's residual concentrates.
struct Concentration {
  std::string variable;  ///< "q2", "qd1", "qdd3", "t"
  double explained = 0;  ///< fraction of the residual variance explained by the bin means
  double bin_low = 0, bin_high = 0;  ///< the bin with the largest residual RMS
  double bin_rms = 0;
};

struct JointFinding {
  int joint = 0;                    ///< 1-based
  double rms = 0;                   ///< residual RMS of the model on the data
  double nmse = 0;                  ///< residual MSE / variance of the torque
  double noise_std_estimate = 0;    ///< from successive differences of the residual
  std::vector<Concentration> concentrations;  ///< strongest first (at most 3)
};

struct Suggestion {
  std::string effect;   ///< a registered effect name ("coulomb")
  int joint = 0;        ///< 1-based
  double score = 0;     ///< gain in log evidence of this joint's torque, nats
  double rms_before = 0;  ///< held-out RMS of the joint without the effect (blocked CV)
  double rms_after = 0;   ///< ... and with it
  /// Residual RMS of the joint on all the data, the model refitted without the effect and
  /// with it: what the effect would leave on this log. Compare it with the joint's
  /// noise_std_estimate. (The held-out RMS above can be much larger on a log whose
  /// contiguous blocks visit different states, since each block is then an extrapolation.)
  double residual_rms_before = 0;
  double residual_rms_after = 0;
  std::map<std::string, double> params;  ///< every parameter of the effect (as estimated)
  /// The text to add to --effects, e.g. "cogging@3:period=0.3": ParseEffectList(spec) gives
  /// back this effect on this joint, with these params.
  std::string spec;
};

/// How a diagnosis ended.
enum class DiagnosisStatus {
  kOk,
  /// The model could not be refitted or factorised on these data (not positive definite):
  /// no suggestion is made; what was found before the failure is kept. Diagnosis::message
  /// says which step failed.
  kNumericalFailure,
};

/// "ok", "numerical_failure".
const char* ToString(DiagnosisStatus status);

struct Diagnosis {
  DiagnosisStatus status = DiagnosisStatus::kOk;
  /// Empty when status is kOk, else what failed.
  std::string message;
  std::vector<JointFinding> joints;
  std::vector<Suggestion> suggestions;  ///< highest score first
  int num_samples = 0;
  std::string model;  ///< model spec and effects in use
  /// What the candidates were scored against: the model's feature map, or Nystrom features
  /// of its kernel.
  std::string features;
  /// Relative noise level sigma_n found by evidence on these data (noise of joint j is
  /// noise_std times the joint's output scale).
  double noise_std = 0;
};

/// Diagnoses a fitted model on data X (m x model.input_dim()),
/// Y (m x N) and times t (size m, or empty when the data have none: drift is then not tried).
/// Rows must be in time order (the folds are contiguous). Throws std::invalid_argument on
/// invalid options (an unknown candidate name, a search range naming no parameter of a
/// registered effect, ...), bad sizes, NaN/Inf, too few rows for the folds, or a model that is
/// not fitted; numerical trouble is Diagnosis::status.
Diagnosis Diagnose(const RobotModel& model, const ConstMatrixRef& X, const ConstMatrixRef& Y,
                   const Vector& t, const DiagnosisOptions& options = {});

/// FINDINGS.json text: {"joints": [...], "suggestions": [...], ...}.
std::string ToJson(const Diagnosis& diagnosis);

}  // namespace structgp

#endif  // STRUCTGP_DIAGNOSE_DIAGNOSIS_H_
