#include "core/knn/knn_feature_storage.h"

#include <cstdint>
#include <random>
#include <vector>

#include "gtest/gtest.h"

namespace shapeid {
namespace knn_internal {
namespace {

std::vector<float> Row(int dim, int64_t r) {
  std::vector<float> row(static_cast<std::size_t>(dim));
  for (int j = 0; j < dim; ++j) row[static_cast<std::size_t>(j)] = static_cast<float>(r * 1000 + j);
  return row;
}

FeatureStorage Filled(int dim, int64_t rows) {
  FeatureStorage storage(dim);
  for (int64_t r = 0; r < rows; ++r) storage.Append(Row(dim, r).data());
  return storage;
}

TEST(FeatureStorageTest, AFullBlockIsWholeKernelBlocksInAHugePage) {
  for (int dim : {1, 3, 81, 240, 700, 5000, 20000}) {
    const FeatureStorage storage(dim);
    EXPECT_EQ(storage.rows_per_block() % kBlockLanes, 0) << dim;
    const std::size_t bytes = static_cast<std::size_t>(storage.rows_per_block()) * dim * 4;
    EXPECT_TRUE(bytes <= kHugePageBytes || storage.rows_per_block() == kBlockLanes) << dim;
    EXPECT_GT(bytes + BlockFloats(dim) * 4, kHugePageBytes) << dim;  // no room for another
  }
  EXPECT_EQ(FeatureStorage(240).rows_per_block(), 2176);
  EXPECT_EQ(FeatureStorage(2048).rows_per_block(), 256);
}

TEST(FeatureStorageTest, MemoryBytesFollowsTheBlocks) {
  const int dim = 240;  // 2,176 rows per block
  EXPECT_EQ(FeatureStorage(dim).memory_bytes(), 0);
  // The last block grows by doubling (kernel blocks of 32 rows); a full one is a huge page.
  const int64_t small = Filled(dim, 1).memory_bytes();
  EXPECT_GE(small, 32 * dim * 4);
  EXPECT_LT(small, 2 * 32 * dim * 4);
  EXPECT_GE(Filled(dim, 40).memory_bytes(), 64 * dim * 4);
  const FeatureStorage full = Filled(dim, 2176);
  EXPECT_GE(full.memory_bytes(), static_cast<int64_t>(kHugePageBytes));
  EXPECT_LT(full.memory_bytes(), static_cast<int64_t>(kHugePageBytes) + 4096);
  // Counted in each copy; the copy's growth is its own.
  FeatureStorage copy = full;
  EXPECT_EQ(copy.memory_bytes(), full.memory_bytes());
  copy.Append(Row(dim, 2176).data());
  EXPECT_GE(copy.memory_bytes() - full.memory_bytes(), 32 * dim * 4);
  EXPECT_LT(copy.memory_bytes() - full.memory_bytes(), 2 * 32 * dim * 4);
  EXPECT_EQ(full.memory_bytes(), Filled(dim, 2176).memory_bytes());
  // Truncating drops the second block; the first, kept, stays a full one.
  copy.Truncate(100);
  EXPECT_EQ(copy.num_blocks(), 1);
  EXPECT_GE(copy.memory_bytes(), full.memory_bytes());
  EXPECT_LT(copy.memory_bytes(), full.memory_bytes() + 32 * dim * 4);
}

TEST(FeatureStorageTest, RowsReadBackAcrossBlocks) {
  const int dim = 2048;  // 256 rows per block
  const FeatureStorage storage = Filled(dim, 1000);
  EXPECT_EQ(storage.rows(), 1000);
  EXPECT_EQ(storage.num_blocks(), 4);
  std::vector<float> out(dim);
  for (int64_t r : {0, 255, 256, 511, 999}) {
    storage.CopyRow(r, out.data());
    EXPECT_EQ(out, Row(dim, r)) << r;
    EXPECT_EQ(storage.At(r, 7), static_cast<float>(r * 1000 + 7));
  }
  const BlockedView last = storage.BlockView(3);
  EXPECT_EQ(last.size, 1000 - 768);
  EXPECT_EQ(last.row_base, 768);
}

TEST(FeatureStorageTest, CopySharesBlocksAndAppendCopiesOnlyTheLast) {
  const int dim = 2048;
  FeatureStorage original = Filled(dim, 2 * 256 + 10);
  ASSERT_EQ(original.rows_per_block(), 256);
  FeatureStorage copy = original;
  for (int64_t b = 0; b < original.num_blocks(); ++b) {
    EXPECT_EQ(copy.block_address(b), original.block_address(b));
  }
  copy.Append(Row(dim, -1).data());
  EXPECT_EQ(copy.block_address(0), original.block_address(0));
  EXPECT_EQ(copy.block_address(1), original.block_address(1));
  EXPECT_NE(copy.block_address(2), original.block_address(2));
  EXPECT_EQ(original.rows(), 2 * 256 + 10);
  EXPECT_EQ(copy.rows(), 2 * 256 + 11);
  std::vector<float> out(dim);
  copy.CopyRow(2 * 256 + 10, out.data());
  EXPECT_EQ(out, Row(dim, -1));
  // The original's padding lane is still zero.
  EXPECT_EQ(original.BlockView(2).data[FeatureOffset(10, dim, 0)], 0.0f);
  // The copy's block is its own now: the next row goes in place (its 32 rows have room).
  const void* own = copy.block_address(2);
  copy.Append(Row(dim, -2).data());
  EXPECT_EQ(copy.block_address(2), own);
  copy.CopyRow(2 * 256 + 11, out.data());
  EXPECT_EQ(out, Row(dim, -2));
}

TEST(FeatureStorageTest, TruncateZeroesPaddingAndKeepsThePrefixShared) {
  const int dim = 2048;
  FeatureStorage original = Filled(dim, 600);
  FeatureStorage copy = original;
  copy.Truncate(300);
  EXPECT_EQ(copy.rows(), 300);
  EXPECT_EQ(copy.num_blocks(), 2);
  EXPECT_EQ(copy.block_address(0), original.block_address(0));
  EXPECT_NE(copy.block_address(1), original.block_address(1));
  EXPECT_EQ(copy.At(299, 3), static_cast<float>(299 * 1000 + 3));
  EXPECT_EQ(copy.BlockView(1).data[FeatureOffset(300 - 256, dim, 3)], 0.0f);
  EXPECT_EQ(original.At(300, 3), static_cast<float>(300 * 1000 + 3));
}

// The block-by-block scan equals one scan of a contiguous copy, ties and all.
TEST(FeatureStorageTest, ScanEqualsAContiguousScan) {
  const int dim = 2048;
  const int64_t n = 1000;
  std::mt19937 rng(3);
  std::uniform_int_distribution<int> small(0, 3);  // many ties
  FeatureStorage storage(dim);
  AlignedFloats contiguous(static_cast<std::size_t>((n + 31) / 32) * BlockFloats(dim), 0.0f);
  std::vector<float> row(dim);
  for (int64_t r = 0; r < n; ++r) {
    for (int j = 0; j < dim; ++j) {
      row[static_cast<std::size_t>(j)] = static_cast<float>(small(rng));
      contiguous[FeatureOffset(r, dim, j)] = row[static_cast<std::size_t>(j)];
    }
    storage.Append(row.data());
  }
  std::vector<float> queries(2 * dim);
  for (float& q : queries) q = static_cast<float>(small(rng));
  for (int64_t from : {int64_t{0}, int64_t{256}, int64_t{288}}) {
    for (int k : {1, 10, 100}) {
      TopK a(k, nullptr, true), b(k, nullptr, true);
      storage.Scan(ActiveSimdLevel(), from, queries.data(), 2, nullptr, true, &a);
      const BlockedView view{
          contiguous.data() + static_cast<std::size_t>(from / 32) * BlockFloats(dim), n - from, dim,
          from};
      ScanBlocks(ActiveSimdLevel(), view, queries.data(), 2, nullptr, true, &b);
      const std::vector<Candidate> x = a.TakeSorted(), y = b.TakeSorted();
      ASSERT_EQ(x.size(), y.size());
      for (std::size_t i = 0; i < x.size(); ++i) {
        EXPECT_EQ(x[i].distance_sq, y[i].distance_sq);
        EXPECT_EQ(x[i].row, y[i].row);
        EXPECT_EQ(x[i].query, y[i].query);
      }
    }
  }
}

}  // namespace
}  // namespace knn_internal
}  // namespace shapeid
