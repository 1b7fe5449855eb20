#include "core/io/ply_reader.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "core/io/cloud_accumulator.h"
#include "core/io/mesh_sampler.h"
#include "core/io/text_lines.h"
#include "core/status_macros.h"

namespace shapeid {
namespace {

enum class Format { kAscii, kLittle, kBig };
enum class Kind { kSigned, kUnsigned, kFloat };

struct Type {
  Kind kind = Kind::kFloat;
  int size = 4;
};

struct Property {
  absl::string_view name;
  bool is_list = false;
  Type count_type;  // lists only
  Type type;        // the value, or a list's items
};

struct Element {
  absl::string_view name;
  uint64_t count = 0;
  uint64_t line = 0;
  std::vector<Property> properties;
};

struct Header {
  Format format = Format::kAscii;
  std::vector<Element> elements;
  size_t data_offset = 0;
  uint64_t data_line = 0;  // the first line after end_header
};

absl::Status LineError(absl::string_view name, uint64_t line, absl::string_view message) {
  return absl::InvalidArgumentError(absl::StrCat(name, ": line ", line, ": ", message));
}

bool ParseType(absl::string_view word, Type* type) {
  static constexpr struct {
    const char* name;
    Kind kind;
    int size;
  } kTypes[] = {{"char", Kind::kSigned, 1},     {"int8", Kind::kSigned, 1},
                {"uchar", Kind::kUnsigned, 1},  {"uint8", Kind::kUnsigned, 1},
                {"short", Kind::kSigned, 2},    {"int16", Kind::kSigned, 2},
                {"ushort", Kind::kUnsigned, 2}, {"uint16", Kind::kUnsigned, 2},
                {"int", Kind::kSigned, 4},      {"int32", Kind::kSigned, 4},
                {"uint", Kind::kUnsigned, 4},   {"uint32", Kind::kUnsigned, 4},
                {"float", Kind::kFloat, 4},     {"float32", Kind::kFloat, 4},
                {"double", Kind::kFloat, 8},    {"float64", Kind::kFloat, 8}};
  for (const auto& t : kTypes) {
    if (word == t.name) {
      *type = Type{t.kind, t.size};
      return true;
    }
  }
  return false;
}

absl::StatusOr<Header> ParseHeader(absl::string_view contents, absl::string_view name) {
  Header h;
  LineReader lines(contents);
  absl::string_view line;
  std::vector<absl::string_view> words;
  bool has_format = false;
  while (lines.Next(&line)) {
    const uint64_t ln = lines.line_number();
    words.clear();
    Tokenizer tokens(line);
    for (absl::string_view w; tokens.Next(&w);) words.push_back(w);
    if (ln == 1) {
      if (words.size() != 1 || words[0] != "ply") {
        return LineError(
            name, ln,
            absl::StrCat("a PLY file starts with a \"ply\" line; found ", QuoteForMessage(line)));
      }
      continue;
    }
    if (words.empty()) continue;
    const absl::string_view keyword = words[0];
    if (keyword == "comment" || keyword == "obj_info") continue;
    if (keyword == "format") {
      if (has_format) return LineError(name, ln, "format appears twice");
      if (words.size() != 3 || words[2] != "1.0") {
        return LineError(name, ln, "expected \"format <encoding> 1.0\"");
      }
      if (words[1] == "ascii") {
        h.format = Format::kAscii;
      } else if (words[1] == "binary_little_endian") {
        h.format = Format::kLittle;
      } else if (words[1] == "binary_big_endian") {
        h.format = Format::kBig;
      } else {
        return LineError(name, ln,
                         absl::StrCat("unknown format ", QuoteForMessage(words[1]),
                                      "; expected ascii, binary_little_endian or "
                                      "binary_big_endian"));
      }
      has_format = true;
    } else if (keyword == "element") {
      Element e;
      if (words.size() != 3 || !absl::SimpleAtoi(words[2], &e.count)) {
        return LineError(name, ln, "expected \"element <name> <count>\"");
      }
      e.name = words[1];
      e.line = ln;
      h.elements.push_back(e);
    } else if (keyword == "property") {
      if (h.elements.empty()) return LineError(name, ln, "a property before any element");
      Property p;
      const bool list = words.size() >= 2 && words[1] == "list";
      if (list ? words.size() != 5 : words.size() != 3) {
        return LineError(name, ln,
                         "expected \"property <type> <name>\" or "
                         "\"property list <count type> <item type> <name>\"");
      }
      p.is_list = list;
      const absl::string_view type_word = list ? words[3] : words[1];
      if (list && (!ParseType(words[2], &p.count_type) || p.count_type.kind == Kind::kFloat)) {
        return LineError(name, ln,
                         absl::StrCat("list count type ", QuoteForMessage(words[2]),
                                      " is not an integer PLY type"));
      }
      if (!ParseType(type_word, &p.type)) {
        return LineError(name, ln, absl::StrCat("unknown PLY type ", QuoteForMessage(type_word)));
      }
      p.name = words.back();
      h.elements.back().properties.push_back(p);
    } else if (keyword == "end_header") {
      if (!has_format) return LineError(name, ln, "the header has no format line");
      h.data_offset = lines.offset();
      h.data_line = ln + 1;
      return h;
    } else {
      return LineError(name, ln,
                       absl::StrCat("unknown PLY header keyword ", QuoteForMessage(keyword)));
    }
  }
  return absl::InvalidArgumentError(absl::StrCat(name, ": the PLY header has no end_header line (",
                                                 lines.line_number(), " lines read)"));
}

// Reads the values of the data section one by one, in ascii or binary.
class ValueReader {
 public:
  ValueReader(absl::string_view contents, absl::string_view name, const Header& h)
      : name_(name),
        format_(h.format),
        data_(contents),
        pos_(h.data_offset),
        lines_(contents.substr(h.data_offset), h.data_line),
        tokens_(absl::string_view()) {}

