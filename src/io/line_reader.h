#ifndef STRUCTGP_SRC_IO_LINE_READER_H_
#define STRUCTGP_SRC_IO_LINE_READER_H_

// Reads a text file line by line, decompressing it on the fly when it is gzip data. Private to
// the library: zlib does not appear in the public headers.

#include <algorithm>
#include <cstddef>
#include <string>
#include <vector>

#include <zlib.h>

namespace structgp {
namespace internal {

// Longest line accepted [bytes]. A CSV line of robot data is a few kilobytes; a longer one
// almost always means the file is not line-oriented text (a binary file given by mistake).
constexpr std::size_t kMaxLineBytes = std::size_t{16} << 20;

// The 1-based editor column of byte `offset` in `line`: UTF-8 continuation bytes do not count.
int EditorColumn(const std::string& line, std::size_t offset);

class LineReader {
 public:
  // Opens `path`; throws DataError naming the path and the system's reason when it cannot.
  explicit LineReader(const std::string& path);
  ~LineReader();
  LineReader(const LineReader&) = delete;
  LineReader& operator=(const LineReader&) = delete;

  // Reads the next line into `line`, without its "\n" or "\r\n" terminator (and without a
  // UTF-8 byte order mark on line 1). Returns false at the end of the file. Throws DataError
  // on a read error, corrupt or truncated gzip data, a NUL byte or an overlong line.
  bool Next(std::string* line);

  // 1-based number of the line last returned by Next (0 before the first call).
  int line_number() const { return line_number_; }
  // True when the file is gzip-compressed.
  bool compressed() const { return compressed_; }

 private:
  // Reads more bytes into the buffer; false at the end of the file.
  bool Fill();
  [[noreturn]] void Fail(int line, int column, const std::string& message) const;

  std::string path_;
  gzFile file_ = nullptr;
  bool compressed_ = false;
  bool at_end_ = false;
  std::string pending_error_;  // Why reading stopped early, reported when its line is read.
  std::vector<char> buffer_;
  std::size_t begin_ = 0;  // First unread byte in buffer_.
  std::size_t end_ = 0;    // One past the last valid byte in buffer_.
  int line_number_ = 0;
};

}  // namespace internal
}  // namespace structgp

#endif  // STRUCTGP_SRC_IO_LINE_READER_H_
