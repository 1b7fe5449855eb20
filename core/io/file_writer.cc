#include "core/io/file_writer.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>

#include "absl/strings/str_cat.h"
#include "core/io/errno_status.h"

namespace shapeid {
namespace {

// Writes all of `bytes`, resuming after signals and short writes; false with errno set.
bool WriteAll(int fd, absl::string_view bytes) {
  while (!bytes.empty()) {
    const ssize_t wrote = ::write(fd, bytes.data(), bytes.size());
    if (wrote < 0) {
      if (errno == EINTR) continue;
      return false;
    }
    bytes.remove_prefix(static_cast<size_t>(wrote));
  }
  return true;
}

}  // namespace

absl::Status WriteFileAtomically(const std::string& path, absl::string_view bytes) {
  const std::string tmp = path + ".tmp";
  int fd;
  do {
    fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
  } while (fd < 0 && errno == EINTR);
  if (fd < 0) return ErrnoStatus(path, absl::StrCat("cannot create ", tmp), errno);

  // fsync before rename: otherwise a crash soon after could leave `path` renamed but empty.
  absl::Status status;
  if (!WriteAll(fd, bytes)) {
    status = ErrnoStatus(path, absl::StrCat("cannot write ", tmp), errno);
  } else if (::fsync(fd) != 0) {
    status = ErrnoStatus(path, absl::StrCat("cannot flush ", tmp), errno);
  }
  if (::close(fd) != 0 && status.ok()) {
    status = ErrnoStatus(path, absl::StrCat("cannot close ", tmp), errno);
  }
  if (status.ok() && std::rename(tmp.c_str(), path.c_str()) != 0) {
    status = ErrnoStatus(path, absl::StrCat("cannot rename ", tmp, " to it"), errno);
  }
  if (!status.ok()) ::unlink(tmp.c_str());
  return status;
}

}  // namespace shapeid
