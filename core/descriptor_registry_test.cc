#include "core/descriptor_registry.h"

#include <set>

#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;

TEST(DescriptorRegistryTest, OffersTheSeedDescriptorsAndDfsdWithDocumentedParameters) {
  std::set<std::string> kinds;
  for (const DescriptorKind& kind : RegisteredDescriptors()) {
    kinds.insert(kind.kind);
    EXPECT_FALSE(kind.summary.empty()) << kind.kind;
    for (const DescriptorParam& p : kind.params) {
      EXPECT_FALSE(p.default_value.empty()) << kind.kind << "." << p.name;
      EXPECT_FALSE(p.help.empty()) << kind.kind << "." << p.name;
    }
    EXPECT_EQ(FindDescriptorKind(kind.kind), &kind);
  }
  EXPECT_EQ(kinds, (std::set<std::string>{"rphsd", "comsd", "cnsd", "dfsd", "learned"}));
  EXPECT_EQ(FindDescriptorKind("esf"), nullptr);
}

TEST(DescriptorRegistryTest, EveryKindBuildsFromDefaultsWithACanonicalSpec) {
  for (const DescriptorKind& kind : RegisteredDescriptors()) {
    const auto d = CreateDescriptor(kind.kind);
    ASSERT_TRUE(d.ok()) << kind.kind << ": " << d.status();
    EXPECT_EQ((*d)->spec().kind, kind.kind);
    // The kind's parameters in order; one that a kind added later may be left out at its
    // default (dfsd's up), so that older canonical specs keep their text.
    size_t next = 0;
    for (const auto& [name, value] : (*d)->spec().params) {
      while (next < kind.params.size() && kind.params[next].name != name) {
        EXPECT_TRUE(kind.params[next].omitted_at_default)
            << kind.kind << "." << kind.params[next].name;
        ++next;
      }
      ASSERT_LT(next, kind.params.size()) << kind.kind << ": " << name << " out of order";
      EXPECT_EQ(value, kind.params[next].default_value) << kind.kind << "." << name;
      ++next;
    }
    EXPECT_GT((*d)->dimension(), 0u);
    // Canonical text is a fixed point.
    const auto again = CreateDescriptor((*d)->spec().ToString());
    ASSERT_TRUE(again.ok()) << again.status();
    EXPECT_EQ((*again)->spec(), (*d)->spec());
  }
}

TEST(DescriptorRegistryTest, UnknownKindsAndParametersAreNamed) {
  const auto unknown = CreateDescriptor("esf:bins=3");
  EXPECT_EQ(unknown.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(unknown.status().message(),
              HasSubstr("unknown descriptor \"esf\"; known: rphsd, comsd, cnsd"));
  const auto bad_param = CreateDescriptor("comsd:size=3");
  EXPECT_THAT(bad_param.status().message(), HasSubstr("comsd has no parameter \"size\""));
  EXPECT_EQ(CreateDescriptor("rphsd:bins=").status().code(), absl::StatusCode::kInvalidArgument);
}

TEST(DescriptorRegistryTest, DescribeRegistryListsKindsAndParameters) {
  const std::string text = DescribeRegistry();
  for (const DescriptorKind& kind : RegisteredDescriptors()) {
    EXPECT_THAT(text, HasSubstr(kind.kind + ": "));
    for (const DescriptorParam& p : kind.params) {
      EXPECT_THAT(text, HasSubstr("  " + p.name + " (default " + p.default_value + ")"));
    }
  }
}

}  // namespace
}  // namespace shapeid
