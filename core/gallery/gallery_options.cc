#include "core/gallery/gallery_options.h"

#include <cmath>

#include "absl/strings/ascii.h"
#include "absl/strings/escaping.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"

namespace shapeid {

namespace {

constexpr absl::string_view kNamePattern = "[A-Za-z0-9][A-Za-z0-9_.-]{0,127}";

// The length of the valid UTF-8 sequence at the start of `s` (non-empty), or 0.
size_t Utf8SequenceLength(absl::string_view s) {
  const auto byte = [&](size_t i) { return static_cast<unsigned char>(s[i]); };
  const unsigned char b0 = byte(0);
  if (b0 < 0x80) return 1;
  size_t len;
  uint32_t min_code;
  uint32_t code;
  if ((b0 & 0xE0) == 0xC0) {
    len = 2, min_code = 0x80, code = b0 & 0x1F;
  } else if ((b0 & 0xF0) == 0xE0) {
    len = 3, min_code = 0x800, code = b0 & 0x0F;
  } else if ((b0 & 0xF8) == 0xF0) {
    len = 4, min_code = 0x10000, code = b0 & 0x07;
  } else {
    return 0;  // a continuation byte or 0xF8..0xFF
  }
  if (s.size() < len) return 0;
  for (size_t i = 1; i < len; ++i) {
    if ((byte(i) & 0xC0) != 0x80) return 0;
    code = (code << 6) | (byte(i) & 0x3F);
  }
  if (code < min_code || code > 0x10FFFF || (code >= 0xD800 && code <= 0xDFFF)) return 0;
  return len;
}

}  // namespace

std::string QuoteForMessage(absl::string_view text) {
  const bool cut = text.size() > 64;
  return absl::StrCat("\"", absl::CHexEscape(text.substr(0, 64)), cut ? "...\"" : "\"");
}

size_t InvalidUtf8Offset(absl::string_view text) {
  for (size_t i = 0; i < text.size();) {
    const size_t len = Utf8SequenceLength(text.substr(i));
    if (len == 0) return i;
    i += len;
  }
  return absl::string_view::npos;
}

absl::Status ValidateGalleryName(absl::string_view name) {
  const auto allowed = [](char c, bool first) {
    return absl::ascii_isalnum(static_cast<unsigned char>(c)) ||
           (!first && (c == '_' || c == '.' || c == '-'));
  };
  bool ok = !name.empty() && name.size() <= 128;
  for (size_t i = 0; ok && i < name.size(); ++i) ok = allowed(name[i], i == 0);
  if (ok) return absl::OkStatus();
  return absl::InvalidArgumentError(
      absl::StrCat("gallery name ", QuoteForMessage(name), " does not match ", kNamePattern,
                   " (a letter or digit, then up to 127 letters, digits, '_', '.' or '-')"));
}

absl::Status ValidateLabel(absl::string_view label) {
  if (label.empty()) return absl::InvalidArgumentError("label is empty");
  if (label.size() > kMaxLabelBytes) {
    return absl::InvalidArgumentError(absl::StrCat("label ", QuoteForMessage(label), " has ",
                                                   label.size(), " bytes, more than the limit of ",
                                                   kMaxLabelBytes));
  }
  if (const size_t bad = InvalidUtf8Offset(label); bad != absl::string_view::npos) {
    return absl::InvalidArgumentError(
        absl::StrCat("label ", QuoteForMessage(label), " is not valid UTF-8 (at byte ", bad, ")"));
  }
  if (label == kUnknownLabel) {
    return absl::InvalidArgumentError(
        absl::StrCat("label \"", kUnknownLabel,
                     "\" is reserved for rejected classifications; pick another name"));
  }
  return absl::OkStatus();
}

absl::Status ValidateGalleryOptions(const GalleryOptions& options) {
  if (absl::Status s = ValidateKnnOptions(options.knn); !s.ok()) return s;
  if (!std::isfinite(options.reject_distance) || options.reject_distance < 0) {
    return absl::InvalidArgumentError(absl::StrFormat(
        "reject_distance is %g; it must be a finite distance >= 0 (0 turns rejection off)",
        options.reject_distance));
  }
  return ValidateAugmentOptions(options.augment);
}

}  // namespace shapeid
