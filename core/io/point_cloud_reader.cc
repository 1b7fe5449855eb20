#include "core/io/point_cloud_reader.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "absl/status/status.h"
#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/strings/strip.h"
#include "core/io/errno_status.h"
#include "core/io/gzip.h"
#include "core/io/las_reader.h"
#include "core/io/npy_reader.h"
#include "core/io/obj_reader.h"
#include "core/io/off_reader.h"
#include "core/io/pcd_reader.h"
#include "core/io/ply_reader.h"
#include "core/io/stl_reader.h"
#include "core/io/vtk_reader.h"
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

const std::vector<std::string>& CloudFormatNames() {
  static const auto* names = new std::vector<std::string>{"pcd", "ply", "off", "obj", "stl", "vtk",
                                                          "las", "npy", "npz", "xyz", "pts", "csv"};
  return *names;
}

absl::StatusOr<CloudFormat> CloudFormatForName(absl::string_view name) {
  std::string lower = absl::AsciiStrToLower(absl::StripPrefix(name, "."));
  // The text formats' other extensions are names too: their files read as xyz.
  if (lower == "txt" || lower == "xyzn" || lower == "xyzrgb") lower = "xyz";
  const std::vector<std::string>& names = CloudFormatNames();
  for (size_t i = 0; i < names.size(); ++i) {
    if (names[i] == lower) return static_cast<CloudFormat>(i);
  }
  return absl::InvalidArgumentError(
      absl::StrCat("unknown input format \"", name, "\"; known: ", absl::StrJoin(names, ", ")));
}

const std::string& SupportedExtensions() {
  static const auto* extensions = new std::string(
      ".pcd .ply .off .obj .stl .vtk .las .npy .npz .xyz .txt .xyzn .xyzrgb .pts .csv "
      "(any of them .gz)");
  return *extensions;
}

absl::StatusOr<CloudFormat> CloudFormatForPath(absl::string_view path) {
  const size_t slash = path.rfind('/');
  absl::string_view base = slash == absl::string_view::npos ? path : path.substr(slash + 1);
  if (base.size() > 3 && absl::EndsWithIgnoreCase(base, ".gz")) base.remove_suffix(3);
  const size_t dot = base.rfind('.');
  const std::string ext =
      dot == absl::string_view::npos ? "" : absl::AsciiStrToLower(base.substr(dot));
  if (ext == ".laz") {  // a valid format this reader does not handle, as the LAS reader says
    return absl::UnimplementedError(absl::StrCat(
        path,
        ": LAZ (compressed LAS) is not read; decompress it to LAS first, e.g. `laszip -i in.laz ",
        "-o out.las` (LAStools) or `pdal translate in.laz out.las` (PDAL)"));
  }
  if (ext.size() > 1) {
    absl::StatusOr<CloudFormat> format = CloudFormatForName(ext);
    if (format.ok()) return format;
  }
  return absl::InvalidArgumentError(absl::StrCat(
      path, ": ",
      ext.empty() ? "no file extension" : absl::StrCat("unknown extension \"", ext, "\""),
      "; supported: ", SupportedExtensions()));
}

