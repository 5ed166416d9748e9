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
/// model's own features with a broad prior and scored on the data (docs/diagnosis.md):
/// - the gain in log marginal likelihood of that joint's torque (exact, by a Schur complement
///   on the model's factor: O(D^2 k) per candidate), with its data term divided by the
///   inflation that autocorrelated residuals cause (Bartlett's formula for the variance of a
///   cross-correlation: 1 + 2 sum_k w_k rho_r(k) rho_e(k), the residual's and the candidate's
///   autocorrelations), so that a 1 kHz log counts as its effective number of samples;
/// - a p-value from that calibrated statistic (chi-square with as many degrees of freedom as
///   the effect has bases), controlled across every candidate on every joint (Holm, or
///   Benjamini-Hochberg);
/// - an effect size: the effect must lower the joint's residual on the log by
///   min_residual_fall and change its fitted torque by min_effect_to_noise times the noise;
/// - confirmation on unseen data: the held-out RMS of the joint by leave-one-trajectory-out
///   when the log has enough trajectories, else by contiguous blocks with a gap on each side
///   (rows too correlated with the block to count as unseen are left out of its fit); an
///   effect tried on the diagnosed log alone (Suggestion::scope "log") on the log's own
///   trajectories or blocks, with the training rows in every fit.
/// A candidate is suggested only when all of them say so. Suggestions are chosen greedily
/// (after the best is added, the others are scored again); a joint's candidates are scored
/// against the model with the suggestions on that joint only (an effect of another joint is
/// not part of this joint's torque), each confirmed with its joint's own gap, so that what
/// is found on one joint does not change what another joint is suggested (the noise level
/// the log is scored at is still one for all joints). Then, per joint, the friction-like
/// effects that passed (viscous, Coulomb, Stribeck, drift, offset) are also chosen jointly,
/// and the joint set replaces the greedy one when it is better on unseen data.
///
/// Before any effect: the model's error on the log is compared with the error of the model
/// refitted on the log (CoverageFinding). When the refit reaches the noise, the model class
/// explains the log and what is wrong is the training data's coverage of these motions, not a
/// missing effect; with the training inputs (DiagnosisOptions::training_inputs) the finding
/// also says where the log leaves the training states.
///
/// A model on a chain that IdentifyChain found, diagnosed with its training data: the chain's
/// kinematics are fitted parameters as its inertial ones are, so the chain is identified again
/// on the training data and the log together before any effect is tried (ChainFinding). When
/// that chain explains the log better, the findings are against the model on it: a chain
/// found from slow motion can be wrong in a wrist the slow torques hardly show, and the error
/// a faster log then shows is the chain's, not a missing effect's.
///
/// Each effect proposes its own parameters from the residual of a refit
/// (Effect::ProposeParameters: cogging period, Stribeck velocity, drift time origin and span),
/// so a user's registered effect gets parameter estimation too; effects the model contains
/// (same name on the joint, or a block of Effect::spanned_by) are not tried.

#include <map>
#include <optional>
#include <string>
#include <vector>

#include "structgp/core/types.h"
#include "structgp/diagnose/holding_torque.h"
#include "structgp/feature/effect_parameter.h"
#include "structgp/fit/chain_identification.h"
#include "structgp/model/robot_model.h"

