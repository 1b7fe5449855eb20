#ifndef SHAPEID_CORE_ENUM_NAMES_H_
#define SHAPEID_CORE_ENUM_NAMES_H_

// One table per enumeration, the only place its values and their names are written: the name
// of a value, the value of a name and the list of names for an error message all read it, so
// a new value cannot be printable but not parseable (or listed in one message and not another).
//
//   constexpr EnumNames<Color, 2> kColorNames = {{{Color::kRed, "red"}, {Color::kBlue,
//   "blue"}}}; NameOf(kColorNames, Color::kRed)   -> "red" ValueNamed(kColorNames, " Blue ") ->
//   Color::kBlue NameList(kColorNames)               -> "red, blue"

#include <array>
#include <cstddef>
#include <optional>
#include <string>

#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/string_view.h"

namespace shapeid {

template <typename Enum>
struct EnumName {
  Enum value;
  absl::string_view name;  // lower case; the canonical spelling
};

template <typename Enum, size_t N>
using EnumNames = std::array<EnumName<Enum>, N>;

// The name of `value`, or `fallback` for a value the table lacks (an integer cast to the enum).
template <typename Enum, size_t N>
constexpr absl::string_view NameOf(const EnumNames<Enum, N>& table, Enum value,
                                   absl::string_view fallback = "unknown") {
  for (const EnumName<Enum>& entry : table) {
    if (entry.value == value) return entry.name;
  }
  return fallback;
}

// The value whose name is `text`, ignoring ASCII case and surrounding white space.
template <typename Enum, size_t N>
std::optional<Enum> ValueNamed(const EnumNames<Enum, N>& table, absl::string_view text) {
  text = absl::StripAsciiWhitespace(text);
  for (const EnumName<Enum>& entry : table) {
    if (absl::EqualsIgnoreCase(entry.name, text)) return entry.value;
  }
  return std::nullopt;
}

// "a, b, c": the names in the table's order.
template <typename Enum, size_t N>
std::string NameList(const EnumNames<Enum, N>& table) {
  std::string list;
  for (const EnumName<Enum>& entry : table) {
    if (!list.empty()) list += ", ";
    list.append(entry.name.data(), entry.name.size());
  }
  return list;
}

}  // namespace shapeid

#endif  // SHAPEID_CORE_ENUM_NAMES_H_
