#include "core/io/npy_reader.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/escaping.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "core/io/cloud_accumulator.h"
#include "core/io/npy_header.h"
#include "core/io/text_lines.h"
#include "core/io/zip_archive.h"
#include "core/status_macros.h"

namespace shapeid {
namespace {

constexpr absl::string_view kNpyMagic("\x93NUMPY", 6);
constexpr bool kHostBigEndian = __BYTE_ORDER__ == __ORDER_BIG_ENDIAN__;
// Item sizes and element counts are capped here, so that sums and products of them never
// overflow; no real array comes near.
constexpr uint64_t kMaxBytes = uint64_t{1} << 62;
// Parsed headers take tens of times their size in memory; numpy's own limit is 10000 bytes.
constexpr uint64_t kMaxHeaderLength = uint64_t{1} << 20;

absl::Status Invalid(absl::string_view name, uint64_t offset, absl::string_view what) {
  return absl::InvalidArgumentError(absl::StrCat(name, ": byte offset ", offset, ": ", what));
}

absl::Status Unimplemented(absl::string_view name, uint64_t offset, absl::string_view what) {
  return absl::UnimplementedError(absl::StrCat(name, ": byte offset ", offset, ": ", what));
}

// *out = a * b; false when it would exceed kMaxBytes.
bool MulCapped(uint64_t a, uint64_t b, uint64_t* out) {
  if (a != 0 && b > kMaxBytes / a) return false;
  *out = a * b;
  return true;
}

// The little-endian unsigned integer of n <= 8 bytes at p.
uint64_t Le(const char* p, int n) {
  uint64_t v = 0;
  for (int i = n - 1; i >= 0; --i) v = (v << 8) | static_cast<unsigned char>(p[i]);
  return v;
}

// The header's Python literal (core/io/npy_header.h).
using npy_internal::IsDigit;
using npy_internal::Literal;
using npy_internal::LiteralParser;
using npy_internal::Quote;

// ---- dtypes ----

using Loader = double (*)(const char*);

// The n <= 8 bytes at p as an unsigned integer, in the given byte order.
template <int kSize, bool kBig>
uint64_t LoadBits(const char* p) {
  uint64_t v = 0;
  for (int i = 0; i < kSize; ++i) {
    v = (v << 8) | static_cast<unsigned char>(p[kBig ? i : kSize - 1 - i]);
  }
  return v;
}

template <typename T, bool kBig>
double Load(const char* p) {
  const uint64_t bits = LoadBits<sizeof(T), kBig>(p);
  if constexpr (std::is_floating_point_v<T>) {
    using Bits = std::conditional_t<sizeof(T) == 4, uint32_t, uint64_t>;
    const Bits b = static_cast<Bits>(bits);
    T value;
    std::memcpy(&value, &b, sizeof value);
    return static_cast<double>(value);
  } else {
    const auto u = static_cast<std::make_unsigned_t<T>>(bits);
    T value;
    std::memcpy(&value, &u, sizeof value);
    return static_cast<double>(value);
  }
}

template <bool kBig>
double LoadHalf(const char* p) {
  const uint64_t h = LoadBits<2, kBig>(p);
  const int exponent = static_cast<int>((h >> 10) & 0x1f);
  const double mantissa = static_cast<double>(h & 0x3ff);
  double v;
  if (exponent == 0) {
    v = std::ldexp(mantissa, -24);
  } else if (exponent == 31) {
    v = mantissa == 0 ? std::numeric_limits<double>::infinity()
                      : std::numeric_limits<double>::quiet_NaN();
  } else {
    v = std::ldexp(mantissa + 1024, exponent - 25);
  }
  return (h & 0x8000) != 0 ? -v : v;
}

// A type string such as '<f4', parsed.
struct Scalar {
  std::string text;  // as written, for messages
  char kind = 'f';   // NumPy's kind: b i u f c m M S a U V
  bool big_endian = false;
  uint64_t size = 0;  // bytes
};

template <bool kBig>
Loader LoaderFor(char kind, uint64_t size) {
  if (kind == 'f') {
    if (size == 2) return &LoadHalf<kBig>;
    if (size == 4) return &Load<float, kBig>;
    if (size == 8) return &Load<double, kBig>;
  } else if (kind == 'i') {
    if (size == 1) return &Load<int8_t, kBig>;
    if (size == 2) return &Load<int16_t, kBig>;
    if (size == 4) return &Load<int32_t, kBig>;
    if (size == 8) return &Load<int64_t, kBig>;
  } else if (kind == 'u') {
    if (size == 1) return &Load<uint8_t, kBig>;
    if (size == 2) return &Load<uint16_t, kBig>;
    if (size == 4) return &Load<uint32_t, kBig>;
    if (size == 8) return &Load<uint64_t, kBig>;
  }
  return nullptr;
}

// The decoder of a coordinate of type `s`, or nullptr for a kind not read as coordinates.
Loader CoordinateLoader(const Scalar& s) {
  return s.big_endian ? LoaderFor<true>(s.kind, s.size) : LoaderFor<false>(s.kind, s.size);
}

std::string NotCoordinates(const Scalar& s) {
  return absl::StrCat("coordinates of dtype '", absl::CHexEscape(s.text),
                      "' are not read (float f2, f4, f8 and integer i1..i8, u1..u8 are)");
}

bool ValidSize(char kind, uint64_t n) {
  switch (kind) {
    case 'b':
      return n == 1;
    case 'i':
    case 'u':
      return n == 1 || n == 2 || n == 4 || n == 8;
    case 'f':
      return n == 2 || n == 4 || n == 8 || n == 10 || n == 12 || n == 16;
    case 'c':
      return n == 8 || n == 16 || n == 20 || n == 24 || n == 32;
    case 'm':
    case 'M':
      return n == 8;
    default:  // S a U V: any length
      return true;
  }
}

// Where the header's parts are, for messages.
struct HeaderContext {
  absl::string_view name;
  uint64_t base;  // the header's byte offset in the file
};

// Parses a NumPy type string: byte order ('<' '>' '=' '|', or none for the host's), kind,
// size in bytes (characters for U), and for datetimes a "[unit]".
absl::Status ParseTypestr(const Literal& lit, const HeaderContext& ctx, Scalar* out) {
  const absl::string_view s = lit.text;
  const uint64_t where = ctx.base + lit.pos;
  out->text = std::string(s);
  const auto bad = [&](absl::string_view why) {
    return Invalid(ctx.name, where,
                   absl::StrCat("dtype '", absl::CHexEscape(s), "' ", why,
                                "; expected a NumPy type string such as '<f4'"));
  };
  size_t i = 0;
  char order = '=';
  if (i < s.size() && absl::string_view("<>=|").find(s[i]) != absl::string_view::npos) {
    order = s[i++];
  }
  if (i >= s.size()) return bad("has no kind");
  out->kind = s[i++];
  if (out->kind == 'O') {
    return Invalid(ctx.name, where,
                   "pickled object arrays are not read (dtype 'O'); save the points as a float "
                   "array");
  }
  if (absl::string_view("biufcmMSaUV").find(out->kind) == absl::string_view::npos) {
    return bad("has an unknown kind");
  }
  if (i >= s.size() || !IsDigit(s[i])) return bad("has no size");
  uint64_t n = 0;
  while (i < s.size() && IsDigit(s[i])) {
    n = n * 10 + static_cast<uint64_t>(s[i++] - '0');
    if (n > (uint64_t{1} << 40)) return bad("has an absurd size");
  }
  if ((out->kind == 'm' || out->kind == 'M') && i < s.size() && s[i] == '[' && s.back() == ']') {
    i = s.size();
  }
  if (i != s.size() || !ValidSize(out->kind, n)) return bad("is not a valid type");
  out->size = out->kind == 'U' ? 4 * n : n;
  const uint64_t unit = out->kind == 'U' ? 4 : n;
  if (order == '|' && unit > 1 && absl::string_view("SaVb").find(out->kind) == s.npos) {
    return bad("has no byte order ('|') but more than one byte per value");
  }
  out->big_endian = order == '>' || (order != '<' && kHostBigEndian);
  return absl::OkStatus();
}

// How to find x, y and z in the data.
struct Layout {
  bool structured = false;
  uint64_t itemsize = 0;  // bytes per array element (a scalar or a record)
  Loader load[3] = {nullptr, nullptr, nullptr};
  uint64_t field_offset[3] = {0, 0, 0};  // structured: within a record
  std::string dtype;                     // for messages
};

// The element count of a sub-array shape (an int or a tuple of ints).
absl::Status SubarrayCount(const Literal& shape, const HeaderContext& ctx, uint64_t* count) {
  const auto bad = [&] {
    return Invalid(ctx.name, ctx.base + shape.pos,
                   "a field's sub-array shape is not a non-negative integer or a tuple of them");
  };
  *count = 1;
  if (shape.type == Literal::Type::kInt) {
    if (shape.negative || shape.too_big || shape.magnitude > kMaxBytes) return bad();
    *count = shape.magnitude;
    return absl::OkStatus();
  }
  if (shape.type != Literal::Type::kTuple) return bad();
  for (const Literal& d : shape.items) {
    if (d.type != Literal::Type::kInt || d.negative || d.too_big ||
        !MulCapped(*count, d.magnitude, count)) {
      return bad();
    }
  }
  return absl::OkStatus();
}

// Walks a structured descr (a list of (name, type[, shape]) tuples), summing field sizes into
// *size. At the top level (`layout` set) the scalar 'x', 'y' and 'z' fields are located.
absl::Status ParseFields(const Literal& list, const HeaderContext& ctx, uint64_t* size,
                         Layout* layout) {
  *size = 0;
  std::vector<std::string> names;
  bool found[3] = {false, false, false};
  for (const Literal& field : list.items) {
    const uint64_t where = ctx.base + field.pos;
    if (field.type != Literal::Type::kTuple || field.items.size() < 2 || field.items.size() > 3) {
      return Invalid(ctx.name, where,
                     "a structured dtype's field is (name, type) or (name, type, shape)");
    }
    const Literal* name = &field.items[0];
    if (name->type == Literal::Type::kTuple && name->items.size() == 2) {
      name = &name->items[1];  // (title, name)
    }
    if (name->type != Literal::Type::kString) {
      return Invalid(ctx.name, where, "a field's name is not a string");
    }
    const Literal& type = field.items[1];
    uint64_t bytes = 0;
    Scalar scalar;
    const bool nested = type.type == Literal::Type::kList;
    if (nested) {
      SHAPEID_RETURN_IF_ERROR(ParseFields(type, ctx, &bytes, nullptr));
    } else if (type.type == Literal::Type::kString) {
      SHAPEID_RETURN_IF_ERROR(ParseTypestr(type, ctx, &scalar));
      bytes = scalar.size;
    } else {
      return Invalid(ctx.name, ctx.base + type.pos,
                     "a field's type is not a type string or a list of fields");
    }
    uint64_t count = 1;
    const bool subarray =
        field.items.size() == 3 &&
        !(field.items[2].type == Literal::Type::kTuple && field.items[2].items.empty());
    if (subarray) SHAPEID_RETURN_IF_ERROR(SubarrayCount(field.items[2], ctx, &count));
    if (!MulCapped(bytes, count, &bytes) || bytes > kMaxBytes - *size) {
      return Invalid(ctx.name, where, "the structured dtype's item size is absurdly large");
    }
    if (layout != nullptr) {
      const std::string& n = name->text;
      const int axis = n == "x" ? 0 : n == "y" ? 1 : n == "z" ? 2 : -1;
      if (axis >= 0) {
        if (found[axis]) {
          return Invalid(ctx.name, where, absl::StrCat("field '", n, "' appears twice"));
        }
        if (nested || subarray) {
          return Unimplemented(
              ctx.name, where,
              absl::StrCat("field '", n, "' is ", nested ? "a nested record" : "a sub-array",
                           "; only scalar x, y and z fields are read"));
        }
        layout->load[axis] = CoordinateLoader(scalar);
        if (layout->load[axis] == nullptr) {
          return Unimplemented(ctx.name, ctx.base + type.pos, NotCoordinates(scalar));
        }
        layout->field_offset[axis] = *size;
        found[axis] = true;
      }
      if (names.size() < 12) names.push_back(absl::StrCat("'", absl::CHexEscape(n), "'"));
    }
    *size += bytes;
  }
  for (int a = 0; a < 3 && layout != nullptr; ++a) {
    if (!found[a]) {
      return Invalid(
          ctx.name, ctx.base + list.pos,
          absl::StrCat("the structured dtype has no '", std::string(1, "xyz"[a]),
                       "' field (its fields: ", names.empty() ? "none" : "",
                       absl::StrJoin(names, ", "), list.items.size() > names.size() ? ", ..." : "",
                       "); fields named x, y and z are read"));
    }
  }
  return absl::OkStatus();
}

absl::Status ParseDescr(const Literal& descr, const HeaderContext& ctx, Layout* layout) {
  if (descr.type == Literal::Type::kString) {
    Scalar scalar;
    SHAPEID_RETURN_IF_ERROR(ParseTypestr(descr, ctx, &scalar));
    const Loader load = CoordinateLoader(scalar);
    if (load == nullptr) {
      return Unimplemented(ctx.name, ctx.base + descr.pos, NotCoordinates(scalar));
    }
    layout->itemsize = scalar.size;
    for (int a = 0; a < 3; ++a) layout->load[a] = load;
    layout->dtype = absl::StrCat("'", absl::CHexEscape(scalar.text), "'");
    return absl::OkStatus();
  }
  if (descr.type == Literal::Type::kList) {
    layout->structured = true;
    SHAPEID_RETURN_IF_ERROR(ParseFields(descr, ctx, &layout->itemsize, layout));
    layout->dtype = absl::StrCat("a structured dtype of ", layout->itemsize, " bytes");
    return absl::OkStatus();
  }
  return Invalid(ctx.name, ctx.base + descr.pos,
                 "'descr' is neither a type string nor a list of fields");
}

std::string ShapeText(const std::vector<uint64_t>& dims) {
  std::string text = "(";
  for (size_t i = 0; i < dims.size(); ++i) absl::StrAppend(&text, i > 0 ? ", " : "", dims[i]);
  return absl::StrCat(text, dims.size() == 1 ? ",)" : ")");
}

// The .npy format proper (no zip dispatch).
absl::StatusOr<ReadResult> ParseNpyArray(absl::string_view contents, absl::string_view name,
                                         const ReadOptions& options) {
  if (contents.substr(0, kNpyMagic.size()) != kNpyMagic || contents.size() < 8) {
    return Invalid(name, 0,
                   absl::StrCat("a .npy file starts with \"\\x93NUMPY\" and a version; found ",
                                QuoteForMessage(contents.substr(0, 8))));
  }
  const int major = static_cast<unsigned char>(contents[6]);
  const int minor = static_cast<unsigned char>(contents[7]);
  if (major < 1 || major > 3 || minor != 0) {
    return Unimplemented(name, 6,
                         absl::StrCat(".npy format version ", major, ".", minor,
                                      " is not read (1.0, 2.0 and 3.0 are)"));
  }
  const int length_bytes = major == 1 ? 2 : 4;
  const uint64_t header_start = 8 + static_cast<uint64_t>(length_bytes);
  if (contents.size() < header_start) {
    return Invalid(name, 8, "the file ends inside the header length");
  }
  const uint64_t header_length = Le(contents.data() + 8, length_bytes);
  if (header_length > contents.size() - header_start) {
    return Invalid(name, 8,
                   absl::StrCat("the header length ", header_length, " runs past the end of the ",
                                "file (", contents.size() - header_start, " bytes follow it)"));
  }
  if (header_length > kMaxHeaderLength) {
    return Invalid(name, 8,
                   absl::StrCat("the header length ", header_length, " is over ", kMaxHeaderLength,
                                " bytes (numpy itself reads at most 10000)"));
  }
  const HeaderContext ctx{name, header_start};
  LiteralParser parser(contents.substr(header_start, header_length), header_start, name,
                       major <= 2);
  SHAPEID_ASSIGN_OR_RETURN(const Literal dict, parser.Parse());
  if (dict.type != Literal::Type::kDict) return parser.Error(dict.pos, "expected a dict");
  const Literal* descr = nullptr;
  const Literal* fortran = nullptr;
  const Literal* shape = nullptr;
  for (size_t i = 0; i + 1 < dict.items.size(); i += 2) {
    const Literal& key = dict.items[i];
    const Literal** slot = key.type != Literal::Type::kString ? nullptr
                           : key.text == "descr"              ? &descr
                           : key.text == "fortran_order"      ? &fortran
                           : key.text == "shape"              ? &shape
                                                              : nullptr;
    const std::string key_text =
        key.type == Literal::Type::kString ? Quote(key.text) : std::string("that is no string");
    if (slot == nullptr) {
      return parser.Error(
          key.pos,
          absl::StrCat("unexpected key ", key_text,
                       "; a .npy header has exactly 'descr', 'fortran_order' and 'shape'"));
    }
    if (*slot != nullptr) {
      return parser.Error(key.pos, absl::StrCat("key ", key_text, " appears twice"));
    }
    *slot = &dict.items[i + 1];
  }
  if (descr == nullptr || fortran == nullptr || shape == nullptr) {
    return parser.Error(dict.pos, absl::StrCat("the header has no '",
                                               descr == nullptr     ? "descr"
                                               : fortran == nullptr ? "fortran_order"
                                                                    : "shape",
                                               "' key"));
  }
  if (fortran->type != Literal::Type::kBool) {
    return parser.Error(fortran->pos, "'fortran_order' is not True or False");
  }
  std::vector<uint64_t> dims;
  bool has_zero = false;
  if (shape->type != Literal::Type::kTuple) {
    return parser.Error(shape->pos, "'shape' is not a tuple");
  }
  for (const Literal& d : shape->items) {
    if (d.type != Literal::Type::kInt || d.negative || d.too_big) {
      return parser.Error(d.pos, "'shape' holds something other than non-negative integers");
    }
    dims.push_back(d.magnitude);
    has_zero = has_zero || d.magnitude == 0;
  }
  Layout layout;
  SHAPEID_RETURN_IF_ERROR(ParseDescr(*descr, ctx, &layout));

  const uint64_t shape_where = header_start + shape->pos;
  const std::string shape_text = ShapeText(dims);
  size_t lead_dims = dims.size();  // the dimensions that index points
  if (layout.structured) {
    if (dims.empty() || dims.size() > 2) {
      return Invalid(name, shape_where,
                     absl::StrCat("a structured array of shape ", shape_text,
                                  " is not a point array; expected (N,) or (H, W)"));
    }
  } else {
    if (dims.size() < 2 || dims.size() > 3) {
      return Invalid(name, shape_where,
                     absl::StrCat("shape ", shape_text,
                                  " is not a point array; expected (N, 3) or more columns (one "
                                  "point is (1, 3)), or (H, W, 3) for an organized cloud"));
    }
    if (dims.back() < 3) {
      return Invalid(
          name, shape_where,
          absl::StrCat("shape ", shape_text, " has ", dims.back(), " columns; x, y and z need 3"));
    }
    lead_dims = dims.size() - 1;
  }

  // Data size check first, so that every product below is bounded by the file size.
  const uint64_t data_offset = header_start + header_length;
  const absl::string_view data = contents.substr(data_offset);
  uint64_t elements = has_zero ? 0 : 1;
  bool overflow = false;
  for (uint64_t d : dims) overflow = overflow || (!has_zero && !MulCapped(elements, d, &elements));
  uint64_t needed = 0;
  overflow = overflow || !MulCapped(elements, layout.itemsize, &needed);
  if (overflow || needed != data.size()) {
    return Invalid(name, data_offset,
                   absl::StrCat("the data is ", data.size(), " bytes, but shape ", shape_text,
                                " of ", layout.dtype, " needs ",
                                overflow ? "more than 2^62" : absl::StrCat(needed), " bytes"));
  }
  CloudAccumulator cloud(name, "byte offset");
  if (elements == 0) return std::move(cloud).Finish(options);

  const uint64_t rows = dims[0];
  const uint64_t cols = lead_dims == 2 ? dims[1] : 1;  // an organized cloud's width
  const uint64_t points = rows * cols;
  const bool fortran_grid = fortran->truth && lead_dims == 2;
  // A point's values are at record * record_size + offset[axis].
  uint64_t record_size = layout.itemsize;
  uint64_t offset[3];
  for (int a = 0; a < 3; ++a) {
    const uint64_t axis = static_cast<uint64_t>(a);
    if (layout.structured) {
      offset[a] = layout.field_offset[a];
    } else if (fortran->truth) {  // all x, then all y, then all z
      offset[a] = axis * points * layout.itemsize;
    } else {
      offset[a] = axis * layout.itemsize;
    }
  }
  if (!layout.structured && !fortran->truth) record_size = dims.back() * layout.itemsize;
  const char* base = data.data();
  const Loader little_float = &Load<float, false>, big_float = &Load<float, true>;
  for (const Loader f32 : {little_float, big_float}) {
    if (fortran_grid || layout.load[0] != f32 || layout.load[1] != f32 || layout.load[2] != f32) {
      continue;
    }
    FloatColumns columns;
    for (int a = 0; a < 3; ++a) {
      columns.axis[a] = base + offset[a];
      columns.stride[a] = record_size;
    }
    columns.byte_swapped = (f32 == big_float) == (__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__);
    columns.where = data_offset + offset[0];
    columns.where_step = record_size;
    return ReadFloatColumns(columns, points, "byte offset", options);
  }
  const Loader little_double = &Load<double, false>;
  if (!fortran_grid && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__ &&
      layout.load[0] == little_double && layout.load[1] == little_double &&
      layout.load[2] == little_double) {  // '<f8', loaded inline rather than through `load`
    return ReadPointsTwice(
        points,
        [&](size_t p, double* xyz) {
          for (int a = 0; a < 3; ++a) std::memcpy(&xyz[a], base + p * record_size + offset[a], 8);
        },
        [&](size_t p) { return data_offset + p * record_size + offset[0]; }, name, "byte offset",
        options);
  }
  // Points go in C order; a Fortran-ordered (H, W) grid stores (h, w) at h + w * H.
  const auto at = [&](size_t p) {
    const uint64_t record = fortran_grid ? p / cols + (p % cols) * rows : p;
    return record * record_size;
  };
  return ReadPointsTwice(
      points,
      [&](size_t p, double* xyz) {
        const char* point = base + at(p);
        for (int a = 0; a < 3; ++a) xyz[a] = layout.load[a](point + offset[a]);
      },
      [&](size_t p) { return data_offset + at(p) + offset[0]; }, name, "byte offset", options);
}

// ---- .npz: the member holding the points ----

constexpr ZipHints kNpzHints{"a .npz file is a zip of .npy arrays",
                             "a .npz file holds .npy arrays"};

// The member holding the points, by name (see ParseNpz).
absl::StatusOr<const ZipMember*> ChooseMember(const std::vector<ZipMember>& members,
                                              absl::string_view name) {
  for (absl::string_view wanted : {"points.npy", "xyz.npy", "pcd.npy", "cloud.npy", "arr_0.npy"}) {
    for (const ZipMember& m : members) {
      if (m.name == wanted) return &m;
    }
  }
  if (members.size() == 1) return &members[0];
  std::string names;
  for (size_t i = 0; i < members.size() && i < 12; ++i) {
    absl::StrAppend(&names, i > 0 ? ", " : "", "\"", absl::CHexEscape(members[i].name), "\"");
  }
  if (members.size() > 12) absl::StrAppend(&names, ", ...");
  return Invalid(name, members[0].record,
                 absl::StrCat("the archive holds ", members.size(), " arrays (", names,
                              ") and none is named points.npy, xyz.npy, pcd.npy, cloud.npy or "
                              "arr_0.npy, the names looked for; save the points under one of "
                              "them, e.g. np.savez(file, points=array)"));
}

}  // namespace

absl::StatusOr<ReadResult> ParseNpy(absl::string_view contents, absl::string_view name,
                                    const ReadOptions& options) {
  if (IsZip(contents)) return ParseNpz(contents, name, options);
  return ParseNpyArray(contents, name, options);
}

absl::StatusOr<ReadResult> ParseNpz(absl::string_view contents, absl::string_view name,
                                    const ReadOptions& options) {
  if (contents.substr(0, kNpyMagic.size()) == kNpyMagic) {
    return ParseNpyArray(contents, name, options);
  }
  SHAPEID_ASSIGN_OR_RETURN(const std::vector<ZipMember> members,
                           ListZipMembers(contents, name, kNpzHints));
  SHAPEID_ASSIGN_OR_RETURN(const ZipMember* member, ChooseMember(members, name));
  std::string inflated;
  SHAPEID_ASSIGN_OR_RETURN(const absl::string_view bytes,
                           ReadZipMember(contents, *member, name, &inflated));
  return ParseNpyArray(bytes, ZipMemberLabel(name, *member), options);
}

}  // namespace shapeid
