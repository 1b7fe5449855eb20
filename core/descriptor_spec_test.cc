#include "core/descriptor_spec.h"

#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;
using ::testing::Pair;

TEST(DescriptorSpecTest, ParsesKindAndParametersInOrder) {
  const auto spec = DescriptorSpec::Parse(" RPHSD : refs = cubic27 , bins=100 ");
  ASSERT_TRUE(spec.ok()) << spec.status();
  EXPECT_EQ(spec->kind, "rphsd");
  EXPECT_THAT(spec->params, ::testing::ElementsAre(Pair("refs", "cubic27"), Pair("bins", "100")));
  EXPECT_EQ(spec->ToString(), "rphsd:refs=cubic27,bins=100");
  ASSERT_NE(spec->Find("bins"), nullptr);
  EXPECT_EQ(*spec->Find("bins"), "100");
  EXPECT_EQ(spec->Find("variant"), nullptr);
}

TEST(DescriptorSpecTest, KindAloneAndBracketedValues) {
  const auto bare = DescriptorSpec::Parse("comsd");
  ASSERT_TRUE(bare.ok());
  EXPECT_EQ(bare->kind, "comsd");
  EXPECT_TRUE(bare->params.empty());
  EXPECT_EQ(bare->ToString(), "comsd");

  // Commas inside [...] belong to the value; a ':' inside a value is kept.
  const auto custom = DescriptorSpec::Parse("rphsd:refs=[0,0,0;1,0,0],bins=4,x=fibonacci:9");
  ASSERT_TRUE(custom.ok()) << custom.status();
  EXPECT_THAT(custom->params, ::testing::ElementsAre(Pair("refs", "[0,0,0;1,0,0]"),
                                                     Pair("bins", "4"), Pair("x", "fibonacci:9")));
  const auto again = DescriptorSpec::Parse(custom->ToString());
  ASSERT_TRUE(again.ok());
  EXPECT_EQ(*again, *custom);
}

TEST(DescriptorSpecTest, SyntaxErrorsQuoteTheProblem) {
  for (const auto& [text, message] : std::vector<std::pair<std::string, std::string>>{
           {"", "must start with a kind"},
           {":bins=3", "must start with a kind"},
           {"rph sd", "must start with a kind"},
           {"rphsd:bins", "\"bins\" in \"rphsd:bins\" is not of the form key=value"},
           {"rphsd:bins=", "parameter bins in \"rphsd:bins=\" has an empty value"},
           {"rphsd:=3", "parameter name \"\""},
           {"rphsd:bins=3,bins=4", "parameter bins is given twice"},
           {"rphsd:refs=[0,0,0", "unclosed '['"},
           {"rphsd:refs=0,0]", "unbalanced ']'"},
       }) {
    const auto spec = DescriptorSpec::Parse(text);
    ASSERT_FALSE(spec.ok()) << text;
    EXPECT_EQ(spec.status().code(), absl::StatusCode::kInvalidArgument);
    EXPECT_THAT(spec.status().message(), HasSubstr(message)) << text;
  }
}

TEST(SpecParamsTest, TypedAccessWithRangesAndChoices) {
  const DescriptorSpec spec{"k", {{"n", "12"}, {"x", "0.25"}, {"mode", "Fast"}, {"bad", "1e999"}}};
  const SpecParams params(spec);
  EXPECT_EQ(*params.Int("n", 1, 100), 12);
  EXPECT_THAT(params.Int("n", 13, 100).status().message(),
              HasSubstr("k: n=12 is outside [13, 100]"));
  EXPECT_THAT(params.Int("x", 0, 1).status().message(), HasSubstr("x=0.25 is not an integer"));
  EXPECT_DOUBLE_EQ(*params.Double("x", 0, 1), 0.25);
  EXPECT_THAT(params.Double("bad", 0, 1).status().message(), HasSubstr("is not a finite number"));
  enum class Mode { kSlow, kFast, kA, kB };
  constexpr EnumNames<Mode, 2> kSpeeds = {{{Mode::kSlow, "slow"}, {Mode::kFast, "fast"}}};
  constexpr EnumNames<Mode, 2> kLetters = {{{Mode::kA, "a"}, {Mode::kB, "b"}}};
  EXPECT_EQ(*params.Choice("mode", kSpeeds), Mode::kFast);
  EXPECT_THAT(params.Choice("mode", kLetters).status().message(),
              HasSubstr("mode=Fast is not one of a, b"));
  EXPECT_EQ(params.Text("missing").status().code(), absl::StatusCode::kInternal);
}

}  // namespace
}  // namespace shapeid
