#ifndef STRUCTGP_DIAGNOSE_HOLDING_TORQUE_H_
#define STRUCTGP_DIAGNOSE_HOLDING_TORQUE_H_

/// @file
/// Torques at rest that the state does not determine: static friction.
///
/// An arm at rest holds whatever torque static friction and its controller leave: anything in
/// the joint's stiction band, depending on how the motion before the stop ended. Two stops at
/// the same configuration can then hold torques far apart, and no function of (q, qd, qdd)
/// can predict both: no model of the library and no candidate effect (docs/diagnosis.md,
/// "Torques at rest"). FindHoldingTorques finds the stretches of a log where every joint is at
/// rest, pairs those at the same configuration, and reports each joint whose mean torque (less
/// what a model predicts there, when given) differs between such a pair by many times its
/// noise at rest. That error bounds what any model of the state can reach on the still parts of
/// the log; the finding says so instead of leaving it unexplained.

#include <string>
#include <vector>

#include "structgp/core/types.h"

namespace structgp {

struct HoldingTorqueOptions {
  /// A row is at rest when every joint's |qd| is below this, rad/s.
  double rest_velocity = 0.005;
  /// A still stretch has at least this many consecutive rows at rest.
  int min_rest_rows = 50;
  /// The residual of a stretch is read on its first rows, at most this many (>= min_rest_rows):
  /// at rest the held torque is constant, and a model is asked for no more predictions.
  int max_rows_per_stretch = 200;
  /// Two stretches are at the same configuration when the mean angles of every joint differ
  /// by at most this, rad. The torques compared are the residuals of the model, whose
  /// predictions carry the gravity of each configuration, so the stops need not be exact.
  double pose_tolerance = 0.05;
  /// A joint is reported when the mean residuals of a pair differ by at least this many times
  /// its noise at rest (the spread of its residual's successive differences within the still
  /// stretches: median absolute difference / (0.674 sqrt 2)).
  double min_difference_to_noise = 10.0;

  /// True when the options are usable; otherwise false with the reason in *error (may be null).
  bool IsValid(std::string* error) const;
};

/// Rows [begin, end) of the data where every joint is at rest.
struct RestStretch {
  int begin = 0;
  int end = 0;
  Vector pose;           ///< mean q (N)
  /// Mean residual (N) over the stretch's first max_rows_per_stretch rows (FindHoldingTorques;
  /// empty from FindRestStretches).
  Vector mean_residual;
};

struct HoldingTorqueJoint {
  int joint = 0;            ///< 1-based
  double difference = 0.0;  ///< largest |mean residual A - mean residual B| of a pair, N m
  int stretch_a = 0;        ///< the pair (indices into HoldingTorqueFinding::stretches)
  int stretch_b = 0;
  double noise = 0.0;       ///< the joint's noise at rest, N m
};

struct HoldingTorqueFinding {
  std::vector<RestStretch> stretches;
  /// Pairs of stretches at the same configuration (indices into stretches).
  int num_pairs = 0;
  /// Joints whose torque at rest differs between stops at the same configuration by at least
  /// min_difference_to_noise times their noise, largest ratio first.
  std::vector<HoldingTorqueJoint> joints;
  /// One sentence for people; empty when joints is.
  std::string message;
};

/// The still stretches of X (rows in time order, at least 2 N columns: q, qd, ...):
/// num_joints' velocities all below options.rest_velocity for min_rest_rows rows or more, not
/// crossing a segment start (see FindHoldingTorques). Throws std::invalid_argument as it.
std::vector<RestStretch> FindRestStretches(const ConstMatrixRef& X, int num_joints,
                                          const std::vector<int>& segment_starts = {},
                                          const HoldingTorqueOptions& options = {});

/// The still stretches of X (rows in time order, at least 2 N columns: q, qd, ...) and the
/// joints whose residual R (m x N: torques less a model's predictions, or the torques
/// themselves) differs between stops at the same configuration. R is read only on the first
/// max_rows_per_stretch rows of each stretch. segment_starts: rows where a
/// new trajectory starts (a stretch does not cross one; empty: one trajectory). Throws
/// std::invalid_argument on bad sizes, non-finite values, invalid options or segment starts
/// that are not increasing rows of X.
HoldingTorqueFinding FindHoldingTorques(const ConstMatrixRef& X, const ConstMatrixRef& R,
                                        const std::vector<int>& segment_starts = {},
                                        const HoldingTorqueOptions& options = {});

/// The finding's message (empty without joints). Rows before log_begin are named as training
/// rows, the others as rows of the log counted from log_begin: how Diagnose words a finding on
/// the training rows followed by the log (FindHoldingTorques: log_begin 0, "rows B-E").
std::string HoldingTorqueMessage(const HoldingTorqueFinding& finding, int log_begin = 0);

}  // namespace structgp

#endif  // STRUCTGP_DIAGNOSE_HOLDING_TORQUE_H_
