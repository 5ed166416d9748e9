#include "io/csv_cells.h"

#include <charconv>
#include <cstdio>
#include <system_error>

#include "structgp/io/data_error.h"

namespace structgp {
namespace internal {

namespace {

bool IsBlank(char c) { return c == ' ' || c == '\t'; }

}  // namespace

bool IsBlankLine(const std::string& line) {
  for (char c : line) {
    if (!IsBlank(c)) return false;
  }
  return true;
}

void SplitCells(const std::string& line, std::vector<Cell>* cells) {
  cells->clear();
  std::size_t start = 0;
  for (;;) {
    std::size_t stop = line.find(',', start);
    if (stop == std::string::npos) stop = line.size();
    std::size_t begin = start;
    std::size_t end = stop;
    while (begin < end && IsBlank(line[begin])) ++begin;
    while (end > begin && IsBlank(line[end - 1])) --end;
    if (end - begin >= 2 && line[begin] == '"' && line[end - 1] == '"') {
      ++begin;
      --end;
    }
    cells->push_back({start, begin, end});
    if (stop == line.size()) break;
    start = stop + 1;
  }
}

std::string_view CellText(const std::string& line, const Cell& cell) {
  return std::string_view(line).substr(cell.begin, cell.end - cell.begin);
}

int CellColumn(const std::string& line, const Cell& cell) {
  return EditorColumn(line, cell.begin < cell.end ? cell.begin : cell.start);
}

std::string Quoted(std::string_view text) {
  std::string out = "'";
  std::size_t shown = 0;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const unsigned char c = static_cast<unsigned char>(text[i]);
    if ((c & 0xC0) != 0x80 && shown++ == kMaxQuotedChars) {
      out += "...";
      break;
    }
    if (c < 0x20 || c == 0x7F) {
      char escaped[8];
      std::snprintf(escaped, sizeof(escaped), "\\x%02X", c);
      out += escaped;
    } else {
      out += static_cast<char>(c);
    }
  }
  out += "'";
  return out;
}

std::string Shortest(double value) {
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  return std::string(buffer, result.ptr);
}

// Parses the whole of `text` as a decimal number (C locale, optional sign, optional
// exponent; "nan", "inf" and "infinity" in any case). Trailing characters are an error.
ParseResult ParseNumber(std::string_view text, double* value) {
  const char* first = text.data();
  const char* last = text.data() + text.size();
  // std::from_chars takes '-' but not '+'.
  if (first != last && *first == '+' && last - first > 1 && first[1] != '-' && first[1] != '+') {
    ++first;
  }
  const auto result = std::from_chars(first, last, *value, std::chars_format::general);
  if (result.ec == std::errc::result_out_of_range && result.ptr == last) {
    return ParseResult::kOutOfRange;
  }
  if (result.ec != std::errc() || result.ptr != last) return ParseResult::kNotANumber;
  return ParseResult::kOk;
}

bool NextDataLine(LineReader* reader, const std::string& path, std::string* line) {
  int first_blank_line = 0;
  while (reader->Next(line)) {
    if (IsBlankLine(*line)) {
      if (first_blank_line == 0) first_blank_line = reader->line_number();
      continue;
    }
    if (first_blank_line != 0) {
      throw DataError(path, first_blank_line, 1,
                      "empty line inside the data (only empty lines at the end of the file are "
                      "allowed)");
    }
    return true;
  }
  return false;
}

}  // namespace internal
}  // namespace structgp
