#ifndef SHAPEID_SERVER_STORAGE_FILE_UTIL_H_
#define SHAPEID_SERVER_STORAGE_FILE_UTIL_H_

#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"

namespace shapeid {

// POSIX file-system steps that durable stores need, as absl::Status (errors name the path and
// errno; ENOSPC/EDQUOT map to ResourceExhausted, everything else to Unavailable).

// mkdir -p, then fsyncs the parent of every directory it created, so the new entries survive
// a power cut.
absl::Status MakeDirectories(const std::string& path);
// fsync of a directory: makes renames, creations and unlinks in it durable.
absl::Status SyncDirectory(const std::string& path);
// fsync of a file's contents.
absl::Status SyncFile(const std::string& path);
// rename(2); atomic within one file system.
absl::Status RenameFile(const std::string& from, const std::string& to);
// unlink(2) that ignores a missing file.
absl::Status RemoveFileIfExists(const std::string& path);
bool FileExists(const std::string& path);
// Names (not paths) of the entries of `dir`, sorted, without "." and "..".
absl::StatusOr<std::vector<std::string>> ListDirectory(const std::string& dir);

}  // namespace shapeid

#endif  // SHAPEID_SERVER_STORAGE_FILE_UTIL_H_
