#include "structgp/io/csv.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <map>
#include <stdexcept>
#include <string>
#include <string_view>
#include <system_error>
#include <utility>
#include <vector>

#include "io/csv_cells.h"
#include "io/line_reader.h"
#include "structgp/core/validate.h"

namespace structgp {
namespace {

using internal::Cell;
using internal::CellColumn;
using internal::EditorColumn;
using internal::IsBlankLine;
using internal::ParseNumber;
using internal::ParseResult;
using internal::Quoted;
using internal::Shortest;
using internal::SplitCells;

// Most header names listed when the header has no joint columns at all.
constexpr std::size_t kMaxListedNames = 10;

// The four quantities of a robot data file, in the order of their columns in X then Y.
constexpr int kNumBlocks = 4;
constexpr const char* kBlockPrefix[kNumBlocks] = {"q", "qd", "qdd", "tau"};

const char* const kExpectedColumns = "q1..qN, qd1..qdN, qdd1..qddN, tau1..tauN";

std::string Join(const std::vector<std::string>& names) {
  std::string out;
  for (const std::string& name : names) {
    if (!out.empty()) out += ", ";
    out += name;
  }
  return out;
}

// A column the reader uses: `t`, or joint `joint` (1-based) of block `block`; `current` for
// the targets written as motor currents (curN, in place of tauN).
struct ColumnName {
  bool is_time = false;
  int block = 0;
  int joint = 0;
  bool current = false;
};

// Motor currents in place of the torques.
constexpr const char* kCurrentPrefix = "cur";

bool ParseColumnName(std::string_view name, ColumnName* out) {
  if (name == "t") {
    *out = ColumnName{true, 0, 0};
    return true;
  }
  const std::string_view cur = kCurrentPrefix;
  if (name.size() > cur.size() && name.substr(0, cur.size()) == cur) {
    const std::string_view digits = name.substr(cur.size());
    if (digits[0] < '1' || digits[0] > '9') return false;
    int joint = 0;
    const auto result = std::from_chars(digits.data(), digits.data() + digits.size(), joint);
    if (result.ec != std::errc() || result.ptr != digits.data() + digits.size()) return false;
    *out = ColumnName{false, kNumBlocks - 1, joint, true};
    return true;
  }
  // Longest prefix first: "qdd3" must not be read as "q" + "dd3".
  for (int block = kNumBlocks - 1; block >= 0; --block) {
    const std::string_view prefix = kBlockPrefix[block];
    if (name.size() <= prefix.size() || name.substr(0, prefix.size()) != prefix) continue;
    const std::string_view digits = name.substr(prefix.size());
    if (digits[0] < '1' || digits[0] > '9') return false;  // No "q0", "q01", "q-1".
    int joint = 0;
    const auto result = std::from_chars(digits.data(), digits.data() + digits.size(), joint);
    if (result.ec != std::errc() || result.ptr != digits.data() + digits.size()) return false;
    *out = ColumnName{false, block, joint};
    return true;
  }
  return false;
}

std::string CanonicalName(int block, int joint, bool current = false) {
  return (current ? std::string(kCurrentPrefix) : std::string(kBlockPrefix[block])) +
         std::to_string(joint);
}

// What the reader does with each CSV column.
struct Layout {
  int num_joints = 0;
  int num_cells = 0;
  // Per CSV column: -1 ignored, 0..4N-1 the column of [X Y], 4N the time.
  std::vector<int> role;
  std::vector<std::string> names;  // Per CSV column, as written in the header (trimmed).
};

class CsvReader {
 public:
  CsvReader(const std::string& path, const CsvOptions& options)
      : path_(path), options_(options), reader_(path) {}

  RobotData Read();

 private:
  [[noreturn]] void Fail(int line, int column, const std::string& message) const {
    throw DataError(path_, line, column, message);
  }
  [[noreturn]] void FailCell(int column_index, const std::string& message) const {
    Fail(reader_.line_number(), CellColumn(line_, cells_[column_index]),
         "CSV column " + std::to_string(column_index + 1) + " (" +
             layout_.names[column_index] + "): " + message);
  }

  void ReadHeader();
  void ReadRow();
  double ParseCell(int column_index, bool is_time);

  std::string path_;
  CsvOptions options_;
  internal::LineReader reader_;
  std::string line_;
  std::vector<Cell> cells_;
  Layout layout_;
  bool current_ = false;  // the targets are cur1..curN

