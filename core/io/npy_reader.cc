#include "core/io/npy_reader.h"

#include <zlib.h>

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
#include "core/io/gzip.h"
#include "core/io/text_lines.h"
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

// ---- The header: a Python literal ----

// A Python literal, as much of the language as .npy headers use.
struct Literal {
  enum class Type { kString, kInt, kBool, kNone, kTuple, kList, kDict };
  Type type = Type::kNone;
  size_t pos = 0;              // where it starts in the header
  std::string text;            // kString
  uint64_t magnitude = 0;      // kInt: |value|, saturated
  bool negative = false;       // kInt
  bool too_big = false;        // kInt: |value| >= 2^64
  bool truth = false;          // kBool
  std::vector<Literal> items;  // kTuple, kList; kDict: key, value, key, value...
};

bool IsSpace(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\f'; }
bool IsDigit(char c) { return c >= '0' && c <= '9'; }
bool IsWordChar(char c) {
  return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_' || IsDigit(c);
}
int HexValue(char c) {
  if (IsDigit(c)) return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

void AppendUtf8(uint32_t code, std::string* out) {
  if (code < 0x80) {
    out->push_back(static_cast<char>(code));
  } else if (code < 0x800) {
    out->push_back(static_cast<char>(0xc0 | (code >> 6)));
    out->push_back(static_cast<char>(0x80 | (code & 0x3f)));
  } else if (code < 0x10000) {
    out->push_back(static_cast<char>(0xe0 | (code >> 12)));
    out->push_back(static_cast<char>(0x80 | ((code >> 6) & 0x3f)));
    out->push_back(static_cast<char>(0x80 | (code & 0x3f)));
  } else {
    out->push_back(static_cast<char>(0xf0 | (code >> 18)));
    out->push_back(static_cast<char>(0x80 | ((code >> 12) & 0x3f)));
    out->push_back(static_cast<char>(0x80 | ((code >> 6) & 0x3f)));
    out->push_back(static_cast<char>(0x80 | (code & 0x3f)));
  }
}

// Header text for messages: its first 40 bytes, quotes left as they are.
std::string Quote(absl::string_view text) {
  constexpr size_t kMax = 40;
  std::string out = "\"";
  for (const char c : text.substr(0, kMax)) {
    if (c == '"' || c == '\\' || c < ' ' || c > '~') {
      absl::StrAppend(&out, absl::CHexEscape(absl::string_view(&c, 1)));
    } else {
      out.push_back(c);
    }
  }
  return absl::StrCat(out, text.size() > kMax ? "...\"" : "\"");
}

// Parses the header's dict literal: strings (either quote, u/b/r prefixes, escapes),
// integers (Python 2's "3L" when long_ints), True, False, None, tuples, lists and dicts.
class LiteralParser {
 public:
  // `base` is the header's byte offset in the file, for messages.
  LiteralParser(absl::string_view header, uint64_t base, absl::string_view name, bool long_ints)
      : text_(header), base_(base), name_(name), long_ints_(long_ints) {}

  // One value, then only whitespace (numpy pads the header with spaces and a '\n').
  absl::StatusOr<Literal> Parse() {
    Literal value;
    SHAPEID_RETURN_IF_ERROR(Value(&value, 0));
    SkipSpace();
    if (pos_ < text_.size()) return SyntaxError("expected the end of the header");
    return value;
  }

  // An error about the header at `pos`.
  absl::Status Error(size_t pos, absl::string_view what) const {
    return Invalid(name_, base_ + pos, absl::StrCat("array header ", Quote(text_), ": ", what));
  }

 private:
  static constexpr int kMaxDepth = 32;

  // A syntax error at pos_, saying what is there.
  absl::Status SyntaxError(absl::string_view what) const {
    return Error(pos_,
                 absl::StrCat(what, ", found ",
                              AtEnd() ? "the end of the header" : Quote(text_.substr(pos_, 1))));
  }

  bool AtEnd() const { return pos_ >= text_.size(); }
  char Peek() const { return AtEnd() ? '\0' : text_[pos_]; }
  void SkipSpace() {
    while (!AtEnd() && IsSpace(text_[pos_])) ++pos_;
  }

  absl::Status Value(Literal* out, int depth) {
    if (depth > kMaxDepth) return SyntaxError("values nest deeper than 32 levels");
    SkipSpace();
    out->pos = pos_;
    const char c = Peek();
    if (c == '{') return Dict(out, depth);
    if (c == '(') return Sequence(')', out, depth);
    if (c == '[') return Sequence(']', out, depth);
    if (c == '\'' || c == '"') return String(false, out);
    if (IsDigit(c) || c == '-' || c == '+') return Int(out);
    if (!AtEnd() && IsWordChar(c)) {
      const size_t start = pos_;
      while (!AtEnd() && IsWordChar(text_[pos_])) ++pos_;
      const absl::string_view word = text_.substr(start, pos_ - start);
      if ((Peek() == '\'' || Peek() == '"') && word.size() == 1 &&
          absl::string_view("uUbBrR").find(word[0]) != absl::string_view::npos) {
        return String(word[0] == 'r' || word[0] == 'R', out);
      }
      if (word == "True" || word == "False") {
        out->type = Literal::Type::kBool;
        out->truth = word == "True";
        return absl::OkStatus();
      }
      if (word == "None") {
        out->type = Literal::Type::kNone;
        return absl::OkStatus();
      }
      return Error(start, absl::StrCat("unknown name ", Quote(word)));
    }
    return SyntaxError("expected a value");
  }

  absl::Status Int(Literal* out) {
    out->type = Literal::Type::kInt;
    if (Peek() == '-' || Peek() == '+') {
      out->negative = Peek() == '-';
      ++pos_;
      SkipSpace();
    }
    if (!IsDigit(Peek())) return SyntaxError("expected digits");
    while (IsDigit(Peek())) {
      const uint64_t digit = static_cast<uint64_t>(text_[pos_++] - '0');
      if (out->magnitude > (std::numeric_limits<uint64_t>::max() - digit) / 10) {
        out->too_big = true;
        out->magnitude = std::numeric_limits<uint64_t>::max();
      } else if (!out->too_big) {
        out->magnitude = out->magnitude * 10 + digit;
      }
    }
    if (long_ints_ && (Peek() == 'L' || Peek() == 'l')) ++pos_;
    return absl::OkStatus();
  }

  // Reads `digits` hex digits into *code.
  absl::Status Hex(int digits, uint32_t* code) {
    *code = 0;
    for (int i = 0; i < digits; ++i) {
      const int v = HexValue(Peek());
      if (v < 0) return SyntaxError("expected a hexadecimal digit in an escape");
      *code = (*code << 4) | static_cast<uint32_t>(v);
      ++pos_;
    }
    return absl::OkStatus();
  }

  absl::Status String(bool raw, Literal* out) {
    out->type = Literal::Type::kString;
    const char quote = text_[pos_++];
    while (true) {
      if (AtEnd() || Peek() == '\n') return SyntaxError("a string is not closed");
      const char c = text_[pos_++];
      if (c == quote) return absl::OkStatus();
      if (c != '\\') {
        out->text.push_back(c);
        continue;
      }
      if (AtEnd()) return SyntaxError("a string is not closed");
      const char e = text_[pos_++];
      if (raw) {
        out->text.push_back('\\');
        out->text.push_back(e);
        continue;
      }
      uint32_t code = 0;
      switch (e) {
        case '\n':
          break;
        case 'n':
          out->text.push_back('\n');
          break;
        case 't':
          out->text.push_back('\t');
          break;
        case 'r':
          out->text.push_back('\r');
          break;
        case 'x':
        case 'u':
        case 'U':
          SHAPEID_RETURN_IF_ERROR(Hex(e == 'x' ? 2 : e == 'u' ? 4 : 8, &code));
          if (code > 0x10ffff) return SyntaxError("a \\U escape beyond U+10FFFF");
          AppendUtf8(code, &out->text);
          break;
        default:
          if (e >= '0' && e <= '7') {  // octal, up to three digits
            code = static_cast<uint32_t>(e - '0');
            for (int i = 0; i < 2 && Peek() >= '0' && Peek() <= '7'; ++i) {
              code = code * 8 + static_cast<uint32_t>(text_[pos_++] - '0');
            }
            AppendUtf8(code, &out->text);
          } else if (e == '\\' || e == '\'' || e == '"') {
            out->text.push_back(e);
          } else {  // Python keeps unknown escapes as written
            out->text.push_back('\\');
            out->text.push_back(e);
          }
      }
    }
  }

  // A tuple or list; "(x)" without a comma is x itself, as in Python.
  absl::Status Sequence(char close, Literal* out, int depth) {
    out->type = close == ')' ? Literal::Type::kTuple : Literal::Type::kList;
    ++pos_;
    bool comma = false;
    SkipSpace();
    if (Peek() == close) {
      ++pos_;
      return absl::OkStatus();
    }
    while (true) {
      Literal item;
      SHAPEID_RETURN_IF_ERROR(Value(&item, depth + 1));
      out->items.push_back(std::move(item));
      SkipSpace();
      if (Peek() == ',') {
        ++pos_;
        comma = true;
        SkipSpace();
        if (Peek() == close) break;
      } else if (Peek() != close) {
        return SyntaxError(absl::StrCat("expected ',' or '", std::string(1, close), "'"));
      }
      if (Peek() == close) break;
    }
    ++pos_;
    if (close == ')' && !comma) {
      Literal inner = std::move(out->items[0]);
      *out = std::move(inner);
    }
    return absl::OkStatus();
  }

  absl::Status Dict(Literal* out, int depth) {
    out->type = Literal::Type::kDict;
    ++pos_;
    SkipSpace();
    if (Peek() == '}') {
      ++pos_;
      return absl::OkStatus();
    }
    while (true) {
      Literal key, value;
      SHAPEID_RETURN_IF_ERROR(Value(&key, depth + 1));
      SkipSpace();
      if (Peek() != ':') return SyntaxError("expected ':' after a dict key");
      ++pos_;
      SHAPEID_RETURN_IF_ERROR(Value(&value, depth + 1));
      out->items.push_back(std::move(key));
      out->items.push_back(std::move(value));
      SkipSpace();
      if (Peek() == ',') {
        ++pos_;
        SkipSpace();
      } else if (Peek() != '}') {
        return SyntaxError("expected ',' or '}'");
      }
      if (Peek() == '}') break;
    }
    ++pos_;
    return absl::OkStatus();
  }

  absl::string_view text_;
  uint64_t base_;
  absl::string_view name_;
  bool long_ints_;
  size_t pos_ = 0;
};

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
                                  "point is (1, 3)), or (H, W, 3) for an organised cloud"));
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
  const uint64_t cols = lead_dims == 2 ? dims[1] : 1;  // an organised cloud's width
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
  cloud.Reserve(points);
  const char* base = data.data();
  for (uint64_t p = 0; p < points; ++p) {
    // Points go in C order; a Fortran-ordered (H, W) grid stores (h, w) at h + w * H.
    const uint64_t record = fortran_grid ? p / cols + (p % cols) * rows : p;
    const uint64_t at = record * record_size;
    cloud.Add(layout.load[0](base + at + offset[0]), layout.load[1](base + at + offset[1]),
              layout.load[2](base + at + offset[2]), data_offset + at + offset[0]);
  }
  return std::move(cloud).Finish(options);
}

