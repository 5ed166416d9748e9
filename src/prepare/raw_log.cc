#include "structgp/prepare/raw_log.h"

#include <charconv>
#include <cmath>
#include <map>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

#include "io/csv_cells.h"
#include "io/line_reader.h"
#include "structgp/io/data_error.h"

namespace structgp {
namespace {

using internal::Cell;
using internal::CellText;
using internal::EditorColumn;
using internal::IsBlankLine;
using internal::ParseNumber;
using internal::ParseResult;
using internal::Quoted;
using internal::SplitCells;

// The per-joint column sets of a raw log, in the order of their storage.
enum Block { kQ = 0, kTau = 1, kCurrent = 2, kNumBlocks = 3 };
constexpr const char* kPrefix[kNumBlocks] = {"q", "tau", "i"};
constexpr const char* kExpected = "t (optional), q1..qN, and tau1..tauN or i1..iN";
// "q12" -> (kQ, 12); "t" -> (-1, 0); false for any other name.
bool ParseName(std::string_view name, int* block, int* joint) {
  if (name == "t") {
    *block = -1;
    *joint = 0;
    return true;
  }
  for (int b = 0; b < kNumBlocks; ++b) {
    const std::string_view prefix = kPrefix[b];
    if (name.size() <= prefix.size() || name.substr(0, prefix.size()) != prefix) continue;
    const std::string_view digits = name.substr(prefix.size());
    if (digits[0] < '1' || digits[0] > '9') continue;
    int j = 0;
    const auto r = std::from_chars(digits.data(), digits.data() + digits.size(), j);
    if (r.ec != std::errc() || r.ptr != digits.data() + digits.size()) continue;
    *block = b;
    *joint = j;
    return true;
  }
  return false;
}

class RawReader {
 public:
  explicit RawReader(const std::string& path) : path_(path), reader_(path) {}
  RawLog Read();

 private:
  [[noreturn]] void Fail(int line, int column, const std::string& message) const {
    throw DataError(path_, line, column, message);
  }
  int ColumnOf(const Cell& c) const { return internal::CellColumn(line_, c); }
  void Header();
  void Row();