  std::vector<double> values_;  // Row-major, 4N per row: q, qd, qdd, tau.
  std::vector<double> times_;
  std::vector<int> lines_;
};

void CsvReader::ReadHeader() {
  if (!reader_.Next(&line_)) {
    Fail(0, 0, "no data rows: the file is empty (expected a header row naming the columns " +
                   std::string(kExpectedColumns) + ", then data rows)");
  }
  if (IsBlankLine(line_)) {
    Fail(1, 1, std::string("line 1 is empty, expected the header row naming the columns ") +
                   kExpectedColumns);
  }
  const std::size_t carriage_return = line_.find('\r');
  if (carriage_return != std::string::npos) {
    Fail(1, EditorColumn(line_, carriage_return),
         "carriage return inside the header line: lines must end with LF or CR LF "
         "(old Mac CR-only line endings are not supported)");
  }
  SplitCells(line_, &cells_);
  if (cells_.size() == 1) {
    for (const char separator : {';', '\t'}) {
      const std::size_t at = line_.find(separator);
      if (at == std::string::npos) continue;
      Fail(1, EditorColumn(line_, at),
           std::string("the header is a single column containing ") +
               (separator == ';' ? "';'" : "a tab") +
               ": cells must be separated by ',' (other separators are not supported)");
    }
  }
  double number = 0.0;
  if (ParseNumber(CellText(line_, cells_[0]), &number) == ParseResult::kOk) {
    Fail(1, CellColumn(line_, cells_[0]),
         "expected a header row of column names, got a number " +
             Quoted(CellText(line_, cells_[0])) + " in CSV column 1 (the header row is required: " +
             kExpectedColumns + ")");
  }

  const int num_cells = static_cast<int>(cells_.size());
  layout_.num_cells = num_cells;
  layout_.names.resize(num_cells);
  std::vector<ColumnName> parsed(num_cells);
  std::vector<bool> recognised(num_cells, false);
  std::map<std::string, int> first_seen;  // Recognised name -> CSV column (0-based).
  int max_joint = 0;
  for (int c = 0; c < num_cells; ++c) {
    layout_.names[c] = std::string(CellText(line_, cells_[c]));
    if (!ParseColumnName(layout_.names[c], &parsed[c])) continue;
    recognised[c] = true;
    const auto [it, inserted] = first_seen.emplace(layout_.names[c], c);
    if (!inserted) {
      Fail(1, CellColumn(line_, cells_[c]),
           "duplicated column '" + layout_.names[c] + "': CSV columns " +
               std::to_string(it->second + 1) + " and " + std::to_string(c + 1));
    }
    if (!parsed[c].is_time) max_joint = std::max(max_joint, parsed[c].joint);
  }

  // N: the largest k with q1..qk all present.
  int n = 0;
  while (n < max_joint && first_seen.count(CanonicalName(0, n + 1)) > 0) ++n;
  if (n == 0) {
    std::vector<std::string> shown;
    for (int c = 0; c < num_cells && shown.size() < kMaxListedNames; ++c) {
      shown.push_back(Quoted(layout_.names[c]));
    }
    std::string listed = Join(shown);
    if (static_cast<std::size_t>(num_cells) > kMaxListedNames) listed += ", ...";
    Fail(1, 0, std::string("no joint columns: expected ") + kExpectedColumns + " (q1 is " +
                   "missing; header has " + listed + ")");
  }
  for (int c = 0; c < num_cells; ++c) {
    if (recognised[c] && !parsed[c].is_time && parsed[c].joint > n) {
      Fail(1, CellColumn(line_, cells_[c]),
           "column '" + layout_.names[c] + "' (CSV column " + std::to_string(c + 1) +
               ") is for joint " + std::to_string(parsed[c].joint) + ", but the header has q1..q" +
               std::to_string(n) + " only (" + CanonicalName(0, n + 1) +
               " is missing; joints must be numbered 1..N without gaps)");
    }
  }
  // The targets: tau1..tauN, or motor currents cur1..curN when no tau column is there.
  bool any_tau = false;
  for (int joint = 1; joint <= n; ++joint) any_tau |= first_seen.count(CanonicalName(3, joint)) > 0;
  bool all_cur = !any_tau;
  for (int joint = 1; joint <= n && all_cur; ++joint) {
    all_cur = first_seen.count(CanonicalName(3, joint, true)) > 0;
  }
  current_ = all_cur;
  std::vector<std::string> missing;
  std::vector<std::string> present;
  for (int block = 0; block < kNumBlocks; ++block) {
    for (int joint = 1; joint <= n; ++joint) {
      const std::string name = CanonicalName(block, joint, block == 3 && current_);
      (first_seen.count(name) > 0 ? present : missing).push_back(name);
    }
  }
  if (!missing.empty()) {
    const bool targets_missing = missing.back().rfind("tau", 0) == 0;
    Fail(1, 0, std::string(missing.size() == 1 ? "missing column " : "missing columns ") +
                   Join(missing) + " (header has " + Join(present) + ")" +
                   (targets_missing && !any_tau
                        ? "; a log of motor currents names them cur1..curN instead of tau1..tauN"
                        : ""));
  }
  if (options_.expected_joints > 0 && options_.expected_joints != n) {
    Fail(1, 0, "expected " + std::to_string(options_.expected_joints) +
                   " joints (model), file has " + std::to_string(n));
  }

  layout_.num_joints = n;
  layout_.role.assign(num_cells, -1);
  for (int c = 0; c < num_cells; ++c) {
    // The other kind of target column (cur beside tau) is ignored.
    if (recognised[c] && !parsed[c].is_time && parsed[c].current != (parsed[c].block == 3 && current_)) {
      recognised[c] = false;
    }
    if (!recognised[c]) continue;
    layout_.role[c] = parsed[c].is_time ? kNumBlocks * n
                                        : parsed[c].block * n + (parsed[c].joint - 1);
  }
}

double CsvReader::ParseCell(int c, bool is_time) {
  const std::string_view text = CellText(line_, cells_[c]);
  double value = 0.0;
  switch (ParseNumber(text, &value)) {
    case ParseResult::kOk:
      break;
    case ParseResult::kNotANumber:
      FailCell(c, text.empty() ? std::string("expected a number, got an empty cell")
                               : "expected a number, got " + Quoted(text));
    case ParseResult::kOutOfRange:
      FailCell(c, "expected a number, got " + Quoted(text) +
                      ", which is outside the range of a double");
  }
  if (is_time) {
    if (!std::isfinite(value)) FailCell(c, "expected a finite time, got " + Quoted(text));
    return value;
  }
  if (!std::isfinite(value)) {
    if (options_.allow_non_finite) return value;
    FailCell(c, "expected a finite number, got " + Quoted(text) +
                    " (CsvOptions::allow_non_finite accepts NaN and Inf)");
  }
  if (std::abs(value) > options_.max_abs) {
    FailCell(c, "expected a magnitude of at most " + Shortest(options_.max_abs) +
                    " (CsvOptions::max_abs), got " + Quoted(text) +
                    "; wrong units or a logging glitch?");
  }
  return value;
}

void CsvReader::ReadRow() {
  SplitCells(line_, &cells_);
  const int got = static_cast<int>(cells_.size());
  if (got != layout_.num_cells) {
    const int column = got > layout_.num_cells
                           ? CellColumn(line_, cells_[layout_.num_cells])
                           : EditorColumn(line_, line_.size());
    Fail(reader_.line_number(), column,
         "expected " + std::to_string(layout_.num_cells) + " cells (as in the header), got " +
             std::to_string(got) +
             (got > layout_.num_cells ? " (numbers must use '.' as the decimal mark)" : ""));
  }
  const int width = kNumBlocks * layout_.num_joints;
  const std::size_t row_start = values_.size();
  values_.resize(row_start + width);
  for (int c = 0; c < got; ++c) {
    const int role = layout_.role[c];
    if (role < 0) continue;
    if (role < width) {
      values_[row_start + role] = ParseCell(c, false);
      continue;
    }
    // A time below the previous one starts a new trajectory (core/segments.h).
    times_.push_back(ParseCell(c, true));
  }
  lines_.push_back(reader_.line_number());
}

RobotData CsvReader::Read() {
  ReadHeader();
  while (internal::NextDataLine(&reader_, path_, &line_)) ReadRow();
  if (lines_.empty()) Fail(1, 0, "no data rows: the header is not followed by any data");

  const int n = layout_.num_joints;
  const Eigen::Index m = static_cast<Eigen::Index>(lines_.size());
  const Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>
      all(values_.data(), m, kNumBlocks * n);
  RobotData data;
  data.num_joints = n;
  data.X = all.leftCols(3 * n);
  data.Y = all.rightCols(n);
  if (!times_.empty()) data.t = Eigen::Map<const Eigen::VectorXd>(times_.data(), m);
  data.source = path_;
  data.line = Eigen::Map<const Eigen::VectorXi>(lines_.data(), m);
  data.target = current_ ? RobotData::Target::kCurrent : RobotData::Target::kTorque;
  return data;
}

void AppendNumber(double value, int precision, std::string* out) {
  char buffer[64];
  std::to_chars_result result;
  if (std::isnan(value)) {
    *out += "nan";
    return;
  }
  if (precision == 0) {
    result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  } else {
    result = std::to_chars(buffer, buffer + sizeof(buffer), value, std::chars_format::general,
                           precision);
  }
  out->append(buffer, result.ptr);
}

}  // namespace

RobotData ReadRobotCsv(const std::string& path, const CsvOptions& options) {
  if (options.expected_joints < 0) {
    throw std::invalid_argument("CsvOptions::expected_joints: expected 0 (infer) or a positive "
                                "number of joints, got " +
                                std::to_string(options.expected_joints));
  }
  if (!(options.max_abs > 0.0)) {
    throw std::invalid_argument("CsvOptions::max_abs: expected a positive limit, got " +
                                Shortest(options.max_abs));
  }
  CsvReader reader(path, options);
  return reader.Read();
}

std::vector<std::string> RobotCsvHeader(int num_joints, bool with_time) {
  if (num_joints < 1) {
    throw std::invalid_argument("RobotCsvHeader: expected at least 1 joint, got " +
                                std::to_string(num_joints));
  }
  std::vector<std::string> header;
  if (with_time) header.push_back("t");
  for (int block = 0; block < kNumBlocks; ++block) {
    for (int joint = 1; joint <= num_joints; ++joint) {
      header.push_back(CanonicalName(block, joint));
    }
  }
  return header;
}

std::string CsvText(const std::vector<std::string>& header, const Eigen::MatrixXd& values,
                    int precision) {
  RequireSize("CsvText: header", static_cast<Eigen::Index>(header.size()), values.cols(),
              "names (one per column of values)");
  if (precision < 0 || precision > 17) {
    throw std::invalid_argument("CsvText: expected a precision in 0..17, got " +
                                std::to_string(precision));
  }
  std::string contents;
  for (std::size_t c = 0; c < header.size(); ++c) {
    if (header[c].find_first_of(",\"\r\n") != std::string::npos) {
      throw std::invalid_argument("CsvText: header name " + std::to_string(c + 1) + " " +
                                  Quoted(header[c]) + " contains ',', '\"' or a line break");
    }
    if (c > 0) contents += ',';
    contents += header[c];
  }
  contents += '\n';
  contents.reserve(contents.size() + static_cast<std::size_t>(values.size()) * 24);
  for (Eigen::Index i = 0; i < values.rows(); ++i) {
    for (Eigen::Index j = 0; j < values.cols(); ++j) {
      if (j > 0) contents += ',';
      AppendNumber(values(i, j), precision, &contents);
    }
    contents += '\n';
  }
  return contents;
}

void WriteCsvAtomically(const std::string& path, const std::vector<std::string>& header,
                        const Eigen::MatrixXd& values, int precision) {
  WriteTextAtomically(path, CsvText(header, values, precision));
}

std::string RobotCsvText(const RobotData& data) {
  const int n = data.num_joints;
  if (n < 1) {
    throw std::invalid_argument("RobotCsvText: expected num_joints >= 1, got " +
                                std::to_string(n));
  }
  RequireSize("RobotCsvText: X", data.X.cols(), 3 * n, "columns (3 x num_joints)");
  RequireSize("RobotCsvText: Y", data.Y.cols(), n, "columns (num_joints)");
  RequireSize("RobotCsvText: Y", data.Y.rows(), data.X.rows(), "rows (as X)");
  if (data.has_time()) RequireSize("RobotCsvText: t", data.t.size(), data.X.rows(), "entries");
  const int offset = data.has_time() ? 1 : 0;
  Eigen::MatrixXd values(data.X.rows(), offset + 4 * n);
  if (data.has_time()) values.col(0) = data.t;
  values.middleCols(offset, 3 * n) = data.X;
  values.rightCols(n) = data.Y;
  std::vector<std::string> header = RobotCsvHeader(n, data.has_time());
  if (data.target == RobotData::Target::kCurrent) {
    for (int j = 0; j < n; ++j) header[header.size() - n + j] = CanonicalName(3, j + 1, true);
  }
  return CsvText(header, values, 17);
}

void WriteRobotCsv(const std::string& path, const RobotData& data) {
  WriteTextAtomically(path, RobotCsvText(data));
}

}  // namespace structgp
