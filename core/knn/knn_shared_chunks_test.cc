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

}  // namespace
}  // namespace knn_internal
}  // namespace shapeid
