#include "structgp/io/data_error.h"

#include <utility>

namespace structgp {
namespace {

std::string Located(const std::string& file, int line, int column, const std::string& message) {
  std::string out = file;
  if (line > 0) {
    out += ':' + std::to_string(line);
    if (column > 0) out += ':' + std::to_string(column);
  }
  out += ": ";
  out += message;
  return out;
}

}  // namespace

DataError::DataError(std::string file, int line, int column, std::string message)
    : std::runtime_error(Located(file, line, column, message)),
      file_(std::move(file)),
      line_(line > 0 ? line : 0),
      column_(line > 0 && column > 0 ? column : 0),
      message_(std::move(message)) {}

}  // namespace structgp
