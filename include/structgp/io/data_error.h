#ifndef STRUCTGP_IO_DATA_ERROR_H_
#define STRUCTGP_IO_DATA_ERROR_H_

/// @file
/// The exception thrown when a user's file cannot be read or written: it names the file and,
/// when they apply, the line and column where the problem is.

#include <stdexcept>
#include <string>

namespace structgp {

/// Something is wrong with a file at the boundary of the library: a CSV cell that is not a
/// number, a missing column, a file that cannot be opened or written.
///
/// what() reads like a compiler diagnostic, so that a program can print it as it is and an
/// editor can jump to the place:
///
///     FILE:LINE:COLUMN: message     (line and column known)
///     FILE:LINE: message            (column is 0: the whole line is concerned)
///     FILE: message                 (line is 0: the whole file is concerned)
///
/// Lines and columns are 1-based and count as an editor shows them: the column counts
/// characters (UTF-8 code points) from the start of the line, a tab counting as one.
class DataError : public std::runtime_error {
 public:
  /// `line` and `column` are 1-based; 0 means "not applicable".
  DataError(std::string file, int line, int column, std::string message);

  /// The path of the file as given by the caller.
  const std::string& file() const { return file_; }
  /// 1-based line, 0 when the error concerns the whole file.
  int line() const { return line_; }
  /// 1-based character column, 0 when the error concerns the whole line or file.
  int column() const { return column_; }
  /// The message without the "FILE:LINE:COLUMN: " prefix.
  const std::string& message() const { return message_; }

 private:
  std::string file_;
  int line_;
  int column_;
  std::string message_;
};

}  // namespace structgp

#endif  // STRUCTGP_IO_DATA_ERROR_H_
