#include "core/io/point_cloud_reader.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "absl/status/status.h"
#include "absl/strings/ascii.h"
#include "absl/strings/str_cat.h"
#include "core/io/errno_status.h"
#include "core/io/obj_reader.h"
#include "core/io/off_reader.h"
#include "core/io/pcd_reader.h"
#include "core/io/ply_reader.h"
#include "core/io/xyz_reader.h"
#include "core/status_macros.h"

namespace shapeid {
namespace {

// Closes a file descriptor on every path out of ReadFileContents.
class FdCloser {
 public:
  explicit FdCloser(int fd) : fd_(fd) {}
  ~FdCloser() { ::close(fd_); }
  FdCloser(const FdCloser&) = delete;
  FdCloser& operator=(const FdCloser&) = delete;

 private:
  int fd_;
};

}  // namespace

absl::StatusOr<CloudFormat> CloudFormatForPath(absl::string_view path) {
  const size_t slash = path.rfind('/');
  const absl::string_view base = slash == absl::string_view::npos ? path : path.substr(slash + 1);
  const size_t dot = base.rfind('.');
  const std::string ext =
      dot == absl::string_view::npos ? "" : absl::AsciiStrToLower(base.substr(dot));
  if (ext == ".pcd") return CloudFormat::kPcd;
  if (ext == ".ply") return CloudFormat::kPly;
  if (ext == ".off") return CloudFormat::kOff;
  if (ext == ".obj") return CloudFormat::kObj;
  if (ext == ".xyz" || ext == ".txt") return CloudFormat::kXyz;
  if (ext == ".csv") return CloudFormat::kCsv;
  return absl::InvalidArgumentError(absl::StrCat(
      path, ": ",
      ext.empty() ? "no file extension" : absl::StrCat("unknown extension \"", ext, "\""),
      "; supported: .pcd, .ply, .off, .obj, .xyz, .txt, .csv"));
}

absl::StatusOr<std::string> ReadFileContents(const std::string& path) {
  int fd;
  do {
    fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  } while (fd < 0 && errno == EINTR);
  if (fd < 0) return ErrnoStatus(path, "cannot open", errno);
  FdCloser closer(fd);
  struct stat st;
  if (::fstat(fd, &st) != 0) return ErrnoStatus(path, "cannot stat", errno);
  if (S_ISDIR(st.st_mode)) return ErrnoStatus(path, "cannot read", EISDIR);

  // The size is a hint: a file that grows or is not regular (a pipe) is read to its end
  // through `probe`, which also confirms the end of a regular file without a larger buffer.
  std::string contents(S_ISREG(st.st_mode) ? static_cast<size_t>(st.st_size) : 0, '\0');
  size_t used = 0;
  char probe[4096];
  while (true) {
    const bool in_place = used < contents.size();
    char* dst = in_place ? &contents[used] : probe;
    const size_t room = in_place ? contents.size() - used : sizeof probe;
    const ssize_t got = ::read(fd, dst, room);
    if (got < 0) {
      if (errno == EINTR) continue;
      return ErrnoStatus(path, "cannot read", errno);
    }
    if (got == 0) break;
    if (in_place) {
      used += static_cast<size_t>(got);
    } else {
      contents.resize(used);
      contents.append(probe, static_cast<size_t>(got));
      used = contents.size();
    }
  }
  contents.resize(used);
  return contents;
}

absl::StatusOr<ReadResult> ParsePointCloud(absl::string_view contents, CloudFormat format,
                                           absl::string_view name, const ReadOptions& options) {
  switch (format) {
    case CloudFormat::kPcd:
      return ParsePcd(contents, name, options);
    case CloudFormat::kPly:
      return ParsePly(contents, name, options);
    case CloudFormat::kOff:
      return ParseOff(contents, name, options);
    case CloudFormat::kObj:
      return ParseObj(contents, name, options);
    case CloudFormat::kXyz:
      return ParseXyz(contents, name, TextDialect::kXyz, options);
    case CloudFormat::kCsv:
      return ParseXyz(contents, name, TextDialect::kCsv, options);
  }
  return absl::InternalError("unreachable CloudFormat");
}

absl::StatusOr<ReadResult> ReadPointCloud(const std::string& path, const ReadOptions& options) {
  SHAPEID_ASSIGN_OR_RETURN(const CloudFormat format, CloudFormatForPath(path));
  SHAPEID_ASSIGN_OR_RETURN(const std::string contents, ReadFileContents(path));
  return ParsePointCloud(contents, format, path, options);
}

}  // namespace shapeid
