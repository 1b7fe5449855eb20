#include "core/io/point_cloud_reader.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <optional>

#include "absl/status/status.h"
#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/strings/strip.h"
#include "core/io/errno_status.h"
#include "core/io/gzip.h"
#include "core/io/reader_registry.h"
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
  static const auto* names = [] {
    auto* all = new std::vector<std::string>;
    for (const CloudReaderKind& reader : RegisteredReaders()) all->push_back(reader.name);
    return all;
  }();
  return *names;
}

namespace {

// The format one of whose extensions is `lower` (".txt"), or nullptr.
const CloudReaderKind* ReaderForExtension(absl::string_view lower) {
  for (const CloudReaderKind& reader : RegisteredReaders()) {
    for (const std::string& extension : reader.extensions) {
      if (extension == lower) return &reader;
    }
  }
  return nullptr;
}

}  // namespace

absl::StatusOr<CloudFormat> CloudFormatForName(absl::string_view name) {
  // A name is a format's name or any of its extensions without the dot ("txt" reads as xyz).
  const std::string lower = absl::StrCat(".", absl::AsciiStrToLower(absl::StripPrefix(name, ".")));
  if (const CloudReaderKind* reader = ReaderForExtension(lower); reader != nullptr) {
    return reader->format;
  }
  return absl::InvalidArgumentError(absl::StrCat(
      "unknown input format \"", name, "\"; known: ", absl::StrJoin(CloudFormatNames(), ", ")));
}

const std::string& SupportedExtensions() {
  static const auto* extensions = [] {
    std::vector<absl::string_view> all;
    for (const CloudReaderKind& reader : RegisteredReaders()) {
      all.insert(all.end(), reader.extensions.begin(), reader.extensions.end());
    }
    return new std::string(absl::StrCat(absl::StrJoin(all, " "), " (any of them .gz)"));
  }();
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
  if (const CloudReaderKind* reader = ReaderForExtension(ext); reader != nullptr) {
    return reader->format;
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

namespace {

// `contents`, or their inflated bytes (held in `*inflated`) when they are gzipped; gzip inside
// gzip is refused.
absl::StatusOr<absl::string_view> Inflated(absl::string_view contents, absl::string_view name,
                                           const ReadOptions& options, std::string* inflated) {
  if (!IsGzip(contents)) return contents;
  SHAPEID_ASSIGN_OR_RETURN(*inflated, Gunzip(contents, name, options.max_inflated_bytes));
  if (IsGzip(*inflated))
    return absl::InvalidArgumentError(absl::StrCat(name, ": gzip inside gzip"));
  return absl::string_view(*inflated);
}

}  // namespace

absl::StatusOr<ReadResult> ParsePointCloud(absl::string_view contents, CloudFormat format,
                                           absl::string_view name, const ReadOptions& options) {
  std::string inflated;
  SHAPEID_ASSIGN_OR_RETURN(const absl::string_view plain,
                           Inflated(contents, name, options, &inflated));
  return ReaderFor(format).parse(plain, name, options);
}

namespace {

// A file whose name named no format: read by its signature (looking through gzip), else
// `unnamed` (why the name did not do) with the signatures that were looked for.
absl::StatusOr<ReadResult> ParseBySignature(absl::string_view contents, absl::string_view name,
                                            const absl::Status& unnamed,
                                            const ReadOptions& options) {
  std::string inflated;
  SHAPEID_ASSIGN_OR_RETURN(const absl::string_view plain,
                           Inflated(contents, name, options, &inflated));
  const std::optional<CloudFormat> format = CloudFormatBySignature(plain);
  if (!format.has_value()) {
    return absl::Status(unnamed.code(), absl::StrCat(unnamed.message(),
                                                     "; nor do its first bytes carry the "
                                                     "signature of a format that has one (",
                                                     FormatsWithSignatures(), ")"));
  }
  return ReaderFor(*format).parse(plain, name, options);
}

}  // namespace

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
  // The format: --input-format, else the extension, else (a missing or unknown extension)
  // the contents' signature.
  std::optional<CloudFormat> format = options.input_format;
  absl::Status unnamed;
  if (!format.has_value()) {
    absl::StatusOr<CloudFormat> by_name = CloudFormatForPath(path);
    if (by_name.ok()) {
      format = *by_name;
    } else if (absl::IsInvalidArgument(by_name.status())) {
      unnamed = by_name.status();
    } else {
      return by_name.status();  // .laz: a known format this reader does not handle
    }
  }
  const auto parse = [&](absl::string_view contents) {
    return format.has_value() ? ParsePointCloud(contents, *format, path, options)
                              : ParseBySignature(contents, path, unnamed, options);
  };
  int fd = -1;
  struct stat st;
  SHAPEID_RETURN_IF_ERROR(OpenForReading(path, &fd, &st));
  FdCloser closer(fd);
  if (S_ISREG(st.st_mode) && st.st_size > 0) {
    const size_t size = static_cast<size_t>(st.st_size);
    void* mapped = ::mmap(nullptr, size, PROT_READ, MAP_PRIVATE | MAP_POPULATE, fd, 0);
    if (mapped != MAP_FAILED) {
      const MappedFile file(mapped, size);
      return parse(file.view());
    }
  }
  // Empty files, pipes and what cannot be mapped are read.
  SHAPEID_ASSIGN_OR_RETURN(const std::string contents, ReadOpenFile(path, fd, st));
  return parse(contents);
}

}  // namespace shapeid
