#ifndef STRUCTGP_PREPARE_RAW_LOG_H_
#define STRUCTGP_PREPARE_RAW_LOG_H_

/// @file
/// Raw robot logs as most controllers record them: joint positions against time, with the
/// joint torques or the motor currents, but no velocities or accelerations. prepare.h turns
/// them into robot data files (io/csv.h). The format and its errors are in
/// docs/csv-format.md ("Raw logs").

#include <Eigen/Core>
#include <string>

namespace structgp {

/// m samples of an N-joint log, one row per sample, in file order.
///
/// Invariants (kept by ReadRawLogCsv): q is m x N with m >= 1; t, line and time_column have m
/// entries or none; tau and current are m x N or m x 0 (at least one of them is m x N when
/// read from a file). Every value is finite.
struct RawLog {
  int num_joints = 0;
  /// Time of each sample [s] (column `t`); empty when the file has none.
  Eigen::VectorXd t;
  /// Joint positions q1..qN [rad or m], m x N.
  Eigen::MatrixXd q;
  /// Joint torques tau1..tauN [N m or N], m x N, or m x 0 when the file has none.
  Eigen::MatrixXd tau;
  /// Motor currents i1..iN [A, or the controller's unit], m x N, or m x 0.
  Eigen::MatrixXd current;
  /// The path read (empty for a log made in memory).
  std::string source;
  /// 1-based file line of each row (empty for a log made in memory).
  Eigen::VectorXi line;
  /// 1-based editor column of the `t` cell on each row, so that a time error can point at it
  /// (empty when there is no `t` or no file).
  Eigen::VectorXi time_column;

  int size() const { return static_cast<int>(q.rows()); }
  bool has_time() const { return t.size() > 0; }
  bool has_torque() const { return tau.cols() > 0; }
  bool has_current() const { return current.cols() > 0; }
};

/// Reads a raw log from a CSV file, plain or gzip-compressed: a header row naming the columns
/// q1..qN (required; N is the largest k with q1..qk present), optionally `t` (seconds),
/// tau1..tauN and i1..iN (each set complete or absent, at least one present); other columns
/// (qd, qdd, anything else) are ignored and not parsed. Cells as in ReadRobotCsv: ',' separated,
/// blanks trimmed, numbers in the C locale; every used cell must be a finite number.
///
/// Throws DataError naming the file, line and column for anything wrong: missing or partial
/// column sets, duplicated names, ragged rows, a cell that is not a finite number, no data.
/// The time column's order and spacing are checked by PrepareRawLog, which knows the options.
RawLog ReadRawLogCsv(const std::string& path);

}  // namespace structgp

#endif  // STRUCTGP_PREPARE_RAW_LOG_H_
