#ifndef SHAPEID_CORE_IO_NPY_HEADER_H_
#define SHAPEID_CORE_IO_NPY_HEADER_H_

// Internal to core/io (the .npy reader): the Python literal that a .npy file's header holds,
// parsed without Python. Errors are InvalidArgument, "<name>: byte offset N: array header
// "<its first 40 bytes>": <what>", N being the offset in the file.

#include <cstdint>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/escaping.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"
#include "core/status_macros.h"

namespace shapeid {
namespace npy_internal {

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

inline bool IsSpace(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\f'; }
inline bool IsDigit(char c) { return c >= '0' && c <= '9'; }
inline bool IsWordChar(char c) {
  return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_' || IsDigit(c);
}
inline int HexValue(char c) {
  if (IsDigit(c)) return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

inline void AppendUtf8(uint32_t code, std::string* out) {
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
inline std::string Quote(absl::string_view text) {
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
    return absl::InvalidArgumentError(absl::StrCat(name_, ": byte offset ", base_ + pos,
                                                   ": array header ", Quote(text_), ": ", what));
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

}  // namespace npy_internal
}  // namespace shapeid

#endif  // SHAPEID_CORE_IO_NPY_HEADER_H_
