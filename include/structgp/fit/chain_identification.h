#ifndef STRUCTGP_FIT_CHAIN_IDENTIFICATION_H_
#define STRUCTGP_FIT_CHAIN_IDENTIFICATION_H_

/// @file
/// The kinematics of a serial chain of revolute joints found from its joint torques alone, for
/// robots whose URDF is not at hand: the result is a URDF, which the `rbd` models then use as
/// they use a manufacturer's (their inertial parameters are identified from the data).
///
/// The hypothesis space is the rigid-body dynamics of every N-joint revolute chain: the 4N - 4
/// kinematic numbers of rigid_body/dh_chain.h (where each joint axis lies relative to the one
/// before it, and how the first leans against gravity), with the 11 N inertial parameters
/// (armature included), optionally the friction of `+fri` (viscous, Coulomb and an offset per
/// joint) and any effects the user names (a cogging ripple, a spring...: the columns `rbd+fri`
/// with `--effects` has, so that a torque no chain makes does not bend the kinematics). For
/// fixed kinematics the torques are linear in all but the kinematic numbers, so least squares
/// eliminates them (variable projection); the kinematics are searched by Levenberg-Marquardt
/// (Ceres, forward differences) from many random starts on evenly spaced rows, each joint's
/// torque divided by its RMS: every start a few iterations on few rows, the best of them to the
/// end; the start of least cost wins and is refined on more rows. When fewer than two of the
/// starts searched to the end reach the best cost, the minimum is not yet found again, and
/// another round of starts is drawn. The same torques can come from several chains; the URDF is
/// one of them, which is all a model of the torques needs, not a kinematic calibration.

#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "structgp/core/types.h"
#include "structgp/model/model_spec.h"
#include "structgp/rigid_body/dh_chain.h"

