#include "core/io/reader_registry.h"

#include "absl/strings/match.h"
#include "absl/strings/str_join.h"
#include "core/io/las_reader.h"
#include "core/io/npy_reader.h"
#include "core/io/obj_reader.h"
#include "core/io/off_reader.h"
#include "core/io/pcd_reader.h"
#include "core/io/ply_reader.h"
#include "core/io/stl_reader.h"
#include "core/io/vtk_reader.h"
#include "core/io/xyz_reader.h"

namespace shapeid {
namespace {

// PCL writes "# .PCD v0.7 - Point Cloud Data file format"; a header may also start at
// VERSION (the PCD reader accepts both).
bool IsPcd(absl::string_view c) {
  return absl::StartsWith(c, "# .PCD") || absl::StartsWith(c, "VERSION");
}
bool IsPly(absl::string_view c) {
  return absl::StartsWith(c, "ply\n") || absl::StartsWith(c, "ply\r\n");
}
// ModelNet writes "OFF490 518 0" on one line; the reader needs only the first three bytes.
bool IsOff(absl::string_view c) { return absl::StartsWith(c, "OFF"); }
bool IsVtk(absl::string_view c) { return absl::StartsWith(c, "# vtk DataFile"); }
bool IsLas(absl::string_view c) { return absl::StartsWith(c, "LASF"); }
bool IsNpy(absl::string_view c) { return absl::StartsWith(c, absl::string_view("\x93NUMPY", 6)); }
// A zip archive: a local file header, or the end record of an empty archive.
bool IsNpz(absl::string_view c) {
  return absl::StartsWith(c, absl::string_view("PK\x03\x04", 4)) ||
         absl::StartsWith(c, absl::string_view("PK\x05\x06", 4));
}

absl::StatusOr<ReadResult> ParseText(absl::string_view c, absl::string_view n,
                                     const ReadOptions& o) {
  return ParseXyz(c, n, TextDialect::kXyz, o);
}
absl::StatusOr<ReadResult> ParsePts(absl::string_view c, absl::string_view n,
                                    const ReadOptions& o) {
  return ParseXyz(c, n, TextDialect::kPts, o);
}
absl::StatusOr<ReadResult> ParseCsv(absl::string_view c, absl::string_view n,
                                    const ReadOptions& o) {
  return ParseXyz(c, n, TextDialect::kCsv, o);
}

}  // namespace

const std::vector<CloudReaderKind>& RegisteredReaders() {
  static const auto* readers = new std::vector<CloudReaderKind>{
      {CloudFormat::kPcd, "pcd", {".pcd"}, IsPcd, ParsePcd},
      {CloudFormat::kPly, "ply", {".ply"}, IsPly, ParsePly},
      {CloudFormat::kOff, "off", {".off"}, IsOff, ParseOff},
      {CloudFormat::kObj, "obj", {".obj"}, nullptr, ParseObj},
      {CloudFormat::kStl, "stl", {".stl"}, HasStlSignature, ParseStl},
      {CloudFormat::kVtk, "vtk", {".vtk"}, IsVtk, ParseVtk},
      {CloudFormat::kLas, "las", {".las"}, IsLas, ParseLas},
      {CloudFormat::kNpy, "npy", {".npy"}, IsNpy, ParseNpy},
      {CloudFormat::kNpz, "npz", {".npz"}, IsNpz, ParseNpz},
      {CloudFormat::kXyz, "xyz", {".xyz", ".txt", ".xyzn", ".xyzrgb"}, nullptr, ParseText},
      {CloudFormat::kPts, "pts", {".pts"}, nullptr, ParsePts},
      {CloudFormat::kCsv, "csv", {".csv"}, nullptr, ParseCsv},
  };
  return *readers;
}

const CloudReaderKind& ReaderFor(CloudFormat format) {
  return RegisteredReaders()[static_cast<size_t>(format)];
}

std::optional<CloudFormat> CloudFormatBySignature(absl::string_view contents) {
  for (const CloudReaderKind& reader : RegisteredReaders()) {
    if (reader.has_signature != nullptr && reader.has_signature(contents)) return reader.format;
  }
  return std::nullopt;
}

std::string FormatsWithSignatures() {
  std::vector<absl::string_view> names;
  for (const CloudReaderKind& reader : RegisteredReaders()) {
    if (reader.has_signature != nullptr) names.push_back(reader.name);
  }
  return absl::StrJoin(names, ", ");
}

}  // namespace shapeid
