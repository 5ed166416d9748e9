#include "structgp/internal/text.h"

#include <algorithm>
#include <charconv>
#include <cstdarg>
#include <cstdio>

namespace structgp {
namespace internal {

std::string Format(const char* format, ...) {
  va_list args;
  va_start(args, format);
  va_list copy;
  va_copy(copy, args);
  const int n = std::vsnprintf(nullptr, 0, format, copy);
  va_end(copy);
  std::string out(static_cast<size_t>(std::max(n, 0)) + 1, '\0');
  std::vsnprintf(&out[0], out.size(), format, args);
  va_end(args);
  out.resize(static_cast<size_t>(std::max(n, 0)));
  return out;
}

std::string ShortestDecimal(double value) {
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value + 0.0);
  return std::string(buffer, result.ptr);
}

std::string ListText(const std::vector<std::string>& items) {
  std::string text;
  for (size_t k = 0; k < items.size(); ++k) {
    if (k > 0) text += k + 1 == items.size() ? " and " : ", ";
    text += items[k];
  }
  return text;
}

std::string JointList(const std::vector<int>& joints) {
  std::vector<std::string> items;
  for (int j : joints) items.push_back(std::to_string(j));
  return ListText(items);
}

std::string JointsText(const std::vector<int>& joints) {
  return (joints.size() == 1 ? "joint " : "joints ") + JointList(joints);
}

std::string Table(const std::vector<std::vector<std::string>>& rows, int indent) {
  std::vector<size_t> width;
  for (const auto& row : rows) {
    if (width.size() < row.size()) width.resize(row.size(), 0);
    for (size_t c = 0; c < row.size(); ++c) width[c] = std::max(width[c], row[c].size());
  }
  std::vector<bool> numeric(width.size(), false), text(width.size(), false);
  for (size_t r = 1; r < rows.size(); ++r) {
    for (size_t c = 0; c < rows[r].size(); ++c) {
      const std::string& cell = rows[r][c];
      if (cell.empty() || cell == "-" || cell == "n/a") continue;
      const bool number = std::string("0123456789+-.").find(cell[0]) != std::string::npos;
      (number ? numeric : text)[c] = true;
    }
  }
  std::vector<bool> left(width.size());
  for (size_t c = 0; c < width.size(); ++c) left[c] = c == 0 || text[c] || !numeric[c];
  std::string out;
  for (const auto& row : rows) {
    std::string line(static_cast<size_t>(indent), ' ');
    for (size_t c = 0; c < row.size(); ++c) {
      const std::string pad(width[c] - row[c].size(), ' ');
      line += left[c] ? row[c] + pad : pad + row[c];
      if (c + 1 < row.size()) line += "  ";
    }
    while (!line.empty() && line.back() == ' ') line.pop_back();
    out += line + "\n";
  }
  return out;
}

}  // namespace internal
}  // namespace structgp