// ---- .npz: a zip archive ----

constexpr uint32_t kEndSignature = 0x06054b50;
constexpr uint32_t kZip64LocatorSignature = 0x07064b50;
constexpr uint32_t kZip64EndSignature = 0x06064b50;
constexpr uint32_t kCentralSignature = 0x02014b50;
constexpr uint32_t kLocalSignature = 0x04034b50;
constexpr uint64_t kEndSize = 22;
constexpr uint64_t kCentralSize = 46;
constexpr uint64_t kLocalSize = 30;
// Deflate emits at most 258 bytes per 2 bits: no stream inflates by more than this.
constexpr uint64_t kMaxDeflateRatio = 1032;

bool IsZip(absl::string_view contents) {
  return contents.substr(0, 4) == absl::string_view("PK\x03\x04", 4) ||
         contents.substr(0, 4) == absl::string_view("PK\x05\x06", 4);
}

struct ZipEntry {
  std::string name;
  uint64_t record = 0;  // where its central directory record starts
  uint32_t flags = 0;
  uint32_t method = 0;
  uint32_t crc = 0;
  uint64_t compressed = 0;
  uint64_t uncompressed = 0;
  uint64_t local = 0;  // its local header's offset
};

std::string MemberText(absl::string_view member) {
  return absl::StrCat("member \"", absl::CHexEscape(member), "\"");
}

