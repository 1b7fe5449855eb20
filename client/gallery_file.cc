#include "client/gallery_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <filesystem>
#include <utility>

#include "absl/strings/str_cat.h"
#include "core/io/errno_status.h"
#include "google/protobuf/io/coded_stream.h"
#include "google/protobuf/io/zero_copy_stream_impl.h"
#include "google/protobuf/util/delimited_message_util.h"

namespace shapeid {
namespace {

constexpr char kStdio[] = "-";

std::string DisplayName(const std::string& path) { return path == kStdio ? "stdin" : path; }

// fsync of a directory, so that a rename in it survives a power cut.
absl::Status SyncDirectory(const std::string& dir) {
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return ErrnoStatus(dir, "cannot open the directory", errno);
  const int synced = ::fsync(fd);
  const int err = errno;
  ::close(fd);
  if (synced != 0) return ErrnoStatus(dir, "cannot sync the directory", err);
  return absl::OkStatus();
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Writer

absl::StatusOr<std::unique_ptr<GalleryFileWriter>> GalleryFileWriter::Open(
    const std::string& path) {
  std::unique_ptr<GalleryFileWriter> writer;
  if (path == kStdio) {
    writer.reset(new GalleryFileWriter(path, "", STDOUT_FILENO));
  } else {
    const std::filesystem::path target(path);
    if (!target.has_filename()) {
      return absl::InvalidArgumentError(absl::StrCat(path, ": names a directory, not a file"));
    }
    const std::filesystem::path dir = target.has_parent_path() ? target.parent_path() : ".";
    // Unique among processes (pid) and among writers of one process (counter); O_EXCL makes
    // sure we never write into someone else's file.
    static std::atomic<uint64_t> counter{0};
    const std::string temp = (dir / absl::StrCat(".", target.filename().string(), ".tmp-",
                                                 ::getpid(), "-", counter.fetch_add(1)))
                                 .string();
    // 0666 minus the umask, like any file the user creates.
    const int fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    if (fd < 0) return ErrnoStatus(path, "cannot create", errno);
    writer.reset(new GalleryFileWriter(path, temp, fd));
  }
  const auto& magic = kGalleryFileMagic;
  void* data;
  int size;
  // The stream's first buffer is far larger than 8 bytes.
  if (!writer->stream_->Next(&data, &size) || size < static_cast<int>(magic.size())) {
    return writer->Fail(ErrnoStatus(path, "cannot write", writer->stream_->GetErrno()));
  }
  std::copy(magic.begin(), magic.end(), static_cast<char*>(data));
  writer->stream_->BackUp(size - static_cast<int>(magic.size()));
  writer->bytes_ = magic.size();
  return writer;
}

GalleryFileWriter::GalleryFileWriter(std::string path, std::string temp_path, int fd)
    : path_(std::move(path)),
      temp_path_(std::move(temp_path)),
      fd_(fd),
      stream_(std::make_unique<google::protobuf::io::FileOutputStream>(fd)) {}

GalleryFileWriter::~GalleryFileWriter() {
  stream_.reset();                 // flushes into the file descriptor, which must still be open
  if (temp_path_.empty()) return;  // stdout: not ours to close
  if (fd_ >= 0) ::close(fd_);
  if (!committed_) ::unlink(temp_path_.c_str());
}

absl::Status GalleryFileWriter::Fail(absl::Status status) {
  error_ = status;
  return status;
}

absl::Status GalleryFileWriter::Write(const v1::GalleryExportChunk& chunk) {
  if (!error_.ok()) return error_;
  if (committed_) return absl::FailedPreconditionError(absl::StrCat(path_, ": already committed"));
  const size_t size = chunk.ByteSizeLong();
  if (size > kMaxGalleryFileChunkBytes) {
    return Fail(absl::ResourceExhaustedError(
        absl::StrCat(path_, ": a chunk of ", size, " bytes, more than a gallery file holds (",
                     kMaxGalleryFileChunkBytes, ")")));
  }
  if (!google::protobuf::util::SerializeDelimitedToZeroCopyStream(chunk, stream_.get())) {
    return Fail(ErrnoStatus(path_, "cannot write", stream_->GetErrno()));
  }
  bytes_ += google::protobuf::io::CodedOutputStream::VarintSize64(size) + size;
  return absl::OkStatus();
}

absl::Status GalleryFileWriter::Commit() {
  if (!error_.ok()) return error_;
  if (committed_) return absl::FailedPreconditionError(absl::StrCat(path_, ": already committed"));
  if (!stream_->Flush()) return Fail(ErrnoStatus(path_, "cannot write", stream_->GetErrno()));
  if (temp_path_.empty()) {
    committed_ = true;
    return absl::OkStatus();
  }
  // Data first, then the name: a crash leaves either the old file or the whole new one.
  if (::fsync(fd_) != 0) return Fail(ErrnoStatus(path_, "cannot sync", errno));
  const int closed = ::close(fd_);
  fd_ = -1;
  if (closed != 0) return Fail(ErrnoStatus(path_, "cannot close", errno));
  if (::rename(temp_path_.c_str(), path_.c_str()) != 0) {
    return Fail(ErrnoStatus(path_, "cannot replace", errno));
  }
  committed_ = true;
  const std::filesystem::path target(path_);
  return SyncDirectory(target.has_parent_path() ? target.parent_path().string() : ".");
}

// ---------------------------------------------------------------------------------------------
// Reader

absl::StatusOr<std::unique_ptr<GalleryFileReader>> GalleryFileReader::Open(
    const std::string& path) {
  int fd = STDIN_FILENO;
  if (path != kStdio) {
    fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) return ErrnoStatus(path, "cannot open", errno);
  }
  std::unique_ptr<GalleryFileReader> reader(new GalleryFileReader(path, fd));
  char magic[8];
  static_assert(sizeof magic == kGalleryFileMagic.size());
  bool read;
  {
    google::protobuf::io::CodedInputStream coded(reader->stream_.get());
    read = coded.ReadRaw(magic, sizeof magic);
  }
  if (reader->stream_->GetErrno() != 0) {
    return ErrnoStatus(DisplayName(path), "cannot read", reader->stream_->GetErrno());
  }
  if (!read || absl::string_view(magic, sizeof magic) != kGalleryFileMagic) {
    return absl::InvalidArgumentError(
        absl::StrCat(DisplayName(path), " is not a shapeid gallery export (bad magic)"));
  }
  reader->bytes_ = sizeof magic;
  return reader;
}

GalleryFileReader::GalleryFileReader(std::string path, int fd)
    : path_(std::move(path)),
      fd_(fd),
      stream_(std::make_unique<google::protobuf::io::FileInputStream>(fd)) {}

GalleryFileReader::~GalleryFileReader() {
  stream_.reset();
  if (fd_ != STDIN_FILENO) ::close(fd_);
}

absl::StatusOr<bool> GalleryFileReader::Next(v1::GalleryExportChunk* chunk) {
  const std::string name = DisplayName(path_);
  // One CodedInputStream per chunk: its byte limit is per stream, and a gallery file may be
  // larger than 2 GiB. Its destructor hands unread bytes back to stream_.
  google::protobuf::io::CodedInputStream coded(stream_.get());
  uint32_t size = 0;
  if (!coded.ReadVarint32(&size)) {
    if (stream_->GetErrno() != 0) return ErrnoStatus(name, "cannot read", stream_->GetErrno());
    if (coded.CurrentPosition() == 0) return false;  // the end, between two chunks
    return absl::DataLossError(absl::StrCat(name,
                                            " is truncated: it ends inside the length of "
                                            "chunk ",
                                            chunks_, " (a copy cut short?)"));
  }
  if (size > kMaxGalleryFileChunkBytes) {
    return absl::DataLossError(
        absl::StrCat(name, " is damaged: chunk ", chunks_, " at byte ", bytes_, " claims ", size,
                     " bytes, more than any export writes (", kMaxGalleryFileChunkBytes, ")"));
  }
  std::string bytes;
  if (!coded.ReadString(&bytes, static_cast<int>(size))) {
    if (stream_->GetErrno() != 0) return ErrnoStatus(name, "cannot read", stream_->GetErrno());
    return absl::DataLossError(absl::StrCat(name, " is truncated: it ends inside chunk ", chunks_,
                                            " of ", size, " bytes (a copy cut short?)"));
  }
  if (!chunk->ParseFromString(bytes)) {
    return absl::DataLossError(absl::StrCat(name, " is damaged: chunk ", chunks_, " at byte ",
                                            bytes_, " is not a GalleryExportChunk"));
  }
  bytes_ += static_cast<uint64_t>(coded.CurrentPosition());
  ++chunks_;
  return true;
}

}  // namespace shapeid