  // Starts the next element instance; its location goes to *where.
  absl::Status BeginInstance(uint64_t* where) {
    if (format_ != Format::kAscii) {
      *where = pos_;
      return absl::OkStatus();
    }
    absl::string_view line;
    while (lines_.Next(&line)) {
      if (!StripComment(line).empty()) {
        tokens_ = Tokenizer(line);
        *where = lines_.line_number();
        return absl::OkStatus();
      }
    }
    return absl::InvalidArgumentError(absl::StrCat(name_, ": line ", lines_.line_number(),
                                                   ": the ascii data ends before the header's ",
                                                   "element counts are read"));
  }

  // Ends an ascii instance: its line must hold nothing more.
  absl::Status EndInstance() {
    absl::string_view token;
    if (format_ == Format::kAscii && tokens_.Next(&token)) {
      return absl::InvalidArgumentError(absl::StrCat(name_, ": line ", lines_.line_number(),
                                                     ": extra value ", QuoteForMessage(token),
                                                     " after the element's properties"));
    }
    return absl::OkStatus();
  }

  absl::Status Read(Type type, double* value) {
    if (format_ == Format::kAscii) {
      absl::string_view token;
      if (!tokens_.Next(&token)) {
        return absl::InvalidArgumentError(absl::StrCat(name_, ": line ", lines_.line_number(),
                                                       ": too few values for the element"));
      }
      if (!ParseDouble(token, value)) {
        return absl::InvalidArgumentError(absl::StrCat(name_, ": line ", lines_.line_number(),
                                                       ": value ", QuoteForMessage(token),
                                                       " is not a number"));
      }
      return absl::OkStatus();
    }
    const size_t size = static_cast<size_t>(type.size);
    if (data_.size() - pos_ < size) {
      return absl::InvalidArgumentError(
          absl::StrCat(name_, ": byte offset ", pos_, ": the binary data is truncated"));
    }
    unsigned char b[8];
    std::memcpy(b, data_.data() + pos_, size);
    pos_ += size;
    const bool little_host = __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__;
    if ((format_ == Format::kLittle) != little_host) std::reverse(b, b + size);
    *value = Decode(type, b);
    return absl::OkStatus();
  }

  // The current location, for errors found after reading a value.
  std::string Where() const {
    return format_ == Format::kAscii ? absl::StrCat("line ", lines_.line_number())
                                     : absl::StrCat("byte offset ", pos_);
  }
  // Binary only: the byte offset of the next value, and a jump over bytes known to be there.
  size_t pos() const { return pos_; }
  void Skip(size_t bytes) { pos_ += bytes; }

