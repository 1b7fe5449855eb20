#include "core/knn/knn_shared_chunks.h"

#include <cstdint>
#include <string>

#include "absl/container/flat_hash_map.h"
#include "absl/container/flat_hash_set.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace knn_internal {
namespace {

using Chunks = SharedChunks<int64_t>;

TEST(SharedChunksTest, PushBackAndIndexAcrossChunks) {
  Chunks v;
  for (int64_t i = 0; i < 2 * Chunks::kChunk + 5; ++i) v.PushBack(i * 3);
  ASSERT_EQ(v.size(), 2 * Chunks::kChunk + 5);
  EXPECT_EQ(v.num_chunks(), 3);
  for (int64_t i = 0; i < v.size(); ++i) ASSERT_EQ(v[i], i * 3);
}

TEST(SharedChunksTest, CopySharesEveryChunkAndAppendCopiesOnlyTheLast) {
  Chunks original;
  for (int64_t i = 0; i < 3 * Chunks::kChunk - 1; ++i) original.PushBack(i);
  Chunks copy = original;
  for (int64_t c = 0; c < original.num_chunks(); ++c) {
    EXPECT_EQ(copy.chunk_address(c), original.chunk_address(c));
  }
  copy.PushBack(-1);
  EXPECT_EQ(copy.chunk_address(0), original.chunk_address(0));
  EXPECT_EQ(copy.chunk_address(1), original.chunk_address(1));
  EXPECT_NE(copy.chunk_address(2), original.chunk_address(2));
  EXPECT_EQ(original.size(), 3 * Chunks::kChunk - 1);
  EXPECT_EQ(copy[copy.size() - 1], -1);
  // A full last chunk is not copied: the next entry opens a new one.
  Chunks second = copy;
  second.PushBack(-2);
  EXPECT_EQ(second.chunk_address(2), copy.chunk_address(2));
  EXPECT_EQ(second.num_chunks(), 4);
  EXPECT_EQ(copy.num_chunks(), 3);
}

TEST(SharedChunksTest, SetCopiesOnlyTheChunkItWrites) {
  Chunks original;
  for (int64_t i = 0; i < 2 * Chunks::kChunk; ++i) original.PushBack(i);
  Chunks copy = original;
  copy.Set(5, 99);
  EXPECT_EQ(copy[5], 99);
  EXPECT_EQ(original[5], 5);
  EXPECT_NE(copy.chunk_address(0), original.chunk_address(0));
  EXPECT_EQ(copy.chunk_address(1), original.chunk_address(1));
  // Sole owner: written in place.
  const void* before = copy.chunk_address(0);
  copy.Set(6, 98);
  EXPECT_EQ(copy.chunk_address(0), before);
}

TEST(SharedChunksTest, TruncateKeepsThePrefixShared) {
  Chunks original;
  for (int64_t i = 0; i < 2 * Chunks::kChunk + 10; ++i) original.PushBack(i);
  Chunks copy = original;
  copy.Truncate(Chunks::kChunk + 3);
  EXPECT_EQ(copy.size(), Chunks::kChunk + 3);
  EXPECT_EQ(copy.chunk_address(0), original.chunk_address(0));
  EXPECT_EQ(original.size(), 2 * Chunks::kChunk + 10);
  EXPECT_EQ(original[Chunks::kChunk + 5], Chunks::kChunk + 5);
  copy.PushBack(-7);
  EXPECT_EQ(copy[Chunks::kChunk + 3], -7);
  EXPECT_EQ(original[Chunks::kChunk + 3], Chunks::kChunk + 3);
  copy.Clear();
  EXPECT_TRUE(copy.empty());
}

TEST(SharedChunksTest, MemoryBytesCountsWholeChunks) {
  Chunks v;
  EXPECT_EQ(v.memory_bytes(), 0);
  v.PushBack(1);
  const int64_t one = v.memory_bytes();
  EXPECT_GE(one, Chunks::kChunk * 8);  // a chunk has room for all its entries at once
  for (int64_t i = 1; i < Chunks::kChunk; ++i) v.PushBack(i);
  EXPECT_EQ(v.memory_bytes(), one);
  v.PushBack(-1);
  EXPECT_GE(v.memory_bytes(), 2 * Chunks::kChunk * 8);
  const Chunks copy = v;  // counted in each copy, shared or not
  EXPECT_EQ(copy.memory_bytes(), v.memory_bytes());
  v.Truncate(5);
  EXPECT_LT(v.memory_bytes(), copy.memory_bytes());
}

TEST(SharedHashTableTest, SetInsertFindErase) {
  SharedHashTable<absl::flat_hash_set<uint64_t>> set;
  for (uint64_t id = 1; id <= 5000; ++id) ASSERT_TRUE(set.Insert(id));
  EXPECT_FALSE(set.Insert(17));
  EXPECT_EQ(set.size(), 5000);
  EXPECT_TRUE(set.contains(4999));
  EXPECT_FALSE(set.contains(5001));
  EXPECT_TRUE(set.Erase(4999));
  EXPECT_FALSE(set.Erase(4999));
  EXPECT_FALSE(set.contains(4999));
  EXPECT_EQ(set.size(), 4999);
}

TEST(SharedHashTableTest, CopyOnWriteTouchesOneShard) {
  using Table = SharedHashTable<absl::flat_hash_map<std::string, int32_t>>;
  Table original;
  for (int i = 0; i < 3000; ++i) ASSERT_TRUE(original.Insert({"label" + std::to_string(i), i}));
  Table copy = original;
  ASSERT_TRUE(copy.Insert({"new", -1}));
  const std::size_t touched = Table::ShardOf("new");
  for (std::size_t s = 0; s < Table::kShards; ++s) {
    if (s == touched) {
      EXPECT_NE(copy.shard_address(s), original.shard_address(s));
    } else {
      ASSERT_EQ(copy.shard_address(s), original.shard_address(s)) << s;
    }
  }
  EXPECT_EQ(original.Find("new"), nullptr);
  ASSERT_NE(copy.Find("new"), nullptr);
  EXPECT_EQ(copy.Find("new")->second, -1);
  EXPECT_EQ(copy.Find("label7")->second, 7);
  EXPECT_TRUE(copy.Erase("label7"));
  EXPECT_NE(original.Find("label7"), nullptr);
}

TEST(SharedHashTableTest, MemoryBytesIsKeptAsShardsChange) {
  using Table = SharedHashTable<absl::flat_hash_set<uint64_t>>;
  Table original;
  const int64_t empty = original.memory_bytes();
  EXPECT_EQ(empty, static_cast<int64_t>(Table::kShards * sizeof(std::shared_ptr<int>)));
  for (uint64_t id = 1; id <= 20000; ++id) ASSERT_TRUE(original.Insert(id));
  const int64_t full = original.memory_bytes();
  EXPECT_GT(full - empty, 20000 * 9);  // 8 bytes and a control byte per id, at least
  EXPECT_LT(full - empty, 20000 * 9 * 3);
  // A copy counts what it holds; changing it leaves the original's count alone.
  Table copy = original;
  EXPECT_EQ(copy.memory_bytes(), full);
  for (uint64_t id = 20001; id <= 40000; ++id) ASSERT_TRUE(copy.Insert(id));
  EXPECT_GT(copy.memory_bytes(), full);
  EXPECT_EQ(original.memory_bytes(), full);
  for (uint64_t id = 1; id <= 40000; ++id) ASSERT_TRUE(copy.Erase(id));
  EXPECT_GT(copy.memory_bytes(), empty);  // tables keep their slots when emptied
  copy.Clear();
  EXPECT_EQ(copy.memory_bytes(), empty);
  EXPECT_EQ(original.memory_bytes(), full);
}

}  // namespace
}  // namespace knn_internal
}  // namespace shapeid
