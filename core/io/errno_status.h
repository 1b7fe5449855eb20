#ifndef SHAPEID_CORE_IO_ERRNO_STATUS_H_
#define SHAPEID_CORE_IO_ERRNO_STATUS_H_

// Internal to core/io: one mapping of a failed system call on a file to an absl::Status,
// shared by the readers and the writers.

#include <cerrno>
#include <cstring>
#include <string>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"

namespace shapeid {

// "<path>: <what>: <strerror>", with the code a caller can act on: NotFound for a missing
// file or directory, PermissionDenied (also a read-only file system), InvalidArgument for a
// directory where a file was expected, Unknown otherwise.
inline absl::Status ErrnoStatus(const std::string& path, absl::string_view what, int err) {
  const std::string message = absl::StrCat(path, ": ", what, ": ", std::strerror(err));
  switch (err) {
    case ENOENT:
    case ENOTDIR:
      return absl::NotFoundError(message);
    case EACCES:
    case EPERM:
    case EROFS:
      return absl::PermissionDeniedError(message);
    case EISDIR:
      return absl::InvalidArgumentError(message);
    default:
      return absl::UnknownError(message);
  }
}

}  // namespace shapeid

#endif  // SHAPEID_CORE_IO_ERRNO_STATUS_H_