namespace {

// Opens `path` for reading and stats it; a directory is refused.
absl::Status OpenForReading(const std::string& path, int* fd, struct stat* st) {
  do {
    *fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  } while (*fd < 0 && errno == EINTR);
  if (*fd < 0) return ErrnoStatus(path, "cannot open", errno);
  if (::fstat(*fd, st) != 0) {
    const int error = errno;
    ::close(*fd);
    return ErrnoStatus(path, "cannot stat", error);
  }
  if (S_ISDIR(st->st_mode)) {
    ::close(*fd);
    return ErrnoStatus(path, "cannot read", EISDIR);
  }
  return absl::OkStatus();
}

absl::StatusOr<std::string> ReadOpenFile(const std::string& path, int fd, const struct stat& st) {
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

// A regular file's bytes, mapped read-only and prefaulted from the page cache: no copy and no
// zero-filled buffer, which made up most of reading a binary cloud. Another process truncating
// the file while it is mapped would raise SIGBUS; the command-line tools read files that stay.
class MappedFile {
 public:
  MappedFile(const void* data, size_t size) : data_(data), size_(size) {}
  ~MappedFile() { ::munmap(const_cast<void*>(data_), size_); }
  MappedFile(const MappedFile&) = delete;
  MappedFile& operator=(const MappedFile&) = delete;

  absl::string_view view() const { return {static_cast<const char*>(data_), size_}; }

 private:
  const void* data_;
  size_t size_;
};

}  // namespace

absl::StatusOr<std::string> ReadFileContents(const std::string& path) {
  int fd = -1;
  struct stat st;
  SHAPEID_RETURN_IF_ERROR(OpenForReading(path, &fd, &st));
  FdCloser closer(fd);
  return ReadOpenFile(path, fd, st);
}

absl::StatusOr<ReadResult> ParsePointCloud(absl::string_view contents, CloudFormat format,
                                           absl::string_view name, const ReadOptions& options) {
  if (IsGzip(contents)) {
    SHAPEID_ASSIGN_OR_RETURN(const std::string inflated,
                             Gunzip(contents, name, options.max_inflated_bytes));
    if (IsGzip(inflated)) {
      return absl::InvalidArgumentError(absl::StrCat(name, ": gzip inside gzip"));
    }
    return ParsePointCloud(inflated, format, name, options);
  }
  switch (format) {
    case CloudFormat::kPcd:
      return ParsePcd(contents, name, options);
    case CloudFormat::kPly:
      return ParsePly(contents, name, options);
    case CloudFormat::kOff:
      return ParseOff(contents, name, options);
    case CloudFormat::kObj:
      return ParseObj(contents, name, options);
    case CloudFormat::kStl:
      return ParseStl(contents, name, options);
    case CloudFormat::kVtk:
      return ParseVtk(contents, name, options);
    case CloudFormat::kLas:
      return ParseLas(contents, name, options);
    case CloudFormat::kNpy:
      return ParseNpy(contents, name, options);
    case CloudFormat::kNpz:
      return ParseNpz(contents, name, options);
    case CloudFormat::kXyz:
      return ParseXyz(contents, name, TextDialect::kXyz, options);
    case CloudFormat::kPts:
      return ParseXyz(contents, name, TextDialect::kPts, options);
    case CloudFormat::kCsv:
      return ParseXyz(contents, name, TextDialect::kCsv, options);
  }
  return absl::InternalError("unreachable CloudFormat");
}

absl::StatusOr<ReadResult> ReadPointCloud(const std::string& path, const ReadOptions& options) {
  if (path == "-") {
    if (!options.input_format.has_value()) {
      return absl::InvalidArgumentError(absl::StrCat(
          "standard input (\"-\") has no extension to choose a reader by; give its format with "
          "--input-format (",
          absl::StrJoin(CloudFormatNames(), ", "), ")"));
    }
    SHAPEID_ASSIGN_OR_RETURN(const std::string contents, ReadFileContents("/dev/stdin"));
    return ParsePointCloud(contents, *options.input_format, "standard input", options);
  }
  CloudFormat format;
  if (options.input_format.has_value()) {
    format = *options.input_format;
  } else {
    SHAPEID_ASSIGN_OR_RETURN(format, CloudFormatForPath(path));
  }
  int fd = -1;
  struct stat st;
  SHAPEID_RETURN_IF_ERROR(OpenForReading(path, &fd, &st));
  FdCloser closer(fd);
  if (S_ISREG(st.st_mode) && st.st_size > 0) {
    const size_t size = static_cast<size_t>(st.st_size);
    void* mapped = ::mmap(nullptr, size, PROT_READ, MAP_PRIVATE | MAP_POPULATE, fd, 0);
    if (mapped != MAP_FAILED) {
      const MappedFile file(mapped, size);
      return ParsePointCloud(file.view(), format, path, options);
    }
  }
  // Empty files, pipes and what cannot be mapped are read.
  SHAPEID_ASSIGN_OR_RETURN(const std::string contents, ReadOpenFile(path, fd, st));
  return ParsePointCloud(contents, format, path, options);
}

}  // namespace shapeid