// Fills the ZIP64 values of `e` (those stored as 0xFFFFFFFF) from its extra field.
absl::Status ReadZip64Extra(absl::string_view extra, uint64_t extra_at, absl::string_view name,
                            ZipEntry* e) {
  uint64_t* wanted[3] = {nullptr, nullptr, nullptr};
  int n = 0;
  for (uint64_t* v : {&e->uncompressed, &e->compressed, &e->local}) {
    if (*v == 0xffffffffu) wanted[n++] = v;
  }
  if (n == 0) return absl::OkStatus();
  for (size_t i = 0; i + 4 <= extra.size();) {
    const uint64_t id = Le(extra.data() + i, 2);
    const uint64_t size = Le(extra.data() + i + 2, 2);
    if (size > extra.size() - i - 4) break;
    if (id == 1) {
      if (size < 8 * static_cast<uint64_t>(n)) {
        return Invalid(name, extra_at + i,
                       absl::StrCat(MemberText(e->name), ": its ZIP64 extra field has ", size,
                                    " bytes, too few for its ", n, " 64-bit sizes"));
      }
      for (int k = 0; k < n; ++k) *wanted[k] = Le(extra.data() + i + 4 + 8 * k, 8);
      return absl::OkStatus();
    }
    i += 4 + size;
  }
  return Invalid(name, extra_at,
                 absl::StrCat(MemberText(e->name),
                              ": sizes or offset of 0xFFFFFFFF but no ZIP64 extra field"));
}

