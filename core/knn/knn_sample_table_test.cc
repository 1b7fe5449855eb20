#include "core/knn/knn_sample_table.h"

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace knn_internal {
namespace {

using ::testing::ElementsAre;
using ::testing::Pair;

TEST(SampleTableTest, IdsLabelsAndRows) {
  SampleTable table;
  table.Append(10, "cup", 1);
  table.Append(20, "bowl", 1);
  table.Append(30, "cup", 1);
  EXPECT_EQ(table.size(), 3);
  EXPECT_EQ(table.num_rows(), 3);
  EXPECT_EQ(table.sample_of_row(), nullptr);  // one row each: no map
  EXPECT_TRUE(table.Contains(20));
  EXPECT_FALSE(table.Contains(40));
  EXPECT_EQ(table.IdAt(2), 30u);
  EXPECT_EQ(table.LabelAt(1), "bowl");
  EXPECT_EQ(table.num_labels(), 2);
  EXPECT_THAT(table.LabelCounts(), ElementsAre(Pair("cup", 2), Pair("bowl", 1)));
  EXPECT_THAT(table.IdsWithLabel("cup"), ElementsAre(10u, 30u));
  EXPECT_TRUE(table.IdsWithLabel("plate").empty());
}

TEST(SampleTableTest, SeveralRowsPartRowsFromSamples) {
  SampleTable table;
  table.Append(1, "a", 1);
  table.Append(2, "b", 3);
  table.Append(3, "a", 2);
  EXPECT_EQ(table.num_rows(), 6);
  ASSERT_NE(table.sample_of_row(), nullptr);
  EXPECT_EQ(table.FirstRow(0), 0);
  EXPECT_EQ(table.FirstRow(1), 1);
  EXPECT_EQ(table.FirstRow(2), 4);
  EXPECT_EQ(table.FirstRow(3), 6);
  const std::vector<int64_t> expected = {0, 1, 1, 1, 2, 2};
  for (int64_t row = 0; row < 6; ++row) {
    EXPECT_EQ(table.SampleOfRow(row), expected[static_cast<std::size_t>(row)]);
    EXPECT_EQ((*table.sample_of_row())[row], expected[static_cast<std::size_t>(row)]);
  }
}

// 10,000 samples with a label each: a copy plus one Append leaves the original as it was.
TEST(SampleTableTest, AppendToACopyLeavesTheOriginal) {
  SampleTable original;
  for (uint64_t id = 1; id <= 10000; ++id) original.Append(id, "l" + std::to_string(id % 5000), 1);
  SampleTable copy = original;
  copy.Append(20000, "l7", 2);
  copy.Append(20001, "fresh", 1);
  EXPECT_EQ(original.size(), 10000);
  EXPECT_EQ(original.num_rows(), 10000);
  EXPECT_FALSE(original.Contains(20000));
  EXPECT_EQ(original.sample_of_row(), nullptr);
  EXPECT_EQ(original.num_labels(), 5000);
  EXPECT_THAT(original.IdsWithLabel("l7"), ElementsAre(7u, 5007u));
  EXPECT_EQ(copy.size(), 10002);
  EXPECT_EQ(copy.num_rows(), 10003);
  EXPECT_EQ(copy.num_labels(), 5001);
  EXPECT_THAT(copy.IdsWithLabel("l7"), ElementsAre(7u, 5007u, 20000u));
  EXPECT_EQ(copy.SampleOfRow(10001), 10000);
  EXPECT_EQ(copy.LabelAt(10001), "fresh");
  // "l7" is the 7th label to appear (ids 1, 2, ... bring "l1", "l2", ...).
  EXPECT_THAT(copy.LabelCounts()[6], Pair("l7", 3));
  EXPECT_THAT(original.LabelCounts()[6], Pair("l7", 2));
}

}  // namespace
}  // namespace knn_internal
}  // namespace shapeid
