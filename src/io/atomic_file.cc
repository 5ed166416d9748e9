#include "structgp/io/atomic_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <system_error>

#include "structgp/io/data_error.h"

namespace structgp {
namespace {

// Attempts at finding an unused temporary name before giving up.
constexpr int kMaxTemporaryNameAttempts = 100;

std::string SystemReason(int error) { return std::strerror(error); }

// Removes the temporary file unless Keep() was called; closes the descriptor if still open.
class TemporaryFile {
 public:
  TemporaryFile() = default;
  TemporaryFile(const TemporaryFile&) = delete;
  TemporaryFile& operator=(const TemporaryFile&) = delete;
  ~TemporaryFile() {
    if (fd_ >= 0) ::close(fd_);
    if (!path_.empty()) ::unlink(path_.c_str());
  }

  // Creates a new file next to `target` with a name nobody else uses. Returns 0 or errno.
  int Create(const std::filesystem::path& target) {
    static std::atomic<unsigned> counter{0};
    const std::string prefix = (target.parent_path() / ("." + target.filename().string() +
                                                        ".tmp-" + std::to_string(::getpid()) +
                                                        "-")).string();
    for (int attempt = 0; attempt < kMaxTemporaryNameAttempts; ++attempt) {
      const std::string candidate = prefix + std::to_string(counter.fetch_add(1));
      // 0666 before the umask: the same permissions a new file made by any program gets.
      const int fd = ::open(candidate.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
      if (fd >= 0) {
        fd_ = fd;
        path_ = candidate;
        return 0;
      }
      if (errno != EEXIST) return errno;
    }
    return EEXIST;
  }

  // Closes the descriptor; returns 0 or errno (a late write error can show up here).
  int Close() {
    const int result = ::close(fd_);
    fd_ = -1;
    return result == 0 ? 0 : errno;
  }

  // The file now has another name: do not remove it.
  void Keep() { path_.clear(); }

  int fd() const { return fd_; }
  const std::string& path() const { return path_; }

 private:
  int fd_ = -1;
  std::string path_;
};

// Writes all of `data`, retrying after interruptions and short writes. Returns 0 or errno.
int WriteAll(int fd, const char* data, std::size_t size) {
  while (size > 0) {
    const ssize_t written = ::write(fd, data, size);
    if (written < 0) {
      if (errno == EINTR) continue;
      return errno;
    }
    data += written;
    size -= static_cast<std::size_t>(written);
  }
  return 0;
}

// Makes the rename itself durable. Failure here loses nothing that is already visible, so it
// is not reported (some file systems do not support fsync on directories).
void SyncDirectory(const std::filesystem::path& directory) {
  const int fd = ::open(directory.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return;
  ::fsync(fd);
  ::close(fd);
}

}  // namespace

void WriteTextAtomically(const std::string& path, const std::string& contents) {
  namespace fs = std::filesystem;
  if (path.empty()) throw std::invalid_argument("WriteTextAtomically: expected a path, got \"\"");
  const auto fail = [&path](const std::string& message) {
    throw DataError(path, 0, 0, "cannot write: " + message);
  };

  // A symbolic link is followed: the file it names is replaced, the link stays.
  fs::path target(path);
  std::error_code error;
  if (fs::is_symlink(fs::symlink_status(target, error))) {
    const fs::path resolved = fs::weakly_canonical(target, error);
    if (error) fail("cannot resolve the symbolic link: " + error.message());
    target = resolved;
  }
  if (target.filename().empty()) fail("the path names a directory, expected a file");
  fs::path directory = target.parent_path();
  if (directory.empty()) directory = ".";

  struct stat existing;
  const bool exists = ::stat(target.c_str(), &existing) == 0;
  if (exists && S_ISDIR(existing.st_mode)) fail("the path is a directory, expected a file");

  TemporaryFile temporary;
  if (const int code = temporary.Create(target); code != 0) {
    fail("cannot create a temporary file in '" + directory.string() + "': " + SystemReason(code));
  }
  if (exists) ::fchmod(temporary.fd(), existing.st_mode & 07777);  // Best effort.
  if (const int code = WriteAll(temporary.fd(), contents.data(), contents.size()); code != 0) {
    fail("writing the temporary file failed: " + SystemReason(code));
  }
  if (::fsync(temporary.fd()) != 0) {
    fail("flushing the temporary file to disk failed: " + SystemReason(errno));
  }
  if (const int code = temporary.Close(); code != 0) {
    fail("closing the temporary file failed: " + SystemReason(code));
  }
  if (::rename(temporary.path().c_str(), target.c_str()) != 0) {
    fail("renaming the temporary file over it failed: " + SystemReason(errno));
  }
  temporary.Keep();
  SyncDirectory(directory);
}

}  // namespace structgp
