#include "core/io/vtk_reader.h"

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "core/io/cloud_accumulator.h"
#include "core/io/mesh_sampler.h"
#include "core/io/text_lines.h"
#include "core/status_macros.h"

namespace shapeid {
namespace {

enum class Kind { kSigned, kUnsigned, kFloat, kBit, kText };

struct DataType {
  const char* name;
  Kind kind;
  uint64_t size;  // bytes per binary value; 0 for bit and text arrays
};

// VTK's legacy type names, matched case-insensitively. VTK reads "long" as sizeof(long), 8 on
// every 64-bit Unix, and writes vtkIdType arrays as int32.
constexpr DataType kTypes[] = {
    {"float", Kind::kFloat, 4},
    {"double", Kind::kFloat, 8},
    {"char", Kind::kSigned, 1},
    {"signed_char", Kind::kSigned, 1},
    {"unsigned_char", Kind::kUnsigned, 1},
    {"short", Kind::kSigned, 2},
    {"unsigned_short", Kind::kUnsigned, 2},
    {"int", Kind::kSigned, 4},
    {"unsigned_int", Kind::kUnsigned, 4},
    {"long", Kind::kSigned, 8},
    {"unsigned_long", Kind::kUnsigned, 8},
    {"vtktypeint64", Kind::kSigned, 8},
    {"vtktypeuint64", Kind::kUnsigned, 8},
    {"vtkidtype", Kind::kSigned, 4},
    {"bit", Kind::kBit, 0},
    {"string", Kind::kText, 0},
    {"utf8_string", Kind::kText, 0},
    {"variant", Kind::kText, 0},
};
constexpr DataType kLegacyCellType = {"int", Kind::kSigned, 4};
constexpr char kNumericTypes[] =
    "float, double, char, signed_char, unsigned_char, short, unsigned_short, int, "
    "unsigned_int, long, unsigned_long, vtktypeint64, vtktypeuint64 or vtkIdType";

const DataType* FindType(absl::string_view word) {
  for (const DataType& t : kTypes) {
    if (absl::EqualsIgnoreCase(word, t.name)) return &t;
  }
  return nullptr;
}

bool IsSpace(char c) { return c == '\n' || IsBlank(c); }

// The file as tokens (ascii, and every keyword line) and big-endian values (binary), with the
// location of the last thing read for messages: its line in ascii files and in the header, its
// byte offset in binary files.
class Scanner {
 public:
  Scanner(absl::string_view data, absl::string_view name) : data_(data), name_(name) {}

  void set_binary(bool binary) { binary_ = binary; }
  bool binary() const { return binary_; }

  // The rest of the current line without its '\n'; false at the end.
  bool Line(absl::string_view* line) {
    Mark();
    if (pos_ >= data_.size()) return false;
    const size_t end = std::min(data_.find('\n', pos_), data_.size());
    *line = data_.substr(pos_, end - pos_);
    pos_ = end;
    SkipLine();
    return true;
  }

  // Moves past the next '\n': binary data starts on the line after its section header.
  void SkipLine() {
    const size_t end = data_.find('\n', pos_);
    if (end == absl::string_view::npos) {
      pos_ = data_.size();
      return;
    }
    pos_ = end + 1;
    ++line_;
  }

  bool Token(absl::string_view* token) {
    while (pos_ < data_.size() && IsSpace(data_[pos_])) {
      if (data_[pos_] == '\n') ++line_;
      ++pos_;
    }
    Mark();
    if (pos_ >= data_.size()) return false;
    const size_t start = pos_;
    while (pos_ < data_.size() && !IsSpace(data_[pos_])) ++pos_;
    *token = data_.substr(start, pos_ - start);
    return true;
  }

  // Whether the next token is `keyword` (case-insensitive); reads nothing.
  bool PeekIs(absl::string_view keyword) const {
    size_t p = pos_;
    while (p < data_.size() && IsSpace(data_[p])) ++p;
    size_t end = p;
    while (end < data_.size() && !IsSpace(data_[end])) ++end;
    return absl::EqualsIgnoreCase(data_.substr(p, end - p), keyword);
  }