// Locates the central directory (through the ZIP64 records when present) and reads it.
absl::StatusOr<std::vector<ZipEntry>> ReadCentralDirectory(absl::string_view contents,
                                                           absl::string_view name) {
  const uint64_t n = contents.size();
  const char* d = contents.data();
  const uint64_t lowest = n < kEndSize ? 0 : n - kEndSize - std::min<uint64_t>(n - kEndSize, 65535);
  uint64_t end = n;
  for (uint64_t i = n < kEndSize ? 0 : n - kEndSize + 1; i-- > lowest;) {
    if (Le(d + i, 4) == kEndSignature && i + kEndSize + Le(d + i + 20, 2) <= n) {
      end = i;
      break;
    }
  }
  if (end == n) {
    return Invalid(name, lowest,
                   absl::StrCat("not a zip archive: no end-of-central-directory record ",
                                "(PK\\5\\6) in its last ", n - lowest,
                                " bytes; a .npz file is a zip of .npy arrays"));
  }
  uint64_t disk = Le(d + end + 4, 2), directory_disk = Le(d + end + 6, 2);
  uint64_t count = Le(d + end + 10, 2);
  uint64_t directory_size = Le(d + end + 12, 4), directory_offset = Le(d + end + 16, 4);
  uint64_t count_at = end + 10, directory_at = end + 12;
  if (end >= 20 && Le(d + end - 20, 4) == kZip64LocatorSignature) {
    const uint64_t locator = end - 20;
    const uint64_t z = Le(d + locator + 8, 8);
    if (Le(d + locator + 16, 4) > 1) {
      return Unimplemented(name, locator + 16,
                           "split (multi-disk) zip archives are not read; join them first");
    }
    if (z > n || n - z < 56) {
      return Invalid(name, locator + 8,
                     absl::StrCat("the ZIP64 locator points to offset ", z,
                                  ", past the end of the archive (", n, " bytes)"));
    }
    if (Le(d + z, 4) != kZip64EndSignature) {
      return Invalid(name, z,
                     absl::StrCat("expected the ZIP64 end-of-central-directory record ",
                                  "(PK\\6\\6), found ", QuoteForMessage(contents.substr(z, 4))));
    }
    disk = Le(d + z + 16, 4);
    directory_disk = Le(d + z + 20, 4);
    count = Le(d + z + 32, 8);
    directory_size = Le(d + z + 40, 8);
    directory_offset = Le(d + z + 48, 8);
    count_at = z + 32;
    directory_at = z + 40;
  }
  if (disk != 0 || directory_disk != 0) {
    return Unimplemented(name, end + 4,
                         "split (multi-disk) zip archives are not read; join them first");
  }
  if (directory_offset > n || directory_size > n - directory_offset) {
    return Invalid(
        name, directory_at,
        absl::StrCat("the central directory (", directory_size, " bytes at offset ",
                     directory_offset, ") runs past the end of the archive (", n, " bytes)"));
  }
  if (count == 0) {
    return Invalid(name, count_at, "the archive is empty; a .npz file holds .npy arrays");
  }
  std::vector<ZipEntry> entries;
  uint64_t pos = directory_offset;
  const uint64_t directory_end = directory_offset + directory_size;
  for (uint64_t i = 0; i < count; ++i) {
    if (directory_end - pos < kCentralSize) {
      return Invalid(
          name, pos,
          absl::StrCat("the central directory ends after ", i, " of its ", count, " entries"));
    }
    if (Le(d + pos, 4) != kCentralSignature) {
      return Invalid(name, pos,
                     absl::StrCat("expected a central directory entry (PK\\1\\2), found ",
                                  QuoteForMessage(contents.substr(pos, 4))));
    }
    ZipEntry e;
    e.record = pos;
    e.flags = static_cast<uint32_t>(Le(d + pos + 8, 2));
    e.method = static_cast<uint32_t>(Le(d + pos + 10, 2));
    e.crc = static_cast<uint32_t>(Le(d + pos + 16, 4));
    e.compressed = Le(d + pos + 20, 4);
    e.uncompressed = Le(d + pos + 24, 4);
    e.local = Le(d + pos + 42, 4);
    const uint64_t name_length = Le(d + pos + 28, 2);
    const uint64_t extra_length = Le(d + pos + 30, 2);
    const uint64_t comment_length = Le(d + pos + 32, 2);
    const uint64_t record_size = kCentralSize + name_length + extra_length + comment_length;
    if (record_size > directory_end - pos) {
      return Invalid(name, pos + 28,
                     absl::StrCat("central directory entry ", i, "'s name, extra field and ",
                                  "comment run past the end of the central directory"));
    }
    e.name = std::string(contents.substr(pos + kCentralSize, name_length));
    const uint64_t extra_at = pos + kCentralSize + name_length;
    SHAPEID_RETURN_IF_ERROR(
        ReadZip64Extra(contents.substr(extra_at, extra_length), extra_at, name, &e));
    entries.push_back(std::move(e));
    pos += record_size;
  }
  return entries;
}