namespace structgp {

class RigidBodyChain;

struct ChainIdentificationOptions {
  /// The friction of `+fri` per joint in the least squares: viscous, Coulomb and a constant
  /// offset (a real arm's friction would otherwise bend the kinematics to explain it).
  bool friction = true;
  /// Velocity width of the Coulomb term tanh(qd / width), rad/s (> 0).
  double friction_width = 0.01;
  /// Evenly spaced rows of the kinematic search (>= 2; each cost evaluation is a regressor per
  /// row: about 70 us a row at 7 joints).
  int search_rows = 400;
  /// Evenly spaced rows on which the best start is searched again to the end (more than
  /// search_rows; less or equal: no refinement).
  int refine_rows = 2000;
  /// Effects beside the chain, as `--effects` writes them (ParseEffectList): their bases in the
  /// least squares on their joints. An effect that uses the time needs X's trailing t column.
  std::vector<EffectSpec> effects;
  /// Random starts (>= 0; 0 with initial_kinematics: a local search from there alone, one
  /// round), and the generator's seed. Each is screened: screen_iterations
  /// iterations on screen_rows evenly spaced rows; the kept_starts of least cost then go on to
  /// the end on search_rows rows (all of them when kept_starts >= starts: no screening).
  int starts = 64;
  std::uint64_t seed = 1;
  int kept_starts = 8;
  int screen_rows = 150;
  int screen_iterations = 15;
  /// A start of one's own (NumChainKinematicParameters entries, or empty): kinematics known
  /// roughly, searched to the end beside the first round's kept random starts (numbered -1 in the
  /// summary).
  Vector initial_kinematics;
  /// After the starts: each length of the best chain set to 0 in turn and searched again from
  /// there, kept when the cost falls by 1% (intersecting and coplanar axes that a random start
  /// misses).
  bool length_moves = true;
  /// Levenberg-Marquardt iterations per start (>= 1).
  int max_iterations = 100;
  /// Rounds of starts at most (>= 1): while fewer than two kept starts have reached the best
  /// cost (within 1%), or while the best chain, finished (length moves, refinement), leaves
  /// more than misfit_ratio (> 0; infinity: never) times the white noise of its residual on
  /// some joint (ChainIdentificationSummary::noise), another `starts` random starts are drawn
  /// and screened, and their kept_starts searched to the end. On a log that no chain explains
  /// (a hydraulic arm's, one with effects not given) every round runs.
  int max_rounds = 3;
  double misfit_ratio = 1.5;
  /// Starts searched at once (>= 1).
  int num_threads = 1;
  /// Name of the robot in the URDF.
  std::string robot_name = "identified_chain";
};

struct ChainIdentificationSummary {
  /// The kinematic parameters of the best start (ChainKinematicNames).
  Vector kinematics;
  /// The kept starts of every round (0-based indices among the random starts, round after
  /// round, each round's least screening cost first; -1 is initial_kinematics) and
  /// each one's final cost: the mean over the search rows and joints of the squared residual of
  /// the least squares, each joint's torque divided by its RMS (so 1e-4 is a residual of 1% of
  /// every joint's torque).
  std::vector<int> starts;
  std::vector<double> start_costs;
  /// The start (as in `starts`) whose kinematics won.
  int best_start = -1;
  /// The cost after the length moves, and how many were kept (NaN, 0 without them).
  double moved_cost = std::numeric_limits<double>::quiet_NaN();
  int moves_kept = 0;
  /// The best start's cost after the refinement on refine_rows rows (NaN without it).
  double refined_cost = std::numeric_limits<double>::quiet_NaN();
  /// Per joint, in the torques' units: the RMS of the torque, and of the least-squares residual
  /// on every row with the identified kinematics (the noise, where the chain and the friction
  /// explain the rest).
  Vector torque_rms;
  Vector residual_rms;
  /// Per joint, the white noise in that residual (NoiseFromDifferences, core/noise_level.h:
  /// from its successive differences, within the log's trajectories when X has the time), which
  /// a smooth misfit does not move: residual_rms near it where the chain and the columns beside
  /// it explain the rest; well above it (1.5 times, say) where the search stopped at a wrong
  /// chain, or the torques hold something no chain makes.
  Vector noise;
  /// Kept starts whose cost is within 1% of the best one's (the same minimum found again).
  int starts_at_best = 0;
  /// Rounds of starts drawn (1 when two kept starts of the first reached the best and its chain
  /// explains the log to misfit_ratio times the noise).
  int rounds = 0;
  /// What the log determines, per kinematic parameter (ChainKinematicNames), at the identified
  /// chain on the last rows searched: moved alone by 0.1 (m or rad), the linear parameters
  /// fitted again, how much the cost rises (relative: 0.01 is 1%), and how much the predicted
  /// torques of the same states at twice the speed (qd x 2, qdd x 4) change, as the largest over
  /// the joints of the RMS change over the joint's residual RMS on those rows.
  Vector cost_change;
  Vector faster_change;
  /// The parameters (indices, in order) the log does not determine although faster motion
  /// would show them: cost_change below 1% (the tolerance at which two starts reach the same
  /// minimum) and faster_change above 1. Their values are a guess the data allow; motion of
  /// other speeds may be predicted badly. Parameters that change no torque at any speed (an
  /// offset along two parallel axes) are not listed.
  std::vector<int> undetermined;
  /// The identified chain as a URDF document (placeholder inertias: 1 kg, 0.01 kg m^2).
  std::string urdf;
};

/// Searches the kinematics of X's rows (q, qd, qdd of N joints: 3N columns, or 3N + 1 with the
/// time t last, which only effects that use the time read) from the torques Y (N columns).
/// Throws std::invalid_argument on mismatched sizes, a non-finite entry, a joint
/// whose torque is zero throughout, an option out of range, a robot name with other characters
/// than letters, digits, '_', '-' and '.', an effect that cannot be made, names a joint the
/// robot lacks or needs a time X lacks, or fewer rows (of the data, search_rows, or screen_rows
/// when screening) than give twice as many torques as linear parameters (11 N, 14 N with
/// friction, and the effects' bases). std::runtime_error when no start gives a chain that can be
/// evaluated.
ChainIdentificationSummary IdentifyChain(const ConstMatrixRef& X, const ConstMatrixRef& Y,
                                         const ChainIdentificationOptions& options = {});

/// The same with the times apart: X is states (3N columns) followed by t when t is not empty
/// (one entry per row; std::invalid_argument otherwise), as a log holds them.
ChainIdentificationSummary IdentifyChain(const ConstMatrixRef& states, const ConstVectorRef& t,
                                         const ConstMatrixRef& Y,
                                         const ChainIdentificationOptions& options = {});

/// The search for `chain` again from where it is, when IdentifyChain found it (its URDF as
/// identify wrote it: ChainKinematicsOf): `search` with the chain's kinematics as
/// initial_kinematics, its robot name, and the friction of `spec` (+fri, Coulomb width
/// friction_width) and its effects beside it. nullopt for any other chain.
std::optional<ChainIdentificationOptions> SearchAgainOptions(const RigidBodyChain& chain,
                                                             const ModelSpec& spec,
                                                             double friction_width,
                                                             ChainIdentificationOptions search);

/// The identification's cost at its end: after the refinement, else after the length moves,
/// else the best start's (ChainIdentificationSummary: each a mean squared residual over
/// torques divided by their RMS).
double ChainIdentificationCost(const ChainIdentificationSummary& summary);

/// The summary as JSON, with the options it was found with: {"friction", "effects" (effect
/// list text), "starts", "rounds", "kinematics": {name: value}, "kept_starts" (numbered from
/// 1, round after round; 0 is initial_kinematics), "start_costs", "best_start",
/// "starts_at_best", "moved_cost" and "refined_cost" (when finite), "moves_kept",
/// "undetermined" (names), "cost_change" and "faster_change" ({name: value}, the finite ones),
/// "joints": [{"joint", "torque_rms", "residual_rms", "noise"}]}.
std::string ToJson(const ChainIdentificationSummary& summary,
                   const ChainIdentificationOptions& options);

}  // namespace structgp

#endif  // STRUCTGP_FIT_CHAIN_IDENTIFICATION_H_