  // Fails fast when `count` values of `type` cannot fit in the rest of the file (ascii values
  // take at least 2 bytes, "0 "), so that no header count is trusted for memory or time. In
  // binary files, moves to the data (the next line).
  absl::Status BeginValues(uint64_t count, const DataType& type, absl::string_view what) {
    if (!binary_) {
      if (count > (remaining() + 1) / 2) {
        return Error(absl::StrCat(what, " announces ", count, " values but only ", remaining(),
                                  " bytes follow"));
      }
      return absl::OkStatus();
    }
    if (count == 0) return absl::OkStatus();
    SkipLine();
    Mark();
    if (count > remaining() / type.size) {
      const std::string needed = count > std::numeric_limits<uint64_t>::max() / type.size
                                     ? std::string("over 2^64")
                                     : absl::StrCat(count * type.size);
      return Error(absl::StrCat(what, " announces ", count, " ", type.name, " values (", needed,
                                " bytes) but only ", remaining(), " bytes follow"));
    }
    return absl::OkStatus();
  }

  // One value of a numeric `type`; `what` names the section for messages.
  absl::Status Real(const DataType& type, absl::string_view what, double* value) {
    if (!binary_) {
      absl::string_view token;
      if (!Token(&token)) return Error(absl::StrCat("the file ends inside ", what));
      if (!ParseDouble(token, value)) {
        return Error(absl::StrCat(what, " value ", QuoteForMessage(token), " is not a number"));
      }
      return absl::OkStatus();
    }
    uint64_t bits = 0;
    SHAPEID_RETURN_IF_ERROR(Binary(type, what, &bits));
    switch (type.kind) {
      case Kind::kFloat:
        if (type.size == 4) {
          const auto narrow = static_cast<uint32_t>(bits);
          float f;
          std::memcpy(&f, &narrow, sizeof f);
          *value = f;
        } else {
          std::memcpy(value, &bits, sizeof bits);
        }
        return absl::OkStatus();
      case Kind::kSigned:
        *value = static_cast<double>(SignExtend(bits, type.size));
        return absl::OkStatus();
      default:
        *value = static_cast<double>(bits);
        return absl::OkStatus();
    }
  }

  // One value of an integer `type` (cell counts, offsets, point indices).
  absl::Status Integer(const DataType& type, absl::string_view what, int64_t* value) {
    if (!binary_) {
      absl::string_view token;
      if (!Token(&token)) return Error(absl::StrCat("the file ends inside ", what));
      if (!absl::SimpleAtoi(token, value)) {
        return Error(absl::StrCat(what, " value ", QuoteForMessage(token), " is not an integer"));
      }
      return absl::OkStatus();
    }
    uint64_t bits = 0;
    SHAPEID_RETURN_IF_ERROR(Binary(type, what, &bits));
    if (type.kind == Kind::kSigned) {
      *value = SignExtend(bits, type.size);
    } else if (bits > static_cast<uint64_t>(std::numeric_limits<int64_t>::max())) {
      return Error(absl::StrCat(what, " value ", bits, " is too large"));
    } else {
      *value = static_cast<int64_t>(bits);
    }
    return absl::OkStatus();
  }

  // Moves past `bytes` bytes of binary data.
  absl::Status SkipBytes(uint64_t bytes, absl::string_view what) {
    Mark();
    if (bytes > remaining()) {
      return Error(
          absl::StrCat(what, " needs ", bytes, " bytes but only ", remaining(), " bytes follow"));
    }
    pos_ += static_cast<size_t>(bytes);
    return absl::OkStatus();
  }

  // Skips the METADATA block (component names, information keys) that may follow an array, up
  // to the blank line that ends it.
  void SkipMetadata() {
    if (!PeekIs("METADATA")) return;
    absl::string_view line;
    Token(&line);
    Line(&line);
    while (Line(&line)) {
      if (std::all_of(line.begin(), line.end(), IsBlank)) return;
    }
  }

