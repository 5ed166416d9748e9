#include "io/line_reader.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

#include "structgp/io/data_error.h"

namespace structgp {
namespace internal {
namespace {

// Bytes asked of zlib at a time; the buffer grows beyond this only for longer lines.
constexpr std::size_t kChunkBytes = std::size_t{1} << 16;

}  // namespace

int EditorColumn(const std::string& line, std::size_t offset) {
  if (offset > line.size()) offset = line.size();
  int column = 1;
  for (std::size_t i = 0; i < offset; ++i) {
    if ((static_cast<unsigned char>(line[i]) & 0xC0) != 0x80) ++column;
  }
  return column;
}

LineReader::LineReader(const std::string& path) : path_(path), buffer_(kChunkBytes) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) Fail(0, 0, std::string("cannot open for reading: ") + std::strerror(errno));
  struct stat info;
  if (::fstat(fd, &info) == 0 && S_ISDIR(info.st_mode)) {
    ::close(fd);
    Fail(0, 0, "is a directory, expected a CSV file");
  }
  file_ = ::gzdopen(fd, "rb");
  if (file_ == nullptr) {
    ::close(fd);
    Fail(0, 0, "cannot open for reading: out of memory");
  }
  ::gzbuffer(file_, static_cast<unsigned>(kChunkBytes));
  // zlib reads a file that is not gzip data as it is ("transparent" mode).
  compressed_ = ::gzdirect(file_) == 0;
}

LineReader::~LineReader() {
  if (file_ != nullptr) ::gzclose(file_);
}

void LineReader::Fail(int line, int column, const std::string& message) const {
  throw DataError(path_, line, column, message);
}

bool LineReader::Fill() {
  if (end_ == buffer_.size()) buffer_.resize(buffer_.size() * 2);
  const std::size_t room = std::min(buffer_.size() - end_, std::size_t{1} << 30);
  const int got = ::gzread(file_, buffer_.data() + end_, static_cast<unsigned>(room));
  if (got > 0) {
    end_ += static_cast<std::size_t>(got);
    return true;
  }
  at_end_ = true;
  int code = Z_OK;
  const char* reason = ::gzerror(file_, &code);
  if (code == Z_ERRNO) {
    pending_error_ = std::string("read error: ") + std::strerror(errno);
  } else if (code == Z_BUF_ERROR) {
    pending_error_ = "gzip data ends early at or after this line: the file is truncated";
  } else if (code != Z_OK || got < 0) {
    pending_error_ = std::string("corrupt gzip data at or after this line: ") +
                     (reason != nullptr ? reason : "unknown zlib error");
  }
  return false;
}

bool LineReader::Next(std::string* line) {
  std::size_t scanned = begin_;
  for (;;) {
    const char* data = buffer_.data();
    const void* newline = scanned < end_ ? std::memchr(data + scanned, '\n', end_ - scanned)
                                         : nullptr;
    if (newline != nullptr) {
      const std::size_t stop = static_cast<const char*>(newline) - data;
      line->assign(data + begin_, stop - begin_);
      begin_ = stop + 1;
      break;
    }
    if (at_end_) {
      // The reason for stopping early belongs to the line that was being read.
      if (!pending_error_.empty()) Fail(line_number_ + 1, 0, pending_error_);
      if (begin_ == end_) return false;
      line->assign(data + begin_, end_ - begin_);  // Last line without a terminator.
      begin_ = end_;
      break;
    }
    if (end_ - begin_ > kMaxLineBytes) {
      Fail(line_number_ + 1, 0, "line longer than 16 MiB: this does not look like CSV text");
    }
    // Move the unfinished line to the front before reading more.
    if (begin_ > 0) {
      std::memmove(buffer_.data(), data + begin_, end_ - begin_);
      end_ -= begin_;
      begin_ = 0;
    }
    scanned = end_;
    Fill();
  }
  ++line_number_;
  if (!line->empty() && line->back() == '\r') line->pop_back();
  if (line_number_ == 1 && line->compare(0, 3, "\xEF\xBB\xBF") == 0) line->erase(0, 3);
  const std::size_t nul = line->find('\0');
  if (nul != std::string::npos) {
    Fail(line_number_, EditorColumn(*line, nul),
         "NUL byte: this looks like a binary file, not CSV text");
  }
  return true;
}

}  // namespace internal
}  // namespace structgp
