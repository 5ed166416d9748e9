#ifndef STRUCTGP_IO_CSV_H_
#define STRUCTGP_IO_CSV_H_

/// @file
/// Robot data files in CSV: reading them with precise error messages, writing them
/// atomically. The format and every error message are described in docs/csv-format.md.

#include <limits>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "structgp/io/atomic_file.h"
#include "structgp/io/data_error.h"
#include "structgp/io/robot_data.h"

namespace structgp {

/// Knobs of ReadRobotCsv. The defaults suit measured robot data in SI units.
struct CsvOptions {
  /// Number of joints the caller needs; 0 infers it from the header. When set, a file with
  /// another number of joints is an error ("expected 3 joints (model), file has 2").
  int expected_joints = 0;
  /// Accept NaN and Inf cells ("nan", "inf", "-inf", any case) in the q, qd, qdd and tau
  /// columns. The `t` column must be finite whatever this says.
  bool allow_non_finite = false;
  /// Largest magnitude accepted in the q, qd, qdd and tau columns; a larger value is taken as
  /// a unit or logging mistake. Must be positive; +infinity disables the check. The `t`
  /// column is not limited (it may hold Unix time stamps).
  double max_abs = 1e6;
};

/// Reads robot data from a CSV file, plain or gzip-compressed (recognised by its content,
/// not its name).
///
/// Format: a header row, then one row per sample, cells separated by ','. The header names
/// the columns q1..qN, qd1..qdN, qdd1..qddN, tau1..tauN in any order (or cur1..curN, motor
/// currents, in place of tau1..tauN: RobotData::target), and optionally `t` (seconds; a time
/// below the previous row's starts a new trajectory, RobotData::segments()); N is the largest
/// k with q1..qk all present, and all 4N columns must be there. Other columns are ignored (and not parsed). Whitespace around
/// cells, a UTF-8 byte order mark, CRLF line endings and empty lines at the end are accepted.
///
/// Throws DataError, naming the file, line and column, for anything wrong in the file; see
/// docs/csv-format.md for the list. Throws std::invalid_argument for invalid `options`.
RobotData ReadRobotCsv(const std::string& path, const CsvOptions& options = {});

/// The canonical header of an N-joint robot data file: `t` first when `with_time`, then
/// q1..qN, qd1..qdN, qdd1..qddN, tau1..tauN.
std::vector<std::string> RobotCsvHeader(int num_joints, bool with_time);

/// The text of a CSV file: one header row, then one row per row of `values`, each number
/// written with `precision` significant digits (1..17; 17 reads back exactly) or, when
/// `precision` is 0, with the fewest digits that read back exactly. NaN and Inf are written as
/// "nan", "inf", "-inf". Throws std::invalid_argument when header.size() != values.cols(),
/// when a name contains ',', '"' or a line break, or when `precision` is outside 0..17.
std::string CsvText(const std::vector<std::string>& header, const Eigen::MatrixXd& values,
                    int precision = 17);

/// Writes CsvText(header, values, precision) atomically (see WriteTextAtomically). Throws as
/// CsvText, and DataError when the file cannot be written (the previous file, if any, is then
/// left untouched).
void WriteCsvAtomically(const std::string& path, const std::vector<std::string>& header,
                        const Eigen::MatrixXd& values, int precision = 17);

/// The text WriteRobotCsv writes (throws as it does, but never DataError).
std::string RobotCsvText(const RobotData& data);

/// Writes `data` atomically with the canonical header (RobotCsvHeader; cur1..curN for currents)
/// and 17 significant
/// digits, so that ReadRobotCsv gives back exactly the same numbers. Throws
/// std::invalid_argument when the sizes of X, Y and t do not agree with num_joints, DataError
/// when the file cannot be written.
void WriteRobotCsv(const std::string& path, const RobotData& data);

}  // namespace structgp

#endif  // STRUCTGP_IO_CSV_H_