  // Where the last token, line or value began.
  uint64_t where() const { return binary_ ? mark_offset_ : mark_line_; }
  absl::Status Error(absl::string_view message) const {
    return absl::InvalidArgumentError(absl::StrCat(name_, ": ", Where(), ": ", message));
  }
  absl::Status Unimplemented(absl::string_view message) const {
    return absl::UnimplementedError(absl::StrCat(name_, ": ", Where(), ": ", message));
  }

 private:
  std::string Where() const {
    return binary_ ? absl::StrCat("byte offset ", mark_offset_) : absl::StrCat("line ", mark_line_);
  }
  size_t remaining() const { return data_.size() - pos_; }

  void Mark() {
    mark_offset_ = pos_;
    // At the end of a file ending with '\n', its last line rather than the empty one after.
    const bool after_last = pos_ >= data_.size() && pos_ > 0 && data_[pos_ - 1] == '\n';
    mark_line_ = after_last && line_ > 1 ? line_ - 1 : line_;
  }

  absl::Status Binary(const DataType& type, absl::string_view what, uint64_t* bits) {
    Mark();
    if (remaining() < type.size) {
      return Error(absl::StrCat("the binary ", what, " data is truncated"));
    }
    uint64_t v = 0;
    for (size_t i = 0; i < type.size; ++i) v = v << 8 | static_cast<unsigned char>(data_[pos_ + i]);
    pos_ += static_cast<size_t>(type.size);
    *bits = v;
    return absl::OkStatus();
  }

  static int64_t SignExtend(uint64_t bits, uint64_t size) {
    if (size < 8 && (bits >> (8 * size - 1) & 1) != 0) bits |= ~uint64_t{0} << (8 * size);
    int64_t v;
    std::memcpy(&v, &bits, sizeof v);
    return v;
  }

  absl::string_view data_;
  absl::string_view name_;
  bool binary_ = false;
  size_t pos_ = 0;
  uint64_t line_ = 1;
  size_t mark_offset_ = 0;
  uint64_t mark_line_ = 1;
};

// What the sections read so far hold.
struct Geometry {
  bool has_points = false;
  uint64_t point_count = 0;
  std::vector<double> xyz;
  std::vector<uint64_t> where;  // each point's line or byte offset
  bool has_surface = false;     // a POLYGONS or TRIANGLE_STRIPS cell
  TriangleMesh mesh;            // their triangles, when sampling
};

enum class CellKind { kOther, kPolygons, kStrips };

absl::Status ReadCount(Scanner& s, absl::string_view usage, uint64_t* count) {
  absl::string_view token;
  if (!s.Token(&token) || !absl::SimpleAtoi(token, count)) {
    return s.Error(absl::StrCat("expected \"", usage, "\", found ", QuoteForMessage(token)));
  }
  return absl::OkStatus();
}

absl::StatusOr<const DataType*> ReadType(Scanner& s, absl::string_view section, bool integer) {
  absl::string_view word;
  s.Token(&word);
  const DataType* type = FindType(word);
  const bool fits =
      type != nullptr && (integer ? type->kind == Kind::kSigned || type->kind == Kind::kUnsigned
                                  : type->kind != Kind::kBit && type->kind != Kind::kText);
  if (!fits) {
    return s.Error(
        absl::StrCat("unknown ", section, " data type ", QuoteForMessage(word), "; expected ",
                     integer ? "an integer type (int, vtktypeint64, ...)" : kNumericTypes));
  }
  return type;
}

absl::Status ReadPoints(Scanner& s, Geometry* g) {
  if (g->has_points) return s.Error("a second POINTS section");
  uint64_t n = 0;
  SHAPEID_RETURN_IF_ERROR(ReadCount(s, "POINTS <count> <type>", &n));
  SHAPEID_ASSIGN_OR_RETURN(const DataType* type, ReadType(s, "POINTS", false));
  if (n > std::numeric_limits<uint64_t>::max() / 3) {
    return s.Error(absl::StrCat("POINTS announces ", n, " points, more than a file can hold"));
  }
  SHAPEID_RETURN_IF_ERROR(s.BeginValues(3 * n, *type, "POINTS"));
  g->xyz.reserve(static_cast<size_t>(3 * n));  // bounded by the file's size just above
  g->where.reserve(static_cast<size_t>(n));
  for (uint64_t i = 0; i < n; ++i) {
    for (int a = 0; a < 3; ++a) {
      double v = 0;
      SHAPEID_RETURN_IF_ERROR(s.Real(*type, "POINTS", &v));
      if (a == 0) g->where.push_back(s.where());
      g->xyz.push_back(v);
    }
  }
  g->has_points = true;
  g->point_count = n;
  s.SkipMetadata();
  return absl::OkStatus();
}

// A cell's point indices, checked against the points read.
class CellReader {
 public:
  CellReader(Scanner& s, absl::string_view section, CellKind kind, bool keep, Geometry* g)
      : s_(s), section_(absl::AsciiStrToUpper(section)), kind_(kind), keep_(keep), g_(g) {}