namespace structgp {

struct DiagnosisOptions {
  /// Candidate effect names; empty (the default): every registered effect, in EffectNames()
  /// order (the built-in ones, then those added with RegisterEffect).
  std::vector<std::string> candidates;
  /// Contiguous folds of the blocked cross-validation.
  int folds = 5;
  /// Minimum gain in log evidence of the joint's torque, nats (about e^10 : 1 odds), after
  /// the autocorrelation correction.
  double min_log_evidence_gain = 10.0;
  /// Minimum relative fall of the held-out RMS of the joint (the confirmation on unseen data),
  /// as the mean over the folds of each fold's RMS ratio (Suggestion::fold_rms_ratio); the RMS
  /// over all held-out rows together (Suggestion::rms_before -> rms_after) must fall too.
  double min_relative_rms_gain = 0.02;
  /// Family-wise error rate (Holm) or false discovery rate (Benjamini-Hochberg) over every
  /// candidate on every joint.
  double significance = 0.01;
  enum class Multiplicity { kHolm, kBenjaminiHochberg, kNone };
  Multiplicity multiplicity = Multiplicity::kHolm;
  /// How the evidence is corrected for autocorrelated residuals. kBartlett: the statistic is
  /// divided by Bartlett's factor (diagnose/autocorrelation.h, BartlettInflation), which sees
  /// only the two autocorrelations. kPrewhitening: by the factor that an AR model of the
  /// residual gives (PrewhiteningInflation): residual and candidate filtered by it, which keeps
  /// the power of a candidate whose shape the noise does not share (a Coulomb step against a
  /// slow wander); never above the white-noise statistic. kNone: every row counts as an
  /// independent sample, which is overconfident on logs sampled faster than their residual
  /// decorrelates.
  enum class Autocorrelation { kNone, kBartlett, kPrewhitening };
  Autocorrelation autocorrelation = Autocorrelation::kBartlett;
  /// Minimum relative fall of the joint's residual RMS on the log (model refitted there without
  /// and with the effect).
  double min_residual_fall = 0.03;
  /// Minimum RMS of the change the effect makes to the joint's fitted torque, in units of the
  /// joint's noise level (noise_std_estimate).
  double min_effect_to_noise = 0.3;
  /// An effect that lowers the held-out RMS by this fraction passes the two bars above
  /// without them: a model refitted on the log (pol on its own training log) can absorb an
  /// effect in sample that it cannot predict out of sample.
  double held_out_fall_alone = 0.25;
  /// An effect that lowers the held-out RMS by held_out_fall_alone, in every fold but at most
  /// one, and does not lower the evidence on the log (gain >= 0) passes the evidence bars too
  /// (evidence, calibrated evidence, z, significance; Suggestion::passed_by "held_out"): a
  /// model as flexible as lagk, refitted on the training rows and the log, absorbs a viscous
  /// friction in sample (+0.7 nats on the Panda) that lowers its held-out error by 28%. Not
  /// for an effect of the log alone (Suggestion::scope "log"), confirmed on the log's blocks,
  /// which any column of the log alone can predict for how the whole log differs from the
  /// training data.
  bool held_out_may_replace_evidence = true;
  /// Minimum size of the effect against its posterior standard deviation (the square root of
  /// the calibrated chi-square statistic).
  double min_effect_z = 4.0;
  /// Rows left out on each side of a held-out block (same trajectory only); -1: the tested
  /// joint's residual's correlation length (first lag where its autocorrelation falls below
  /// 0.1; each joint its own, so that another joint's residual does not move its blocks), at
  /// most half a block.
  int confirmation_gap = -1;
  /// The coverage finding: a joint's error is "coverage" when the model's RMS on the log
  /// exceeds coverage_ratio times the RMS of the model refitted on the log, and that refit
  /// reaches noise_tolerance times the noise.
  double coverage_ratio = 2.0;
  double noise_tolerance = 1.3;
  /// The data the model was trained on, optional (in time order, as the log).
  /// training_inputs alone (rows x at least 3 N columns: q, qd, qdd): the coverage finding
  /// measures how far each row of the log is from the training states (at most 2,000 of them,
  /// evenly spaced, are used).
  /// With training_targets too (training_inputs then with the model's input columns, and
  /// training_times when the log has times): the candidates are scored, and the model refitted
  /// for refit_rms and the verdict, on the training rows and the log together, as separate
  /// trajectories. A model as rich as pol refitted on one log alone can bend along that one
  /// path to absorb an effect (viscous friction on a single trajectory is some function of the
  /// state along it); it cannot across slow and fast motion, so this is the sharper test.
  Matrix training_inputs;
  Matrix training_targets;
  Vector training_times;
  /// At most this many suggestions (a 7-joint arm with three friction terms on every joint
  /// has 21 missing effects).
  int max_suggestions = 32;
  /// At most this many refused candidates in Diagnosis::refused (0: none).
  int max_refused = 8;
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
  /// Torques at rest that the state does not determine (Diagnosis::holding): the still
  /// stretches of the log and of the training rows, when given, each a trajectory of its own.
  HoldingTorqueOptions holding;
  /// A model on a chain IdentifyChain found (its URDF as identify wrote it: ChainKinematicsOf),
  /// diagnosed with training_targets: the chain is identified again on the training rows and
  /// the log together (IdentifyChain with `chain`, from the model's own kinematics, with the
  /// model's friction and effects beside it, and the effects the diagnosis on the model's own
  /// chain suggests for every row) and the model fitted again on it (FitModel from
  /// the model's hyper-parameters). When the log's error of that model, refitted on the
  /// training rows and the log, is lower by min_residual_fall on some joint than the model's
  /// own chain gives (and higher by as much on none), the findings are against it
  /// (Diagnosis::chain).
  bool reidentify_chain = true;
  /// That identification's search; by default a local one from the model's kinematics (no
  /// random starts, no length moves). friction, friction_width, effects, initial_kinematics
  /// and robot_name are the model's.
  ChainIdentificationOptions chain = [] {
    ChainIdentificationOptions o;
    o.starts = 0;
    o.length_moves = false;
    return o;
  }();

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
  /// Residual RMS of the model refitted on these data (its features and prior, no effect):
  /// near noise_std_estimate when the model class explains the log.
  double refit_rms = 0;
  /// Residual RMS on the log of the diagnosis's own refit (the fit its candidates are scored
  /// against: the noise level and output scales re-estimated on these data) with exactly this
  /// joint's suggestions, or with none when it has none: what the suggestions leave of the
  /// joint's error. -1 when the search did not run.
  double residual_rms_with_suggestions = -1;
  /// With DiagnosisOptions::training_inputs: the fraction of the log's rows whose distance
  /// to the training states (below) exceeds 1, and the largest distance; -1 without.
  double outside_fraction = -1;
  double max_distance = -1;
  std::vector<Concentration> concentrations;  ///< strongest first (at most 3)
};

/// An effect that explains what a suggestion explains (Suggestion::alternatives).
struct AlternativeEffect {
  std::string spec;   ///< as Suggestion::spec, e.g. "offset@2"
  std::string scope;  ///< as Suggestion::scope
  double score = 0;   ///< its calibrated score, nats, in the round the suggestion was chosen in
};

struct Suggestion {
  std::string effect;   ///< a registered effect name ("coulomb")
  int joint = 0;        ///< 1-based
  double score = 0;     ///< gain in log evidence of this joint's torque, nats
  /// Held-out RMS of the joint without the effect and with it, pooled over the held-out rows
  /// (blocked CV): every row's blocks, or for scope "log" the diagnosed log's.
  double rms_before = 0;
  double rms_after = 0;
  /// Residual RMS of the joint on the diagnosed log (every row of it), the model refitted
  /// without the effect and with it: what the effect would leave on this log. Compare it with the joint's
  /// noise_std_estimate. (The held-out RMS above can be much larger on a log whose
  /// contiguous blocks visit different states, since each block is then an extrapolation.)
  double residual_rms_before = 0;
  double residual_rms_after = 0;
  std::map<std::string, double> params;  ///< every parameter of the effect (as estimated)
  /// Calibration (docs/diagnosis.md): score_uncorrected is the gain with every row an
  /// independent sample; inflation = rows / effective_samples (>= 1) the factor by which
  /// autocorrelation overstates it (rows: those scored, the training rows included when
  /// DiagnosisOptions::training_targets are given); p_value from the calibrated chi-square statistic,
  /// adjusted_p_value after the multiplicity correction.
  double score_uncorrected = 0;
  double inflation = 1;
  double effective_samples = 0;
  double p_value = 1;
  double adjusted_p_value = 1;
  /// Effect size: RMS of the change the effect makes to the joint's fitted torque, and that
  /// over the joint's noise level; z: the effect against its posterior std (calibrated).
  double effect_rms = 0;
  double effect_to_noise = 0;
  double z = 0;
  /// How rms_before / rms_after were confirmed on unseen data: "trajectories" (leave one
  /// trajectory out) or "blocks" (contiguous blocks with confirmation_gap rows left out on each
  /// side), of every row or, for scope "log", of the diagnosed log's rows (the training rows
  /// then in every fit); folds, the gap, and in how many folds the effect lowered the held-out
  /// error.
  std::string confirmation;
  int confirmation_folds = 0;
  int confirmation_gap = 0;
  int folds_improved = 0;
  /// Mean over the folds of the held-out RMS with the effect over that without it: the number
  /// the held-out bars (min_relative_rms_gain, held_out_fall_alone) apply to. Each fold weighs
  /// the same, so that a fold the model extrapolates to badly (on a log whose blocks visit
  /// different states) does not drown what the effect does in the others; rms_before and
  /// rms_after pool the folds.
  double fold_rms_ratio = 1;
  /// "greedy" (chosen one at a time) or "joint" (chosen together with the joint's other
  /// friction-like effects, because the set is better on unseen data than the greedy choice).
  std::string selection = "greedy";
  /// "evidence": it passed every bar; "held_out": it failed the in-sample evidence bars and
  /// passed on its held-out fall (DiagnosisOptions::held_out_may_replace_evidence).
  std::string passed_by = "evidence";
  /// "all": the effect is on every row scored (the training data too, when given); "log": on
  /// the diagnosed log alone, with the training data given: the log has it and the training
  /// data do not (the robot changed since, or the training motion did not excite it). Both
  /// are tried when training data are given, each counted as a test.
  std::string scope = "all";
  /// The joint's residual on every row of the log, the model refitted there without and with
  /// the effect (with the suggestions chosen before it on its joint in both): what the report
  /// plots against q and qd. Not written to FINDINGS.json.
  Vector residual_before_rows, residual_after_rows;
  /// The text to add to --effects, e.g. "cogging@3:period=0.3": ParseEffectList(spec) gives
  /// back this effect on this joint, with these params.
  std::string spec;
  /// Other effects of this joint that passed every bar in the round this one was chosen in and
  /// pass no more once it is added: they explain the same part of the log. A score close to
  /// this one's says the log cannot tell them apart (on a joint that hardly moves, a spring's
  /// torque k q is nearly a constant, as an offset is). Best score first; empty for a
  /// suggestion chosen with the joint's other friction-like effects (selection "joint") and
  /// for the last one when max_suggestions stopped the search after it.
  std::vector<AlternativeEffect> alternatives;
};

/// A candidate that was not suggested, and the bar that refused it (Diagnosis::refused): the
/// answer to "why is X not named?". Scored against the model as given (before any
/// suggestion), the best parameter set of its effect, joint and scope; or, when it passed
/// every bar there, scored against the model with the suggestions chosen before it on its
/// joint (`after_suggestions`: they explain it).
struct Refusal {
  /// The candidate's numbers as far as the scoring went: the evidence, held-out and size
  /// numbers always; inflation, effective_samples, score, z and the p-values only when
  /// `calibrated` (the cheap bars come first and the calibration is not computed after one
  /// of them refused); residual rows are not kept.
  Suggestion candidate;
  /// The first bar it failed: "evidence" (min_log_evidence_gain, white-noise gain),
  /// "held_out" (min_relative_rms_gain on fold_rms_ratio), "residual_fall" (min_residual_fall),
  /// "effect_size" (min_effect_to_noise), "calibrated_evidence" (min_log_evidence_gain after
  /// the autocorrelation correction), "z" (min_effect_z), "significance" (the multiplicity-
  /// corrected test at DiagnosisOptions::significance).
  std::string bar;
  /// The bar with the candidate's number and the limit, e.g.
  /// "calibrated evidence -2.3 nats <= 10".
  std::string reason;
  bool calibrated = false;
  bool after_suggestions = false;
};

/// What the model's error on the log is about (Diagnosis::coverage).
enum class Verdict {
  /// The model predicts the log to the noise on every joint: nothing to fix.
  kExplained,
  /// The model class explains the log (refitted on it, it reaches the noise) but the model
  /// does not: the training data did not cover these motions. Retrain with them; no effect is
  /// missing.
  kCoverage,
  /// Effects were suggested.
  kMissingEffect,
  /// The refit does not reach the noise on some joint, and no candidate effect explains it
  /// (CoverageFinding::unexplained_joints).
  kUnexplained,
};

/// "explained", "coverage", "missing_effect", "unexplained".
const char* ToString(Verdict verdict);

/// "none", "bartlett", "prewhitening".
const char* ToString(DiagnosisOptions::Autocorrelation correction);
/// The inverse of ToString; false (nothing written) for any other text.
bool FromString(const std::string& text, DiagnosisOptions::Autocorrelation* correction);

/// Where the log leaves the training data (FINDINGS.json "coverage").
struct CoverageFinding {
  Verdict verdict = Verdict::kExplained;
  std::string message;             ///< one sentence for people
  std::vector<int> coverage_joints;  ///< 1-based joints whose error is coverage, not physics
  /// 1-based joints, not coverage joints, that the model does not predict to the noise and
  /// that, refitted on this log with their suggestions (JointFinding::
  /// residual_rms_with_suggestions; refit_rms when the search did not run), still stay above
  /// noise_tolerance times the noise: error that neither the model class nor the candidate
  /// effects explain (a load that changes during the log, a state the log does not record).
  /// The message names them with every verdict but kExplained; with kUnexplained it may be
  /// empty (the joint above the noise on the log and the one whose refit is short differ).
  std::vector<int> unexplained_joints;
  /// With DiagnosisOptions::training_inputs: distance of the log's rows to the nearest training
  /// state, per joint in the joint's standardised (q, qd, qdd) (1 = one training standard
  /// deviation away), decimated in time to at most 400 points (the largest distance of each
  /// stretch of rows): time (or row index without times) and distances (points x N).
  Vector distance_time;
  Matrix distance;
};

/// The chain identified again on the training data and the log (DiagnosisOptions::
/// reidentify_chain; FINDINGS.json "chain").
struct ChainFinding {
  /// True when the chain identified again lowers the log's error of the model refitted on the
  /// training rows and the log by min_residual_fall on some joint (`joints`) and raises it by
  /// as much on none (a chain the least squares cannot tell from the model's can need inertial
  /// parameters the refit's prior does not expect): the joints'
  /// refit_rms, the coverage finding and the suggestions are then against the model on that
  /// chain (the joints' rms, nmse and concentrations stay the model's own). False: everything
  /// is against the model as it is.
  bool changed = false;
  std::vector<int> joints;
  /// Per joint: the log's residual RMS of the model on its own chain, refitted on the training
  /// rows and the log (JointFinding::refit_rms of the diagnosis without the chain identified
  /// again), and on the chain identified again.
  Vector refit_rms_before;
  Vector refit_rms_after;
  /// The effects beside the chain in that identification besides the model's own: the
  /// suggestions on the model's chain (not those of the log alone), so that a missing effect
  /// does not bend the chain identified again (effect list text; empty: none).
  std::string effects;
  /// The kinematic parameters (ChainKinematicNames) of the model's chain and of the chain
  /// identified again, and that identification's final cost (ChainIdentificationSummary).
  Vector kinematics_before;
  Vector kinematics;
  double cost = 0;
  /// Suggestions (their spec text) the model's own chain gave that the chain identified again
  /// does not: error of the chain, not a missing effect. Empty unless changed.
  std::vector<std::string> explained;
  /// The chain identified again, as a URDF document (ChainUrdf).
  std::string urdf;
  double seconds = 0;   ///< the identification and the fit on its chain
  std::string message;  ///< one sentence for people; what failed when the search or fit did
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
  /// The closest candidates that were not suggested (at most DiagnosisOptions::max_refused):
  /// those that passed against the model alone and not after the suggestions first, then by
  /// white-noise evidence gain; an effect suggested on a joint is not listed there.
  /// FINDINGS.json "refused".
  std::vector<Refusal> refused;
  int num_samples = 0;
  std::string model;  ///< model spec and effects in use
  /// What the candidates were scored against: the model's feature map, or Nystrom features
  /// of its kernel.
  std::string features;
  /// Relative noise level sigma_n found by evidence on these data (noise of joint j is
  /// noise_std times the joint's output scale).
  double noise_std = 0;
  CoverageFinding coverage;
  /// Stops at the same configuration that hold other torques (static friction): error no
  /// model of the state and no candidate effect explains (FINDINGS.json "holding_torque").
  HoldingTorqueFinding holding;
  /// Set when DiagnosisOptions::reidentify_chain applied (a model on an identified chain,
  /// diagnosed with its training data).
  std::optional<ChainFinding> chain;
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
