#include "core/enum_names.h"

#include "gtest/gtest.h"

namespace shapeid {
namespace {

enum class Colour { kRed, kGreen, kBlue };

constexpr EnumNames<Colour, 3> kColourNames = {{
    {Colour::kRed, "red"},
    {Colour::kGreen, "green"},
    {Colour::kBlue, "blue"},
}};

TEST(EnumNamesTest, NameOfEveryValueReadsBackAsThatValue) {
  for (const EnumName<Colour>& entry : kColourNames) {
    EXPECT_EQ(ValueNamed(kColourNames, NameOf(kColourNames, entry.value)), entry.value);
  }
}

TEST(EnumNamesTest, NameOfAValueOutsideTheTableIsTheFallback) {
  const auto stray = static_cast<Colour>(7);
  EXPECT_EQ(NameOf(kColourNames, stray), "unknown");
  EXPECT_EQ(NameOf(kColourNames, stray, "?"), "?");
}

TEST(EnumNamesTest, ValueNamedIgnoresCaseAndSurroundingSpaceOnly) {
  EXPECT_EQ(ValueNamed(kColourNames, " GREEN\t"), Colour::kGreen);
  EXPECT_EQ(ValueNamed(kColourNames, "Blue"), Colour::kBlue);
  EXPECT_EQ(ValueNamed(kColourNames, "gre en"), std::nullopt);
  EXPECT_EQ(ValueNamed(kColourNames, "redd"), std::nullopt);
  EXPECT_EQ(ValueNamed(kColourNames, ""), std::nullopt);
}

TEST(EnumNamesTest, NameListKeepsTheTablesOrder) {
  EXPECT_EQ(NameList(kColourNames), "red, green, blue");
}

TEST(EnumNamesTest, NameOfIsAConstantExpression) {
  static_assert(NameOf(kColourNames, Colour::kBlue) == "blue");
}

}  // namespace
}  // namespace shapeid