  absl::Status Read() {
    if (!g_->has_points) {
      return s_.Error(absl::StrCat(section_, " before POINTS: cells index points not read yet"));
    }
    uint64_t n = 0, size = 0;
    const std::string usage = absl::StrCat(section_, " <cells> <size>");
    SHAPEID_RETURN_IF_ERROR(ReadCount(s_, usage, &n));
    SHAPEID_RETURN_IF_ERROR(ReadCount(s_, usage, &size));
    return s_.PeekIs("OFFSETS") ? ReadOffsetsLayout(n, size) : ReadLegacyLayout(n, size);
  }

 private:
  // VTK <= 4.2: `size` int32 values, each cell its point count then its indices.
  absl::Status ReadLegacyLayout(uint64_t n, uint64_t size) {
    if (n > size) {
      return s_.Error(absl::StrCat(section_, " announces ", n, " cells in ", size,
                                   " values; each cell takes one value or more"));
    }
    SHAPEID_RETURN_IF_ERROR(s_.BeginValues(size, kLegacyCellType, section_));
    uint64_t left = size;
    for (uint64_t c = 0; c < n; ++c) {
      int64_t k = 0;
      SHAPEID_RETURN_IF_ERROR(s_.Integer(kLegacyCellType, section_, &k));
      const uint64_t where = s_.where();
      if (k < 0 || static_cast<uint64_t>(k) >= left) {
        return s_.Error(absl::StrCat(section_, " cell ", c, " has ", k, " points but ",
                                     left == 0 ? 0 : left - 1, " of the ", size,
                                     " announced values remain"));
      }
      left -= 1 + static_cast<uint64_t>(k);
      cell_.clear();
      for (int64_t j = 0; j < k; ++j) {
        SHAPEID_RETURN_IF_ERROR(ReadIndex(kLegacyCellType));
      }
      Add(where);
    }
    if (left != 0) {
      return s_.Error(absl::StrCat(section_, " announces ", size, " values but its ", n,
                                   " cells hold ", size - left));
    }
    return absl::OkStatus();
  }

