#ifndef SHAPEID_CORE_IO_TEXT_LINES_H_
#define SHAPEID_CORE_IO_TEXT_LINES_H_

#include <charconv>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>
#include <system_error>

#include "absl/strings/escaping.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"

namespace shapeid {

// Internal to core/io: the text scanning that the PCD header, PCD ascii data and XYZ readers
// share. Works on views into one buffer, allocating nothing.

inline bool IsBlank(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }

// Yields the lines of `text` without their '\n' (a trailing '\r' is left to the tokenizers,
// which treat it as blank), numbering them from `first_line`.
class LineReader {
 public:
  explicit LineReader(absl::string_view text, uint64_t first_line = 1)
      : text_(text), next_line_(first_line) {}

  // Stores the next line and returns true, or returns false at the end of the text.
  bool Next(absl::string_view* line) {
    if (pos_ >= text_.size()) return false;
    const size_t end = text_.find('\n', pos_);
    const size_t stop = end == absl::string_view::npos ? text_.size() : end;
    *line = text_.substr(pos_, stop - pos_);
    pos_ = end == absl::string_view::npos ? text_.size() : end + 1;
    line_ = next_line_++;
    return true;
  }
  // The number of the line last returned.
  uint64_t line_number() const { return line_; }
  // Offset in the text just past the line last returned (and its '\n').
  size_t offset() const { return pos_; }

 private:
  absl::string_view text_;
  size_t pos_ = 0;
  uint64_t line_ = 0;
  uint64_t next_line_;
};

// The line with a '#' comment removed and blanks trimmed; empty for blank and comment lines.
inline absl::string_view StripComment(absl::string_view line) {
  const size_t hash = line.find('#');
  if (hash != absl::string_view::npos) line = line.substr(0, hash);
  while (!line.empty() && IsBlank(line.front())) line.remove_prefix(1);
  while (!line.empty() && IsBlank(line.back())) line.remove_suffix(1);
  return line;
}

// Splits a line into tokens separated by runs of blanks and/or of `separator` (none if '\0').
// With ',', "1, 2 ,3" gives 1 2 3 and "1,,3" gives 1 and 3: a doubled separator is not an
// empty field, because point files have no optional fields.
class Tokenizer {
 public:
  explicit Tokenizer(absl::string_view line, char separator = '\0')
      : begin_(line.data()), end_(line.data() + line.size()), separator_(separator) {}

  bool Next(absl::string_view* token) {
    while (begin_ != end_ && IsSeparator(*begin_)) ++begin_;
    if (begin_ == end_) return false;
    const char* start = begin_;
    while (begin_ != end_ && !IsSeparator(*begin_)) ++begin_;
    *token = absl::string_view(start, static_cast<size_t>(begin_ - start));
    return true;
  }

 private:
  // Hot: called per character, so no string searches here.
  bool IsSeparator(char c) const { return IsBlank(c) || (c == separator_ && c != '\0'); }

  const char* begin_;
  const char* end_;
  char separator_;
};

// `text` quoted for an error message: escaped (a binary file's bytes stay printable) and cut
// at 40 characters.
inline std::string QuoteForMessage(absl::string_view text) {
  constexpr size_t kMax = 40;
  const bool cut = text.size() > kMax;
  return absl::StrCat("\"", absl::CHexEscape(text.substr(0, kMax)), cut ? "...\"" : "\"");
}

// absl::SimpleAtod's syntax and values (a leading '+', surrounding blanks, inf and nan in any
// case, overflow to infinity), at std::from_chars's speed: the plain finite decimals that fill
// real files take the fast path, everything else goes to SimpleAtod itself, so that what is
// accepted and the value read are the same. Both round correctly.
inline bool ParseDouble(absl::string_view token, double* out) {
  const char* end = token.data() + token.size();
  double value = 0;
  const std::from_chars_result r = std::from_chars(token.data(), end, value);
  if (r.ec == std::errc() && r.ptr == end && std::isfinite(value)) {
    *out = value;
    return true;
  }
  return absl::SimpleAtod(token, out);
}

}  // namespace shapeid

#endif  // SHAPEID_CORE_IO_TEXT_LINES_H_
