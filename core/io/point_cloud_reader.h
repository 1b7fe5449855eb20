#ifndef SHAPEID_CORE_IO_POINT_CLOUD_READER_H_
#define SHAPEID_CORE_IO_POINT_CLOUD_READER_H_

#include <string>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "core/io/read_options.h"

namespace shapeid {

// The file formats ReadPointCloud knows, by extension (case-insensitive):
//   .pcd               PCD v0.7, DATA ascii, binary or binary_compressed (core/io/pcd_reader.h)
//   .ply               PLY ascii / binary little or big endian; vertices, or faces sampled
//                      with ReadOptions::sample_faces (core/io/ply_reader.h)
//   .off               OFF mesh, sampled to ReadOptions::sample_points (core/io/off_reader.h)
//   .obj               Wavefront OBJ mesh, sampled like OFF; an OBJ without faces gives its
//                      vertices (core/io/obj_reader.h)
//   .xyz .txt          text, blank- or comma-separated (core/io/xyz_reader.h)
//   .csv               text, comma- or semicolon-separated
enum class CloudFormat { kPcd, kPly, kOff, kObj, kXyz, kCsv };

// The format for `path`'s extension; InvalidArgument listing the supported extensions.
absl::StatusOr<CloudFormat> CloudFormatForPath(absl::string_view path);

// Reads and parses one point-cloud file, choosing the reader by extension. The file is read
// with one bulk read and parsed from memory. Error messages start with `path`, and name the
// line or byte offset of a problem in the contents. Codes: NotFound / PermissionDenied for a
// file that cannot be opened, InvalidArgument for an unknown extension or malformed contents,
// Unimplemented for valid files this reader cannot handle yet. Thread-safe.
absl::StatusOr<ReadResult> ReadPointCloud(const std::string& path, const ReadOptions& options = {});

// Parses contents already in memory (e.g. an upload); `name` only labels error messages.
absl::StatusOr<ReadResult> ParsePointCloud(absl::string_view contents, CloudFormat format,
                                           absl::string_view name, const ReadOptions& options = {});

// The whole file, in one read after sizing it. Messages start with `path`.
absl::StatusOr<std::string> ReadFileContents(const std::string& path);

}  // namespace shapeid

#endif  // SHAPEID_CORE_IO_POINT_CLOUD_READER_H_