  // VTK 5.x: "OFFSETS <type>" (n values, the first 0, the last m) and "CONNECTIVITY <type>"
  // (m point indices); cell c is connectivity[offsets[c], offsets[c + 1]).
  absl::Status ReadOffsetsLayout(uint64_t n, uint64_t m) {
    absl::string_view keyword;
    s_.Token(&keyword);
    SHAPEID_ASSIGN_OR_RETURN(const DataType* offsets_type, ReadType(s_, "OFFSETS", true));
    SHAPEID_RETURN_IF_ERROR(s_.BeginValues(n, *offsets_type, "OFFSETS"));
    std::vector<uint64_t> offsets;
    offsets.reserve(static_cast<size_t>(n));  // bounded by the file's size just above
    for (uint64_t i = 0; i < n; ++i) {
      int64_t v = 0;
      SHAPEID_RETURN_IF_ERROR(s_.Integer(*offsets_type, "OFFSETS", &v));
      const bool ordered = i == 0 ? v == 0 : v >= 0 && static_cast<uint64_t>(v) >= offsets.back();
      if (!ordered || static_cast<uint64_t>(v) > m) {
        return s_.Error(absl::StrCat("OFFSETS value ", i, " is ", v, "; offsets rise from 0 to ",
                                     section_, "'s connectivity size ", m));
      }
      offsets.push_back(static_cast<uint64_t>(v));
    }
    if ((n == 0 ? 0 : offsets.back()) != m) {
      return s_.Error(absl::StrCat("the last of the ", n, " OFFSETS is ",
                                   n == 0 ? 0 : offsets.back(), " but ", section_, " announces ", m,
                                   " connectivity values"));
    }
    s_.SkipMetadata();
    if (!s_.Token(&keyword) || !absl::EqualsIgnoreCase(keyword, "CONNECTIVITY")) {
      return s_.Error(
          absl::StrCat("expected CONNECTIVITY after OFFSETS, found ", QuoteForMessage(keyword)));
    }
    SHAPEID_ASSIGN_OR_RETURN(const DataType* type, ReadType(s_, "CONNECTIVITY", true));
    SHAPEID_RETURN_IF_ERROR(s_.BeginValues(m, *type, "CONNECTIVITY"));
    for (uint64_t c = 0; c + 1 < n; ++c) {
      cell_.clear();
      uint64_t where = s_.where();
      for (uint64_t j = offsets[c]; j < offsets[c + 1]; ++j) {
        SHAPEID_RETURN_IF_ERROR(ReadIndex(*type));
        if (j == offsets[c]) where = s_.where();
      }
      Add(where);
    }
    s_.SkipMetadata();
    return absl::OkStatus();
  }

  absl::Status ReadIndex(const DataType& type) {
    int64_t v = 0;
    SHAPEID_RETURN_IF_ERROR(s_.Integer(type, section_, &v));
    if (v < 0 || static_cast<uint64_t>(v) >= g_->point_count) {
      return s_.Error(
          absl::StrCat(section_, " point index ", v, " is not in [0, ", g_->point_count, ")"));
    }
    cell_.push_back(static_cast<uint64_t>(v));
    return absl::OkStatus();
  }

  void Add(uint64_t where) {
    if (kind_ == CellKind::kOther) return;
    g_->has_surface = true;
    if (!keep_) return;
    if (kind_ == CellKind::kPolygons) {
      g_->mesh.AddPolygon(cell_, where);
      return;
    }
    for (size_t j = 2; j < cell_.size(); ++j) {
      triangle_.assign({cell_[j - 2], cell_[j - 1], cell_[j]});
      g_->mesh.AddPolygon(triangle_, where);
    }
  }

