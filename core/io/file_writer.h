#ifndef SHAPEID_CORE_IO_FILE_WRITER_H_
#define SHAPEID_CORE_IO_FILE_WRITER_H_

#include <string>

#include "absl/status/status.h"
#include "absl/strings/string_view.h"

namespace shapeid {

// Writes `bytes` to `path`, replacing any file there. The bytes go to `path` + ".tmp", which
// is flushed with fsync and then renamed over `path`, so a crash or a full disk never leaves
// a half-written `path` (at worst a stale .tmp beside it). Errors name the path and the
// system's reason (core/io/errno_status.h): NotFound for a missing directory,
// PermissionDenied, and Unknown for others (e.g. ENOSPC). Thread-safe, but two writers of
// one path race.
absl::Status WriteFileAtomically(const std::string& path, absl::string_view bytes);

}  // namespace shapeid

#endif  // SHAPEID_CORE_IO_FILE_WRITER_H_