  std::string path_;
  internal::LineReader reader_;
  std::string line_;
  std::vector<Cell> cells_;
  std::vector<std::string> names_;
  int n_ = 0;
  bool has_time_ = false, has_tau_ = false, has_current_ = false;
  // Per CSV column: -2 ignored, -1 time, else block * n + joint - 1.
  std::vector<int> role_;
  std::vector<double> values_;  // row-major, 3N per row (q, tau, i)
  std::vector<double> times_;
  std::vector<int> lines_, time_columns_;
};

void RawReader::Header() {
  if (!reader_.Next(&line_)) {
    Fail(0, 0,
         std::string("no data rows: the file is empty (expected a header row naming the "
                     "columns ") +
             kExpected + ")");
  }
  if (IsBlankLine(line_))
    Fail(1, 1, std::string("line 1 is empty, expected the header row: ") + kExpected);
  SplitCells(line_, &cells_);
  const int count = static_cast<int>(cells_.size());
  std::map<std::string, int> seen;
  std::vector<int> block(count, -2), joint(count, 0);
  int max_joint[kNumBlocks] = {0, 0, 0};
  names_.resize(count);
  for (int c = 0; c < count; ++c) {
    names_[c] = line_.substr(cells_[c].begin, cells_[c].end - cells_[c].begin);
    if (!ParseName(names_[c], &block[c], &joint[c])) {
      block[c] = -2;
      continue;
    }
    const auto [it, inserted] = seen.emplace(names_[c], c);
    if (!inserted) {
      Fail(1, ColumnOf(cells_[c]),
           "duplicated column '" + names_[c] + "': CSV columns " + std::to_string(it->second + 1) +
               " and " + std::to_string(c + 1));
    }
    if (block[c] >= 0) max_joint[block[c]] = std::max(max_joint[block[c]], joint[c]);
  }
  while (n_ < max_joint[kQ] && seen.count("q" + std::to_string(n_ + 1)) > 0) ++n_;
  if (n_ == 0) {
    Fail(1, 0,
         std::string("no joint position columns: expected ") + kExpected + " (q1 is missing)");
  }
  has_time_ = seen.count("t") > 0;
  bool present[kNumBlocks] = {true, false, false};
  for (int b = kTau; b < kNumBlocks; ++b) {
    std::vector<std::string> missing;
    int found = 0;
    for (int j = 1; j <= n_; ++j) {
      const std::string name = kPrefix[b] + std::to_string(j);
      if (seen.count(name) > 0) {
        ++found;
      } else {
        missing.push_back(name);
      }
    }
    if (found > 0 && !missing.empty()) {
      std::string list;
      for (const auto& m : missing) list += (list.empty() ? "" : ", ") + m;
      Fail(1, 0,
           std::string(missing.size() == 1 ? "missing column " : "missing columns ") + list +
               " (the header has q1..q" + std::to_string(n_) + ", so " + kPrefix[b] + "1.." +
               kPrefix[b] + std::to_string(n_) + " must be complete or absent)");
    }
    present[b] = found > 0;
  }
  for (int c = 0; c < count; ++c) {
    if (block[c] >= 0 && joint[c] > n_) {
      Fail(1, ColumnOf(cells_[c]),
           "column '" + names_[c] + "' (CSV column " + std::to_string(c + 1) + ") is for joint " +
               std::to_string(joint[c]) + ", but the header has q1..q" + std::to_string(n_) +
               " only (joints must be numbered 1..N without gaps)");
    }
  }
  has_tau_ = present[kTau];
  has_current_ = present[kCurrent];
  if (!has_tau_ && !has_current_) {
    Fail(1, 0,
         "no torque or current columns: expected tau1..tau" + std::to_string(n_) + " or i1..i" +
             std::to_string(n_));
  }
  role_.assign(count, -2);
  for (int c = 0; c < count; ++c) {
    if (block[c] == -1) role_[c] = -1;
    if (block[c] >= 0) role_[c] = block[c] * n_ + joint[c] - 1;
  }
}

void RawReader::Row() {
  SplitCells(line_, &cells_);
  const int got = static_cast<int>(cells_.size());
  const int want = static_cast<int>(role_.size());
  if (got != want) {
    const int column = got > want ? ColumnOf(cells_[want]) : EditorColumn(line_, line_.size());
    Fail(reader_.line_number(), column,
         "expected " + std::to_string(want) + " cells (as in the header), got " +
             std::to_string(got) +
             (got > want ? " (numbers must use '.' as the decimal mark)" : ""));
  }
  const std::size_t start = values_.size();
  values_.resize(start + 3 * static_cast<std::size_t>(n_), 0.0);
  for (int c = 0; c < got; ++c) {
    if (role_[c] == -2) continue;
    const std::string_view text = CellText(line_, cells_[c]);
    double value = 0.0;
    const ParseResult parsed = ParseNumber(text, &value);
    const std::string where = "CSV column " + std::to_string(c + 1) + " (" + names_[c] + "): ";
    if (parsed != ParseResult::kOk) {
      Fail(reader_.line_number(), ColumnOf(cells_[c]),
           where + (text.empty() ? std::string("expected a number, got an empty cell")
                                 : "expected a number, got " + Quoted(text) +
                                       (parsed == ParseResult::kOutOfRange
                                            ? ", which is outside the range of a double"
                                            : "")));
    }
    if (!std::isfinite(value)) {
      Fail(reader_.line_number(), ColumnOf(cells_[c]),
           where + "expected a finite number, got " + Quoted(text));
    }
    if (role_[c] == -1) {
      times_.push_back(value);
      time_columns_.push_back(ColumnOf(cells_[c]));
    } else {
      values_[start + static_cast<std::size_t>(role_[c])] = value;
    }
  }
  lines_.push_back(reader_.line_number());
}

RawLog RawReader::Read() {
  Header();
  while (internal::NextDataLine(&reader_, path_, &line_)) Row();
  if (lines_.empty()) Fail(1, 0, "no data rows: the header is not followed by any data");
  const Eigen::Index m = static_cast<Eigen::Index>(lines_.size());
  const Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>
      all(values_.data(), m, 3 * n_);
  RawLog log;
  log.num_joints = n_;
  log.q = all.leftCols(n_);
  log.tau = has_tau_ ? Eigen::MatrixXd(all.middleCols(n_, n_)) : Eigen::MatrixXd(m, 0);
  log.current = has_current_ ? Eigen::MatrixXd(all.rightCols(n_)) : Eigen::MatrixXd(m, 0);
  if (has_time_) {
    log.t = Eigen::Map<const Eigen::VectorXd>(times_.data(), m);
    log.time_column = Eigen::Map<const Eigen::VectorXi>(time_columns_.data(), m);
  }
  log.source = path_;
  log.line = Eigen::Map<const Eigen::VectorXi>(lines_.data(), m);
  return log;
}

}  // namespace

RawLog ReadRawLogCsv(const std::string& path) {
  RawReader reader(path);
  return reader.Read();
}

}  // namespace structgp
