#ifndef SHAPEID_CORE_IO_READER_REGISTRY_H_
#define SHAPEID_CORE_IO_READER_REGISTRY_H_

#include <optional>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "core/io/read_options.h"

namespace shapeid {

// One point-cloud format the readers know. Adding a format is one reader file pair in
// core/io/ with its Parse function, one CloudFormat enumerator and one entry in the table in
// reader_registry.cc; names, extensions, signatures and messages all come from the table.
struct CloudReaderKind {
  CloudFormat format;
  std::string name;  // "pcd": what --input-format takes
  // Lower case with the dot, the first the format's own (".pcd"); a file's extension picks the
  // reader. The text formats' other names (".txt", ".xyzn") read as the format they alias.
  std::vector<std::string> extensions;
  // True when `contents` (a whole file, inflated) starts with this format's signature; null
  // for formats that have none (OBJ and the text formats), which only an extension or
  // --input-format can name.
  bool (*has_signature)(absl::string_view contents);
  // The reader. Messages start with `name`.
  absl::StatusOr<ReadResult> (*parse)(absl::string_view contents, absl::string_view name,
                                      const ReadOptions& options);
};

// Every format, in CloudFormat's order.
const std::vector<CloudReaderKind>& RegisteredReaders();

// The entry for `format`.
const CloudReaderKind& ReaderFor(CloudFormat format);

// The one format whose signature `contents` (inflated) carry, or nullopt: for a file whose
// name says nothing and for standard input. Signatures are disjoint (reader_registry_test).
std::optional<CloudFormat> CloudFormatBySignature(absl::string_view contents);

// The names of the formats with a signature, for messages: "pcd, ply, ...".
std::string FormatsWithSignatures();

}  // namespace shapeid

#endif  // SHAPEID_CORE_IO_READER_REGISTRY_H_
