#include "server/storage/file_util.h"

#include <dirent.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

#include "absl/strings/str_cat.h"

namespace shapeid {

namespace {

// Unlike core/io's ErrnoStatus (a client's own file: NotFound, PermissionDenied), a store
// failure is the server's condition, not the caller's fault: the client sees UNAVAILABLE
// (retry elsewhere or later) or RESOURCE_EXHAUSTED (disk full).
absl::Status StoreErrno(const std::string& path, absl::string_view what, int err) {
  const std::string message = absl::StrCat(what, " ", path, ": ", std::strerror(err));
  if (err == ENOSPC || err == EDQUOT) {
    return absl::ResourceExhaustedError(absl::StrCat(message, " (the disk is full)"));
  }
  return absl::UnavailableError(message);
}

std::string Parent(const std::string& path) {
  const size_t slash = path.find_last_of('/');
  if (slash == std::string::npos) return ".";
  if (slash == 0) return "/";
  return path.substr(0, slash);
}

absl::Status SyncPath(const std::string& path, int flags, absl::string_view what) {
  const int fd = open(path.c_str(), flags | O_CLOEXEC);
  if (fd < 0) return StoreErrno(path, absl::StrCat("cannot open (to sync) ", what), errno);
  const int rc = fsync(fd);
  const int err = errno;
  close(fd);
  if (rc != 0) return StoreErrno(path, absl::StrCat("cannot fsync ", what), err);
  return absl::OkStatus();
}

}  // namespace

absl::Status MakeDirectories(const std::string& path) {
  if (path.empty()) return absl::InvalidArgumentError("empty directory path");
  struct stat st;
  if (stat(path.c_str(), &st) == 0) {
    if (S_ISDIR(st.st_mode)) return absl::OkStatus();
    return absl::UnavailableError(absl::StrCat(path, " exists and is not a directory"));
  }
  const std::string parent = Parent(path);
  if (parent != path) {
    if (absl::Status s = MakeDirectories(parent); !s.ok()) return s;
  }
  if (mkdir(path.c_str(), 0755) != 0 && errno != EEXIST) {
    return StoreErrno(path, "cannot create directory", errno);
  }
  return SyncDirectory(parent);
}

absl::Status SyncDirectory(const std::string& path) {
  return SyncPath(path, O_RDONLY | O_DIRECTORY, "directory");
}

absl::Status SyncFile(const std::string& path) { return SyncPath(path, O_RDONLY, "file"); }

absl::Status RenameFile(const std::string& from, const std::string& to) {
  if (rename(from.c_str(), to.c_str()) != 0) {
    return StoreErrno(from, absl::StrCat("cannot rename to ", to, ":"), errno);
  }
  return absl::OkStatus();
}

absl::Status RemoveFileIfExists(const std::string& path) {
  if (unlink(path.c_str()) != 0 && errno != ENOENT) {
    return StoreErrno(path, "cannot remove", errno);
  }
  return absl::OkStatus();
}

bool FileExists(const std::string& path) {
  struct stat st;
  return stat(path.c_str(), &st) == 0;
}

absl::StatusOr<std::vector<std::string>> ListDirectory(const std::string& dir) {
  DIR* d = opendir(dir.c_str());
  if (d == nullptr) return StoreErrno(dir, "cannot list directory", errno);
  std::vector<std::string> names;
  errno = 0;
  while (const dirent* entry = readdir(d)) {
    const std::string name = entry->d_name;
    if (name != "." && name != "..") names.push_back(name);
  }
  const int err = errno;
  closedir(d);
  if (err != 0) return StoreErrno(dir, "cannot list directory", err);
  std::sort(names.begin(), names.end());
  return names;
}

}  // namespace shapeid
