#ifndef SHAPEID_CORE_DESCRIPTOR_SPEC_H_
#define SHAPEID_CORE_DESCRIPTOR_SPEC_H_

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "absl/types/span.h"
#include "core/enum_names.h"

namespace shapeid {

// A descriptor kind and its parameters, in the text form users type:
//   rphsd:refs=cubic27,bins=100,variant=complete
//   comsd:grid=50
//   rphsd:refs=[0,0,0;1,0,0;0,1,0]      (brackets group commas inside one value)
// The kind comes before the first ':'; parameters are `key=value` separated by commas.
// Parsing only checks syntax; which keys and values a kind accepts is the registry's job
// (core/descriptor_registry.h), which also produces the canonical form.
struct DescriptorSpec {
  std::string kind;
  std::vector<std::pair<std::string, std::string>> params;  // in the order given

  // Syntax errors are InvalidArgument and quote the offending part.
  static absl::StatusOr<DescriptorSpec> Parse(absl::string_view text);

  // "kind" or "kind:k1=v1,k2=v2", parameters in stored order. Parse(ToString()) round-trips.
  std::string ToString() const;

  // The value of `key`, or nullptr when absent.
  const std::string* Find(absl::string_view key) const;

  friend bool operator==(const DescriptorSpec& a, const DescriptorSpec& b) {
    return a.kind == b.kind && a.params == b.params;
  }
};

// The shortest text that reads back as exactly `value` (%.Ng with the least N), never "-0":
// the canonical form of a real-valued parameter.
std::string FormatSpecNumber(double value);

// Typed access to a spec whose parameters have all been checked against the kind's schema
// and filled with defaults. Every error names the kind, the parameter and the bad value.
class SpecParams {
 public:
  explicit SpecParams(const DescriptorSpec& spec) : spec_(spec) {}

  absl::StatusOr<int64_t> Int(absl::string_view key, int64_t min, int64_t max) const;
  absl::StatusOr<double> Double(absl::string_view key, double min, double max) const;
  // The value named in `names` (core/enum_names.h); an error lists the names.
  template <typename Enum, size_t N>
  absl::StatusOr<Enum> Choice(absl::string_view key, const EnumNames<Enum, N>& names) const {
    std::array<absl::string_view, N> choices;
    for (size_t i = 0; i < N; ++i) choices[i] = names[i].name;
    auto name = ChoiceOf(key, choices);
    if (!name.ok()) return name.status();
    return *ValueNamed(names, *name);
  }
  // The raw text (for values with their own grammar, like reference arrangements).
  absl::StatusOr<std::string> Text(absl::string_view key) const;

 private:
  absl::StatusOr<std::string> ChoiceOf(absl::string_view key,
                                       absl::Span<const absl::string_view> choices) const;

  const DescriptorSpec& spec_;
};

}  // namespace shapeid

#endif  // SHAPEID_CORE_DESCRIPTOR_SPEC_H_
