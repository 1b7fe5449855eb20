#ifndef SHAPEID_CORE_IO_POINT_CLOUD_READER_H_
#define SHAPEID_CORE_IO_POINT_CLOUD_READER_H_

#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "core/io/read_options.h"

namespace shapeid {

// CloudFormat, the formats and their extensions: core/io/read_options.h.

// Every format's name as `--input-format` takes it ("pcd", "ply", ..., "csv"), in enum order.
const std::vector<std::string>& CloudFormatNames();

// The format named `name` ("pcd", "xyz", ...; case-insensitive, a leading '.' allowed), for
// reading standard input; InvalidArgument listing the names.
absl::StatusOr<CloudFormat> CloudFormatForName(absl::string_view name);

// The format for `path`'s extension, looking through a final ".gz". InvalidArgument listing
// the supported extensions; for .laz, Unimplemented naming the commands that decompress it.
absl::StatusOr<CloudFormat> CloudFormatForPath(absl::string_view path);

// The extensions CloudFormatForPath accepts, for messages: ".pcd .ply ... .csv".
const std::string& SupportedExtensions();

// Reads and parses one point-cloud file, choosing the reader by extension, or for a file whose
// extension is missing or unknown by its first bytes' signature (reader_registry.h); "-" reads
// standard input, which needs ReadOptions::input_format (which also overrides any extension). The
// file is read with one bulk read (inflated if gzipped) and parsed from memory. Error messages
// start with `path`, and name the line or byte offset of a problem in the contents. Codes: NotFound
// / PermissionDenied for a file that cannot be opened, InvalidArgument for an unknown extension or
// malformed contents, Unimplemented for valid files this reader cannot handle yet. Thread-safe.
absl::StatusOr<ReadResult> ReadPointCloud(const std::string& path, const ReadOptions& options = {});

// Parses contents already in memory (e.g. an upload), inflating them first if they start with
// gzip's magic bytes; `name` only labels error messages.
absl::StatusOr<ReadResult> ParsePointCloud(absl::string_view contents, CloudFormat format,
                                           absl::string_view name, const ReadOptions& options = {});

// The whole file, in one read after sizing it. Messages start with `path`.
absl::StatusOr<std::string> ReadFileContents(const std::string& path);

}  // namespace shapeid

#endif  // SHAPEID_CORE_IO_POINT_CLOUD_READER_H_
