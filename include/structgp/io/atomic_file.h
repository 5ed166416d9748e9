#ifndef STRUCTGP_IO_ATOMIC_FILE_H_
#define STRUCTGP_IO_ATOMIC_FILE_H_

/// @file
/// Writing a file so that readers see either the old contents or the new, never a part.

#include <string>

namespace structgp {

/// Replaces the file at `path` with `contents`, atomically.
///
/// The bytes go to a new temporary file in the same directory (named
/// ".<name>.tmp-<pid>-<n>"), which is flushed to disk (fsync) and then renamed over `path`.
/// A reader, or a crash, therefore sees the old file or the complete new one. When `path`
/// already exists its permission bits are kept; a symbolic link is followed and the file it
/// points to is replaced.
///
/// On any failure (directory missing or not writable, `path` is a directory, disk full,
/// file size limit) the file at `path` is left untouched, the temporary file is removed, and
/// DataError is thrown with `path` as its file and the system's reason in its message.
/// Throws std::invalid_argument when `path` is empty.
void WriteTextAtomically(const std::string& path, const std::string& contents);

}  // namespace structgp

#endif  // STRUCTGP_IO_ATOMIC_FILE_H_