  Scanner& s_;
  const std::string section_;
  const CellKind kind_;
  const bool keep_;
  Geometry* const g_;
  std::vector<uint64_t> cell_;
  std::vector<uint64_t> triangle_;
};

// Skips "FIELD <name> <arrays>" and its arrays ("<name> <components> <tuples> <type>", then
// the values); NULL_ARRAY stands for an array without values.
absl::Status SkipField(Scanner& s) {
  absl::string_view token;
  uint64_t arrays = 0;
  s.Token(&token);
  SHAPEID_RETURN_IF_ERROR(ReadCount(s, "FIELD <name> <arrays>", &arrays));
  for (uint64_t i = 0; i < arrays; ++i) {
    if (!s.Token(&token)) {
      return s.Error(
          absl::StrCat("the file ends after ", i, " of the FIELD's ", arrays, " arrays"));
    }
    if (token == "NULL_ARRAY") continue;
    const std::string array(token);
    const std::string usage = absl::StrCat(array, " <components> <tuples> <type>");
    uint64_t components = 0, tuples = 0;
    SHAPEID_RETURN_IF_ERROR(ReadCount(s, usage, &components));
    SHAPEID_RETURN_IF_ERROR(ReadCount(s, usage, &tuples));
    s.Token(&token);
    const DataType* type = FindType(token);
    if (type == nullptr) {
      return s.Error(absl::StrCat("unknown data type ", QuoteForMessage(token), " for FIELD array ",
                                  QuoteForMessage(array)));
    }
    if (type->kind == Kind::kText) {
      return s.Unimplemented(absl::StrCat("FIELD array ", QuoteForMessage(array), " of type ",
                                          type->name, " is not read"));
    }
    if (components != 0 && tuples > std::numeric_limits<uint64_t>::max() / components) {
      return s.Error(
          absl::StrCat("FIELD array ", QuoteForMessage(array), " announces more than 2^64 values"));
    }
    const uint64_t values = components * tuples;
    const std::string what = absl::StrCat("FIELD array ", QuoteForMessage(array));
    if (s.binary() && type->kind == Kind::kBit) {
      if (values == 0) continue;
      s.SkipLine();
      SHAPEID_RETURN_IF_ERROR(s.SkipBytes(values / 8 + (values % 8 != 0 ? 1 : 0), what));
    } else {
      const DataType& value_type = type->kind == Kind::kBit ? kLegacyCellType : *type;
      SHAPEID_RETURN_IF_ERROR(s.BeginValues(values, value_type, what));
      if (s.binary()) {
        SHAPEID_RETURN_IF_ERROR(s.SkipBytes(values * value_type.size, what));
      } else {
        for (uint64_t v = 0; v < values; ++v) {
          double ignored = 0;
          SHAPEID_RETURN_IF_ERROR(s.Real(value_type, what, &ignored));
        }
      }
    }
    s.SkipMetadata();
  }
  return absl::OkStatus();
}

enum class Dataset { kPolyData, kUnstructuredGrid, kStructuredGrid };

absl::StatusOr<Dataset> ReadDataset(Scanner& s) {
  absl::string_view keyword, type;
  if (!s.Token(&keyword)) return s.Error("the file ends before its DATASET line");
  if (absl::EqualsIgnoreCase(keyword, "FIELD")) {
    return s.Unimplemented("the file holds only FIELD data (a vtkDataObject), no DATASET");
  }
  if (!absl::EqualsIgnoreCase(keyword, "DATASET") || !s.Token(&type)) {
    return s.Error(absl::StrCat("expected \"DATASET <type>\", found ", QuoteForMessage(keyword)));
  }
  if (absl::EqualsIgnoreCase(type, "POLYDATA")) return Dataset::kPolyData;
  if (absl::EqualsIgnoreCase(type, "UNSTRUCTURED_GRID")) return Dataset::kUnstructuredGrid;
  if (absl::EqualsIgnoreCase(type, "STRUCTURED_GRID")) return Dataset::kStructuredGrid;
  for (const char* implicit : {"STRUCTURED_POINTS", "RECTILINEAR_GRID"}) {
    if (absl::EqualsIgnoreCase(type, implicit)) {
      return s.Unimplemented(absl::StrCat("DATASET ", implicit,
                                          " has no POINTS (its points are a grid's); only "
                                          "POLYDATA, UNSTRUCTURED_GRID and STRUCTURED_GRID are "
                                          "read"));
    }
  }
  for (const char* other : {"TABLE", "TREE", "DIRECTED_GRAPH", "UNDIRECTED_GRAPH", "MOLECULE"}) {
    if (absl::EqualsIgnoreCase(type, other)) {
      return s.Unimplemented(absl::StrCat("DATASET ", other,
                                          " is not read; only POLYDATA, UNSTRUCTURED_GRID and "
                                          "STRUCTURED_GRID are"));
    }
  }
  return s.Error(absl::StrCat("unknown DATASET type ", QuoteForMessage(type)));
}

}  // namespace

absl::StatusOr<ReadResult> ParseVtk(absl::string_view contents, absl::string_view name,
                                    const ReadOptions& options) {
  Scanner s(contents, name);
  absl::string_view line;
  if (!s.Line(&line) || !absl::StartsWithIgnoreCase(line, "# vtk DataFile Version")) {
    return absl::InvalidArgumentError(
        absl::StrCat(name, ": line 1: a legacy VTK file starts with \"# vtk DataFile Version ",
                     "x.y\"; found ", QuoteForMessage(line)));
  }
  if (!s.Line(&line)) {
    return absl::InvalidArgumentError(
        absl::StrCat(name, ": line 2: the file ends before its title line"));
  }
  line = absl::string_view();
  s.Line(&line);
  const absl::string_view encoding = absl::StripAsciiWhitespace(line);
  if (absl::EqualsIgnoreCase(encoding, "BINARY")) {
    s.set_binary(true);
  } else if (!absl::EqualsIgnoreCase(encoding, "ASCII")) {
    return absl::InvalidArgumentError(
        absl::StrCat(name, ": line 3: expected ASCII or BINARY, found ", QuoteForMessage(line)));
  }
  SHAPEID_ASSIGN_OR_RETURN(const Dataset dataset, ReadDataset(s));
  const bool polydata = dataset == Dataset::kPolyData;
  const bool keep = polydata && options.sample_points > 0;

  Geometry g;
  absl::string_view keyword;
  while (s.Token(&keyword)) {
    const auto is = [keyword](const char* word) { return absl::EqualsIgnoreCase(keyword, word); };
    if (is("POINT_DATA") || is("CELL_DATA")) break;  // attributes: no geometry follows
    if (is("FIELD")) {
      SHAPEID_RETURN_IF_ERROR(SkipField(s));
    } else if (is("POINTS")) {
      SHAPEID_RETURN_IF_ERROR(ReadPoints(s, &g));
      if (!polydata) break;  // a grid's cells are not read
    } else if (polydata && (is("VERTICES") || is("LINES"))) {
      SHAPEID_RETURN_IF_ERROR(CellReader(s, keyword, CellKind::kOther, keep, &g).Read());
    } else if (polydata && is("POLYGONS")) {
      SHAPEID_RETURN_IF_ERROR(CellReader(s, keyword, CellKind::kPolygons, keep, &g).Read());
    } else if (polydata && is("TRIANGLE_STRIPS")) {
      SHAPEID_RETURN_IF_ERROR(CellReader(s, keyword, CellKind::kStrips, keep, &g).Read());
    } else if (dataset == Dataset::kStructuredGrid && is("DIMENSIONS")) {
      uint64_t ignored = 0;
      for (int a = 0; a < 3; ++a) {
        SHAPEID_RETURN_IF_ERROR(ReadCount(s, "DIMENSIONS nx ny nz", &ignored));
      }
    } else {
      return s.Error(
          absl::StrCat(polydata ? "unknown POLYDATA keyword " : "expected POINTS, found ",
                       QuoteForMessage(keyword)));
    }
  }
  if (!g.has_points) return s.Error("the dataset has no POINTS section");

  CloudAccumulator cloud(name, s.binary() ? "byte offset" : "line");
  const size_t n = static_cast<size_t>(g.point_count);
  if (keep && g.has_surface) {
    for (size_t i = 0; i < n; ++i)
      g.mesh.AddVertex(g.xyz[3 * i], g.xyz[3 * i + 1], g.xyz[3 * i + 2]);
    SHAPEID_RETURN_IF_ERROR(g.mesh.Sample(options.sample_points, options.sample_seed, name,
                                          s.binary() ? "byte offset" : "line", &cloud));
    return std::move(cloud).Finish(options);
  }
  return ReadPointsTwice(
      n, [&](size_t i, double* p) { std::memcpy(p, &g.xyz[3 * i], 3 * sizeof(double)); },
      [&](size_t i) { return g.where[i]; }, name, s.binary() ? "byte offset" : "line", options);
}

}  // namespace shapeid
