#include "core/descriptor_registry.h"

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "core/descriptors/cnsd.h"
#include "core/descriptors/comsd.h"
#include "core/descriptors/dfsd.h"
#include "core/descriptors/learned.h"
#include "core/descriptors/rphsd.h"
#include "core/status_macros.h"

namespace shapeid {

const std::vector<DescriptorKind>& RegisteredDescriptors() {
  static const auto* const kinds = new std::vector<DescriptorKind>{
      RphsdKind(), ComsdKind(), CnsdKind(), DfsdKind(), LearnedKind(),
  };
  return *kinds;
}

const DescriptorKind* FindDescriptorKind(absl::string_view kind) {
  for (const DescriptorKind& entry : RegisteredDescriptors()) {
    if (entry.kind == kind) return &entry;
  }
  return nullptr;
}

namespace {

std::string KnownKinds() {
  std::vector<std::string> names;
  for (const DescriptorKind& entry : RegisteredDescriptors()) names.push_back(entry.kind);
  return absl::StrJoin(names, ", ");
}

std::string ParamNames(const DescriptorKind& entry) {
  std::vector<std::string> names;
  for (const DescriptorParam& p : entry.params) names.push_back(p.name);
  return names.empty() ? "none" : absl::StrJoin(names, ", ");
}

}  // namespace

absl::StatusOr<std::unique_ptr<Descriptor>> CreateDescriptor(const DescriptorSpec& spec) {
  const DescriptorKind* entry = FindDescriptorKind(spec.kind);
  if (entry == nullptr) {
    return absl::InvalidArgumentError(
        absl::StrCat("unknown descriptor \"", spec.kind, "\"; known: ", KnownKinds()));
  }
  for (const auto& [key, value] : spec.params) {
    bool known = false;
    for (const DescriptorParam& p : entry->params) known |= p.name == key;
    if (!known) {
      return absl::InvalidArgumentError(absl::StrCat(spec.kind, " has no parameter \"", key,
                                                     "\"; its parameters: ", ParamNames(*entry)));
    }
  }
  DescriptorSpec filled{spec.kind, {}};
  for (const DescriptorParam& p : entry->params) {
    const std::string* given = spec.Find(p.name);
    filled.params.emplace_back(p.name, given != nullptr ? *given : p.default_value);
  }
  return entry->create(filled);
}

absl::StatusOr<std::unique_ptr<Descriptor>> CreateDescriptor(absl::string_view spec_text) {
  SHAPEID_ASSIGN_OR_RETURN(DescriptorSpec spec, DescriptorSpec::Parse(spec_text));
  return CreateDescriptor(spec);
}

std::string DescribeRegistry() {
  std::string text;
  for (const DescriptorKind& entry : RegisteredDescriptors()) {
    absl::StrAppend(&text, entry.kind, ": ", entry.summary, "\n");
    for (const DescriptorParam& p : entry.params) {
      absl::StrAppend(&text, "  ", p.name, " (default ", p.default_value, "): ", p.help, "\n");
    }
  }
  return text;
}

}  // namespace shapeid
