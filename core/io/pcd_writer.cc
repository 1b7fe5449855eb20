#include "core/io/pcd_writer.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <cstdio>
#include <cstring>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"
#include "absl/types/span.h"
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

std::string EncodePcd(const PointCloud& cloud, PcdEncoding encoding) {
  const size_t n = cloud.size();
  const bool ascii = encoding == PcdEncoding::kAscii;
  std::string out;
  absl::StrAppend(&out, "# .PCD v0.7 - Point Cloud Data file format\n", "VERSION 0.7\n",
                  "FIELDS x y z\n", "SIZE 4 4 4\n", "TYPE F F F\n", "COUNT 1 1 1\n");
  absl::StrAppend(&out, "WIDTH ", n, "\n", "HEIGHT 1\n", "VIEWPOINT 0 0 0 1 0 0 0\n");
  absl::StrAppend(&out, "POINTS ", n, "\n", "DATA ", ascii ? "ascii" : "binary", "\n");
  const absl::Span<const float> xyz = cloud.xyz();
  if (!ascii) {
    if (!xyz.empty()) {
      out.append(reinterpret_cast<const char*>(xyz.data()), xyz.size() * sizeof(float));
    }
    return out;
  }
  // std::to_chars rather than printf: the same %.9g digits, but never a locale's decimal comma.
  out.reserve(out.size() + 3 * 16 * n);
  char buffer[32];
  for (size_t i = 0; i < xyz.size(); ++i) {
    const std::to_chars_result r =
        std::to_chars(buffer, buffer + sizeof buffer, xyz[i], std::chars_format::general, 9);
    out.append(buffer, r.ptr);
    out.push_back(i % 3 == 2 ? '\n' : ' ');
  }
  return out;
}

absl::Status WritePcd(const std::string& path, const PointCloud& cloud, PcdEncoding encoding) {
  const std::string bytes = EncodePcd(cloud, encoding);
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
