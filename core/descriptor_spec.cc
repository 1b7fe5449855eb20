#include "core/descriptor_spec.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>

#include "absl/strings/ascii.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"

namespace shapeid {
namespace {

bool IsNameChar(char c) {
  return absl::ascii_isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-';
}

bool IsName(absl::string_view s) {
  if (s.empty()) return false;
  for (char c : s) {
    if (!IsNameChar(c)) return false;
  }
  return true;
}

// Splits on commas that are not inside [...].
absl::StatusOr<std::vector<absl::string_view>> SplitTopLevel(absl::string_view text) {
  std::vector<absl::string_view> parts;
  int depth = 0;
  size_t start = 0;
  for (size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (c == '[') {
      ++depth;
    } else if (c == ']') {
      if (--depth < 0) {
        return absl::InvalidArgumentError(
            absl::StrCat("unbalanced ']' at offset ", i, " in \"", text, "\""));
      }
    } else if (c == ',' && depth == 0) {
      parts.push_back(text.substr(start, i - start));
      start = i + 1;
    }
  }
  if (depth != 0) {
    return absl::InvalidArgumentError(absl::StrCat("unclosed '[' in \"", text, "\""));
  }
  parts.push_back(text.substr(start));
  return parts;
}

}  // namespace

absl::StatusOr<DescriptorSpec> DescriptorSpec::Parse(absl::string_view text) {
  text = absl::StripAsciiWhitespace(text);
  DescriptorSpec spec;
  const size_t colon = text.find(':');
  const absl::string_view kind = absl::StripAsciiWhitespace(text.substr(0, colon));
  if (!IsName(kind)) {
    return absl::InvalidArgumentError(absl::StrCat(
        "descriptor spec \"", text, "\" must start with a kind such as rphsd, comsd or cnsd"));
  }
  spec.kind = absl::AsciiStrToLower(kind);
  if (colon == absl::string_view::npos) return spec;

  auto parts = SplitTopLevel(text.substr(colon + 1));
  if (!parts.ok()) return parts.status();
  for (absl::string_view part : *parts) {
    part = absl::StripAsciiWhitespace(part);
    const size_t eq = part.find('=');
    if (eq == absl::string_view::npos) {
      return absl::InvalidArgumentError(
          absl::StrCat("parameter \"", part, "\" in \"", text, "\" is not of the form key=value"));
    }
    const absl::string_view key = absl::StripAsciiWhitespace(part.substr(0, eq));
    const absl::string_view value = absl::StripAsciiWhitespace(part.substr(eq + 1));
    if (!IsName(key)) {
      return absl::InvalidArgumentError(
          absl::StrCat("parameter name \"", key, "\" in \"", text, "\" is not a valid name"));
    }
    if (value.empty()) {
      return absl::InvalidArgumentError(
          absl::StrCat("parameter ", key, " in \"", text, "\" has an empty value"));
    }
    const std::string lower_key = absl::AsciiStrToLower(key);
    if (spec.Find(lower_key) != nullptr) {
      return absl::InvalidArgumentError(
          absl::StrCat("parameter ", lower_key, " is given twice in \"", text, "\""));
    }
    spec.params.emplace_back(lower_key, std::string(value));
  }
  return spec;
}

std::string DescriptorSpec::ToString() const {
  if (params.empty()) return kind;
  return absl::StrCat(kind, ":", absl::StrJoin(params, ",", absl::PairFormatter("=")));
}

const std::string* DescriptorSpec::Find(absl::string_view key) const {
  for (const auto& [k, v] : params) {
    if (k == key) return &v;
  }
  return nullptr;
}

absl::StatusOr<std::string> SpecParams::Text(absl::string_view key) const {
  const std::string* value = spec_.Find(key);
  if (value == nullptr) {
    return absl::InternalError(absl::StrCat(spec_.kind, ": parameter ", key, " has no value"));
  }
  return *value;
}

absl::StatusOr<int64_t> SpecParams::Int(absl::string_view key, int64_t min, int64_t max) const {
  auto text = Text(key);
  if (!text.ok()) return text.status();
  int64_t value = 0;
  if (!absl::SimpleAtoi(*text, &value)) {
    return absl::InvalidArgumentError(
        absl::StrCat(spec_.kind, ": ", key, "=", *text, " is not an integer"));
  }
  if (value < min || value > max) {
    return absl::InvalidArgumentError(
        absl::StrCat(spec_.kind, ": ", key, "=", value, " is outside [", min, ", ", max, "]"));
  }
  return value;
}

absl::StatusOr<double> SpecParams::Double(absl::string_view key, double min, double max) const {
  auto text = Text(key);
  if (!text.ok()) return text.status();
  double value = 0;
  if (!absl::SimpleAtod(*text, &value) || !std::isfinite(value)) {
    return absl::InvalidArgumentError(
        absl::StrCat(spec_.kind, ": ", key, "=", *text, " is not a finite number"));
  }
  if (value < min || value > max) {
    return absl::InvalidArgumentError(
        absl::StrCat(spec_.kind, ": ", key, "=", *text, " is outside [", min, ", ", max, "]"));
  }
  return value;
}

absl::StatusOr<std::string> SpecParams::ChoiceOf(
    absl::string_view key, absl::Span<const absl::string_view> choices) const {
  auto text = Text(key);
  if (!text.ok()) return text.status();
  const std::string lower = absl::AsciiStrToLower(*text);
  for (absl::string_view choice : choices) {
    if (lower == choice) return std::string(choice);
  }
  return absl::InvalidArgumentError(absl::StrCat(spec_.kind, ": ", key, "=", *text,
                                                 " is not one of ", absl::StrJoin(choices, ", ")));
}

std::string FormatSpecNumber(double value) {
  if (value == 0) value = 0;  // no "-0"
  char buffer[32];
  for (int precision = 1; precision <= 17; ++precision) {
    std::snprintf(buffer, sizeof(buffer), "%.*g", precision, value);
    if (std::strtod(buffer, nullptr) == value) break;
  }
  return buffer;
}

}  // namespace shapeid
