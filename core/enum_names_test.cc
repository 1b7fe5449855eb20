#include "core/enum_names.h"

#include "gtest/gtest.h"

namespace shapeid {
namespace {

enum class Color { kRed, kGreen, kBlue };

constexpr EnumNames<Color, 3> kColorNames = {{
    {Color::kRed, "red"},
    {Color::kGreen, "green"},
    {Color::kBlue, "blue"},
}};

TEST(EnumNamesTest, NameOfEveryValueReadsBackAsThatValue) {
  for (const EnumName<Color>& entry : kColorNames) {
    EXPECT_EQ(ValueNamed(kColorNames, NameOf(kColorNames, entry.value)), entry.value);
  }
}

TEST(EnumNamesTest, NameOfAValueOutsideTheTableIsTheFallback) {
  const auto stray = static_cast<Color>(7);
  EXPECT_EQ(NameOf(kColorNames, stray), "unknown");
  EXPECT_EQ(NameOf(kColorNames, stray, "?"), "?");
}

TEST(EnumNamesTest, ValueNamedIgnoresCaseAndSurroundingSpaceOnly) {
  EXPECT_EQ(ValueNamed(kColorNames, " GREEN\t"), Color::kGreen);
  EXPECT_EQ(ValueNamed(kColorNames, "Blue"), Color::kBlue);
  EXPECT_EQ(ValueNamed(kColorNames, "gre en"), std::nullopt);
  EXPECT_EQ(ValueNamed(kColorNames, "redd"), std::nullopt);
  EXPECT_EQ(ValueNamed(kColorNames, ""), std::nullopt);
}

TEST(EnumNamesTest, NameListKeepsTheTablesOrder) {
  EXPECT_EQ(NameList(kColorNames), "red, green, blue");
}

TEST(EnumNamesTest, NameOfIsAConstantExpression) {
  static_assert(NameOf(kColorNames, Color::kBlue) == "blue");
}

}  // namespace
}  // namespace shapeid