  // Whether nothing but blank lines follows the ascii data.
  bool AtEnd() {
    if (format_ != Format::kAscii) return true;  // trailing bytes (padding) are ignored
    absl::string_view line;
    while (lines_.Next(&line)) {
      if (!StripComment(line).empty()) return false;
    }
    return true;
  }

 private:
  static double Decode(Type type, const unsigned char* b) {
    switch (type.kind) {
      case Kind::kFloat:
        return type.size == 4 ? Load<float>(b) : Load<double>(b);
      case Kind::kSigned:
        return type.size == 1   ? Load<int8_t>(b)
               : type.size == 2 ? Load<int16_t>(b)
                                : Load<int32_t>(b);
      case Kind::kUnsigned:
        return type.size == 1   ? Load<uint8_t>(b)
               : type.size == 2 ? Load<uint16_t>(b)
                                : Load<uint32_t>(b);
    }
    return 0;
  }
  template <typename T>
  static double Load(const unsigned char* b) {
    T v;
    std::memcpy(&v, b, sizeof v);
    return static_cast<double>(v);
  }

  absl::string_view name_;
  Format format_;
  absl::string_view data_;
  size_t pos_;
  LineReader lines_;
  Tokenizer tokens_;
};

// The bytes of one instance of `e` when they are fixed (binary, no list property) and x, y and
// z are float32, so that its coordinates can be read as columns; 0 otherwise.
uint64_t FloatVertexRecordBytes(const Element& e, const size_t coord[3]) {
  uint64_t bytes = 0;
  for (const Property& p : e.properties) {
    if (p.is_list) return 0;
    bytes += static_cast<uint64_t>(p.type.size);
  }
  for (int a = 0; a < 3; ++a) {
    const Type t = e.properties[coord[a]].type;
    if (t.kind != Kind::kFloat || t.size != 4) return 0;
  }
  return bytes;
}

uint64_t PropertyOffset(const Element& e, size_t property) {
  uint64_t bytes = 0;
  for (size_t i = 0; i < property; ++i) bytes += static_cast<uint64_t>(e.properties[i].type.size);
  return bytes;
}

int FindScalar(const Element& e, absl::string_view property) {
  for (size_t i = 0; i < e.properties.size(); ++i) {
    if (e.properties[i].name == property && !e.properties[i].is_list) return static_cast<int>(i);
  }
  return -1;
}

}  // namespace

absl::StatusOr<ReadResult> ParsePly(absl::string_view contents, absl::string_view name,
                                    const ReadOptions& options) {
  SHAPEID_ASSIGN_OR_RETURN(const Header h, ParseHeader(contents, name));
  const Element* vertex = nullptr;
  const Element* face = nullptr;
  for (const Element& e : h.elements) {
    if (e.name == "vertex" && vertex == nullptr) vertex = &e;
    if (e.name == "face" && face == nullptr) face = &e;
  }
  if (vertex == nullptr) {
    return absl::InvalidArgumentError(absl::StrCat(name, ": the PLY header has no vertex element"));
  }
  size_t coord[3];
  for (int a = 0; a < 3; ++a) {
    const int found = FindScalar(*vertex, absl::string_view(&"xyz"[a], 1));
    coord[a] = static_cast<size_t>(found);
    if (found < 0) {
      return LineError(name, vertex->line,
                       absl::StrCat("the vertex element has no scalar \"", std::string(1, "xyz"[a]),
                                    "\" property"));
    }
  }
  // A mesh is sampled like every other mesh format; a cloud saved as PLY has no faces.
  // A face element without a vertex_indices list holds nothing to sample: its vertices are read.
  int indices_property = -1;
  if (face != nullptr) {
    for (size_t i = 0; i < face->properties.size(); ++i) {
      const Property& p = face->properties[i];
      if (p.is_list && (p.name == "vertex_indices" || p.name == "vertex_index")) {
        indices_property = static_cast<int>(i);
      }
    }
  }
  const bool sample =
      options.sample_points > 0 && face != nullptr && face->count > 0 && indices_property >= 0;

  const bool ascii = h.format == Format::kAscii;
  CloudAccumulator cloud(name, ascii ? "line" : "byte offset");
  TriangleMesh mesh;
  // Counts are not trusted for memory: reserve no more than the data could hold.
  const size_t bound = static_cast<size_t>(
      std::min<uint64_t>(vertex->count, (contents.size() - h.data_offset) / (ascii ? 6 : 3)));
  if (!sample) cloud.Reserve(bound);
  ValueReader reader(contents, name, h);
  std::vector<double> values;
  std::vector<uint64_t> polygon;
  // Binary vertices with float32 x, y, z in fixed records are read as columns, in one go.
  const uint64_t record = ascii || sample ? 0 : FloatVertexRecordBytes(*vertex, coord);
  std::optional<ReadResult> columns_read;
  for (const Element& e : h.elements) {
    const bool is_vertex = &e == vertex;
    const bool is_face = &e == face && sample;
    uint64_t vertex_bytes = 0;
    if (is_vertex && record > 0 && !__builtin_mul_overflow(e.count, record, &vertex_bytes) &&
        vertex_bytes <= contents.size() - reader.pos()) {
      FloatColumns columns;
      for (int a = 0; a < 3; ++a) {
        columns.axis[a] = contents.data() + reader.pos() + PropertyOffset(e, coord[a]);
        columns.stride[a] = record;
      }
      columns.byte_swapped =
          (h.format == Format::kBig) == (__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__);
      columns.where = reader.pos();
      columns.where_step = record;
      columns_read = ReadFloatColumns(columns, e.count, "byte offset", options);
      reader.Skip(vertex_bytes);
      continue;
    }
    values.assign(e.properties.size(), 0.0);
    // A binary element without properties has instances of zero bytes: nothing to read,
    // however many the header announces (counting to 2^64 - 1 would hang the reader).
    if (e.properties.empty() && !ascii) continue;
    for (uint64_t i = 0; i < e.count; ++i) {
      uint64_t where = 0;
      SHAPEID_RETURN_IF_ERROR(reader.BeginInstance(&where));
      for (size_t p = 0; p < e.properties.size(); ++p) {
        const Property& prop = e.properties[p];
        if (!prop.is_list) {
          SHAPEID_RETURN_IF_ERROR(reader.Read(prop.type, &values[p]));
          continue;
        }
        double count = 0;
        SHAPEID_RETURN_IF_ERROR(reader.Read(prop.count_type, &count));
        if (!(count >= 0 && count <= 4294967295.0) || count != std::floor(count)) {
          return absl::InvalidArgumentError(
              absl::StrCat(name, ": ", reader.Where(), ": list length ", count, " is not a count"));
        }
        const bool keep = is_face && static_cast<int>(p) == indices_property;
        if (keep) polygon.clear();
        for (uint64_t k = 0; k < static_cast<uint64_t>(count); ++k) {
          double item = 0;
          SHAPEID_RETURN_IF_ERROR(reader.Read(prop.type, &item));
          if (!keep) continue;
          if (!(item >= 0 && item < static_cast<double>(vertex->count)) ||
              item != std::floor(item)) {
            return absl::InvalidArgumentError(
                absl::StrCat(name, ": ", reader.Where(), ": vertex index ", item,
                             " is not an integer in [0, ", vertex->count, ")"));
          }
          polygon.push_back(static_cast<uint64_t>(item));
        }
        if (keep) mesh.AddPolygon(polygon, where);
      }
      SHAPEID_RETURN_IF_ERROR(reader.EndInstance());
      if (!is_vertex) continue;
      if (sample) {
        mesh.AddVertex(values[coord[0]], values[coord[1]], values[coord[2]]);
      } else {
        cloud.Add(values[coord[0]], values[coord[1]], values[coord[2]], where);
      }
    }
  }
  if (!reader.AtEnd()) {
    return absl::InvalidArgumentError(absl::StrCat(
        name, ": ", reader.Where(), ": more data than the header's element counts describe"));
  }
  if (columns_read.has_value()) return std::move(columns_read).value();
  if (sample) {
    SHAPEID_RETURN_IF_ERROR(mesh.Sample(options.sample_points, options.sample_seed, name,
                                        ascii ? "line" : "byte offset", &cloud));
  }
  return std::move(cloud).Finish(options);
}

}  // namespace shapeid
