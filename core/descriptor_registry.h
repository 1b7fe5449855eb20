#ifndef SHAPEID_CORE_DESCRIPTOR_REGISTRY_H_
#define SHAPEID_CORE_DESCRIPTOR_REGISTRY_H_

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "core/descriptor.h"
#include "core/descriptor_spec.h"

namespace shapeid {

struct DescriptorParam {
  std::string name;
  std::string default_value;
  std::string help;  // one line: meaning, accepted values
  // The canonical spec leaves this parameter out while it is at its default. Only for a
  // parameter added after galleries were stored with the kind: their spec text, which
  // the store compares, stays the same.
  bool omitted_at_default = false;
};

// One registry entry. Adding a descriptor is one file pair in core/descriptors/ that defines
// an entry like this, plus one line in the table in descriptor_registry.cc.
struct DescriptorKind {
  std::string kind;                     // "rphsd"
  std::string summary;                  // one line for --help and ListDescriptors
  std::vector<DescriptorParam> params;  // canonical order
  // Builds the descriptor from a spec whose keys are all known and all present (defaults
  // filled). Returns InvalidArgument for values out of range.
  absl::StatusOr<std::unique_ptr<Descriptor>> (*create)(const DescriptorSpec& filled);
  // The algorithm's version. Bump it in the same commit as any change that alters the
  // output of some spec of this kind, even by one ulp: stored galleries record it, and a
  // server refuses to add to (or classify against) a gallery made by another version rather
  // than mix descriptors that are not comparable.
  uint32_t version = 1;
};

// The spec used wherever a caller names none (Describe without a spec, a new gallery, the
// CLI): DFSD at its defaults, 240 values. It beats the dissertation's RPHSD on both real
// datasets at the same 1-NN setting (ModelNet10 90.3 % vs 83.0 %, DALES 95.0 % vs 94.6 %,
// docs/accuracy.md) and, like every seed descriptor, ignores absolute scale. RPHSD at the
// dissertation's best settings is still "rphsd".
inline constexpr char kDefaultDescriptorSpec[] = "dfsd";

// Every registered kind, in registration order.
const std::vector<DescriptorKind>& RegisteredDescriptors();

// The entry for `kind`, or nullptr.
const DescriptorKind* FindDescriptorKind(absl::string_view kind);

// Checks `spec` against its kind's schema (unknown kind or parameter: InvalidArgument naming
// what is known), fills defaults and builds the descriptor. Its spec() is canonical.
absl::StatusOr<std::unique_ptr<Descriptor>> CreateDescriptor(const DescriptorSpec& spec);
absl::StatusOr<std::unique_ptr<Descriptor>> CreateDescriptor(absl::string_view spec_text);

// A multi-line human description of every kind and its parameters, for --help.
std::string DescribeRegistry();

}  // namespace shapeid

#endif  // SHAPEID_CORE_DESCRIPTOR_REGISTRY_H_
