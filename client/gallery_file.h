#ifndef SHAPEID_CLIENT_GALLERY_FILE_H_
#define SHAPEID_CLIENT_GALLERY_FILE_H_

// The portable gallery file of `shapeid gallery export` / `import`: the 8 bytes "SHAPEIDG",
// then each GalleryExportChunk of an export (proto/shapeid/v1/shapeid.proto), in order, each
// preceded by its length as a varint (protobuf's delimited format, readable by any protobuf
// library). This file only frames the chunks; the server checks their content (order,
// counts, checksum) on import.
//
//   auto writer = shapeid::GalleryFileWriter::Open("parts.shapeid");
//   absl::Status s = client->ExportGallery("parts", [&](const auto& chunk) {
//     return (*writer)->Write(chunk);
//   });
//   if (s.ok()) s = (*writer)->Commit();   // else the file is left as it was
//
//   auto reader = shapeid::GalleryFileReader::Open("parts.shapeid");
//   auto gallery = client->ImportGallery(
//       [&](shapeid::v1::GalleryExportChunk* chunk) { return (*reader)->Next(chunk); });

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "shapeid/v1/shapeid.pb.h"

namespace google::protobuf::io {
class FileInputStream;
class FileOutputStream;
}  // namespace google::protobuf::io

namespace shapeid {

inline constexpr absl::string_view kGalleryFileMagic = "SHAPEIDG";

// Largest chunk a gallery file may hold. Exports cut chunks of about 1 MiB; the cap only
// stops a damaged length prefix from making a reader allocate gigabytes.
inline constexpr size_t kMaxGalleryFileChunkBytes = size_t{64} << 20;

// Writes a gallery file so that `path` only ever holds a complete file: the chunks go to a
// temporary file beside it, which Commit flushes, fsyncs and renames over `path` (then
// fsyncs the directory, so the rename survives a power cut). Without Commit, the destructor
// removes the temporary file and `path` keeps whatever it held. "-" writes to stdout
// directly (no temporary file; Commit flushes). Not thread-safe.
class GalleryFileWriter {
 public:
  // Creates the temporary file. Errors name the path: NotFound (no such directory),
  // PermissionDenied, InvalidArgument, Unknown (errno's message).
  static absl::StatusOr<std::unique_ptr<GalleryFileWriter>> Open(const std::string& path);

  GalleryFileWriter(const GalleryFileWriter&) = delete;
  GalleryFileWriter& operator=(const GalleryFileWriter&) = delete;
  ~GalleryFileWriter();

  // Appends one chunk. ResourceExhausted for a chunk over kMaxGalleryFileChunkBytes (it
  // could not be read back); the write error, naming the path, for a full disk. After an
  // error every call returns that error; after Commit, FailedPrecondition.
  absl::Status Write(const v1::GalleryExportChunk& chunk);

  // Makes the file durable under its final name (see the class comment). Call once. An
  // error before the rename leaves `path` as it was.
  absl::Status Commit();

  // Bytes written so far, the magic included.
  uint64_t bytes_written() const { return bytes_; }
  const std::string& path() const { return path_; }

 private:
  GalleryFileWriter(std::string path, std::string temp_path, int fd);
  absl::Status Fail(absl::Status status);

  const std::string path_;
  const std::string temp_path_;  // empty for stdout
  int fd_;
  std::unique_ptr<google::protobuf::io::FileOutputStream> stream_;
  uint64_t bytes_ = 0;
  bool committed_ = false;
  absl::Status error_;  // the first error; every later call returns it
};

// Reads the chunks of a gallery file in order. "-" reads stdin. Not thread-safe.
class GalleryFileReader {
 public:
  // Opens `path` and checks the magic: InvalidArgument "<path> is not a shapeid gallery
  // export (bad magic)" for any other file (an empty one included); open errors as in
  // GalleryFileWriter::Open.
  static absl::StatusOr<std::unique_ptr<GalleryFileReader>> Open(const std::string& path);

  GalleryFileReader(const GalleryFileReader&) = delete;
  GalleryFileReader& operator=(const GalleryFileReader&) = delete;
  ~GalleryFileReader();

  // Replaces `*chunk` with the next chunk and returns true, or returns false at the end of
  // the file. DataLoss, naming the path and the chunk, when the file ends inside a chunk
  // (a truncated copy), a chunk does not parse, or a length is over
  // kMaxGalleryFileChunkBytes; read errors as the system reports them.
  absl::StatusOr<bool> Next(v1::GalleryExportChunk* chunk);

  // Bytes consumed so far, the magic included.
  uint64_t bytes_read() const { return bytes_; }

 private:
  GalleryFileReader(std::string path, int fd);

  const std::string path_;
  const int fd_;
  std::unique_ptr<google::protobuf::io::FileInputStream> stream_;
  uint64_t bytes_ = 0;
  int64_t chunks_ = 0;
};

}  // namespace shapeid

#endif  // SHAPEID_CLIENT_GALLERY_FILE_H_