// The member holding the points, by name (see ParseNpz).
absl::StatusOr<const ZipEntry*> ChooseMember(const std::vector<ZipEntry>& entries,
                                             absl::string_view name) {
  for (absl::string_view wanted : {"points.npy", "xyz.npy", "pcd.npy", "cloud.npy", "arr_0.npy"}) {
    for (const ZipEntry& e : entries) {
      if (e.name == wanted) return &e;
    }
  }
  if (entries.size() == 1) return &entries[0];
  std::string names;
  for (size_t i = 0; i < entries.size() && i < 12; ++i) {
    absl::StrAppend(&names, i > 0 ? ", " : "", "\"", absl::CHexEscape(entries[i].name), "\"");
  }
  if (entries.size() > 12) absl::StrAppend(&names, ", ...");
  return Invalid(name, entries[0].record,
                 absl::StrCat("the archive holds ", entries.size(), " arrays (", names,
                              ") and none is named points.npy, xyz.npy, pcd.npy, cloud.npy or "
                              "arr_0.npy, the names looked for; save the points under one of "
                              "them, e.g. np.savez(file, points=array)"));
}

absl::StatusOr<ReadResult> ReadMember(absl::string_view contents, absl::string_view name,
                                      const ZipEntry& e, const ReadOptions& options) {
  const uint64_t n = contents.size();
  const std::string member = MemberText(e.name);
  if ((e.flags & 1) != 0) {
    return Unimplemented(name, e.record + 8,
                         absl::StrCat(member, " is encrypted; encrypted archives are not read"));
  }
  if (e.method != 0 && e.method != 8) {
    const char* method = e.method == 9    ? " (deflate64)"
                         : e.method == 12 ? " (bzip2)"
                         : e.method == 14 ? " (LZMA)"
                         : e.method == 93 ? " (zstd)"
                         : e.method == 95 ? " (xz)"
                                          : "";
    return Unimplemented(name, e.record + 10,
                         absl::StrCat(member, " is compressed with method ", e.method, method,
                                      "; stored (0) and deflate (8), as numpy writes, are read"));
  }
  if (e.local > n || n - e.local < kLocalSize) {
    return Invalid(name, e.record + 42,
                   absl::StrCat(member, ": its local header offset ", e.local,
                                " is past the end of the archive (", n, " bytes)"));
  }
  const char* local = contents.data() + e.local;
  if (Le(local, 4) != kLocalSignature) {
    return Invalid(name, e.local,
                   absl::StrCat(member, ": expected a local file header (PK\\3\\4), found ",
                                QuoteForMessage(contents.substr(e.local, 4))));
  }
  const uint64_t name_length = Le(local + 26, 2);
  const uint64_t data_start = e.local + kLocalSize + name_length + Le(local + 28, 2);
  if (data_start > n) {
    return Invalid(name, e.local + 26,
                   absl::StrCat(member, ": its local header runs past the end of the archive"));
  }
  if (contents.substr(e.local + kLocalSize, name_length) != e.name) {
    return Invalid(
        name, e.local + kLocalSize,
        absl::StrCat(member, ": its local header names it ",
                     QuoteForMessage(contents.substr(e.local + kLocalSize, name_length))));
  }
  if (e.compressed > n - data_start) {
    return Invalid(name, e.record + 20,
                   absl::StrCat(member, ": its ", e.compressed, " bytes at offset ", data_start,
                                " run past the end of the archive (", n, " bytes)"));
  }
  const absl::string_view raw = contents.substr(data_start, e.compressed);
  const std::string label = absl::StrCat(name, ":", absl::CHexEscape(e.name));
  std::string inflated;
  absl::string_view bytes = raw;
  if (e.method == 0) {
    if (e.uncompressed != e.compressed) {
      return Invalid(name, e.record + 20,
                     absl::StrCat(member, " is stored, yet its sizes differ (", e.compressed,
                                  " bytes stored, ", e.uncompressed, " bytes uncompressed)"));
    }
  } else {
    if (e.uncompressed > e.compressed * kMaxDeflateRatio + kMaxDeflateRatio) {
      return Invalid(name, e.record + 24,
                     absl::StrCat(member, " claims ", e.uncompressed, " bytes from ", e.compressed,
                                  " deflated bytes, more than deflate can ", "reach (1032:1)"));
    }
    SHAPEID_ASSIGN_OR_RETURN(inflated, InflateRaw(raw, e.uncompressed, label));
    bytes = inflated;
  }
  const uint32_t crc =
      static_cast<uint32_t>(crc32_z(0, reinterpret_cast<const Bytef*>(bytes.data()), bytes.size()));
  if (crc != e.crc) {
    return Invalid(name, e.record + 16,
                   absl::StrCat(member, ": its data's CRC-32 is 0x",
                                absl::Hex(crc, absl::kZeroPad8), ", the archive records 0x",
                                absl::Hex(e.crc, absl::kZeroPad8), " (the archive is corrupt)"));
  }
  return ParseNpyArray(bytes, label, options);
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
  SHAPEID_ASSIGN_OR_RETURN(const std::vector<ZipEntry> entries,
                           ReadCentralDirectory(contents, name));
  SHAPEID_ASSIGN_OR_RETURN(const ZipEntry* member, ChooseMember(entries, name));
  return ReadMember(contents, name, *member, options);
}

}  // namespace shapeid
