#ifndef STRUCTGP_SRC_IO_CSV_CELLS_H_
#define STRUCTGP_SRC_IO_CSV_CELLS_H_

// The pieces every CSV reader of the library shares: data lines (the blank-line rule), cells
// of a line, numbers in cells, and cell text quoted for messages. Private to the library.

#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

#include "io/line_reader.h"

namespace structgp {
namespace internal {

// Longest piece of a user's cell quoted in a message [characters]; longer text is cut.
constexpr std::size_t kMaxQuotedChars = 40;

// One cell of a line: bytes [begin, end) after trimming spaces and tabs and one pair of double
// quotes; `start` is where the cell begins (just after the previous separator).
struct Cell {
  std::size_t start;
  std::size_t begin;
  std::size_t end;
};

// True when the line holds nothing but spaces and tabs.
bool IsBlankLine(const std::string& line);

// Splits the line at every ',' (there is no quoting of separators).
void SplitCells(const std::string& line, std::vector<Cell>* cells);

// The text of a cell.
std::string_view CellText(const std::string& line, const Cell& cell);

// The editor column of a cell: its first character, or where it starts when it is empty.
int CellColumn(const std::string& line, const Cell& cell);

// `text` in single quotes for a message, cut to kMaxQuotedChars, control bytes escaped.
std::string Quoted(std::string_view text);

// The shortest text that reads back as `value`.
std::string Shortest(double value);

enum class ParseResult { kOk, kNotANumber, kOutOfRange };

// Parses the whole of `text` as a decimal number (C locale, optional sign, optional
// exponent; "nan", "inf" and "infinity" in any case). Trailing characters are an error.
ParseResult ParseNumber(std::string_view text, double* value);

// The next data line of `reader` into `line`, skipping blank lines; false at the end of the
// file. Blank lines are allowed only at the end: a data line after one throws DataError
// (file `path`) at the first blank line.
bool NextDataLine(LineReader* reader, const std::string& path, std::string* line);

}  // namespace internal
}  // namespace structgp

#endif  // STRUCTGP_SRC_IO_CSV_CELLS_H_
