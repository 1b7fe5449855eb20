#ifndef SHAPEID_CORE_KNN_KNN_SHARED_CHUNKS_H_
#define SHAPEID_CORE_KNN_KNN_SHARED_CHUNKS_H_

// Internal to core/knn: containers whose copies share their storage in fixed-size pieces, so
// that a copy costs O(pieces) pointer copies and a change to the copy copies only the pieces
// it touches (copy-on-write). What lets a gallery commit one sample in O(block), not
// O(gallery) (KnnIndex).
//
// Thread safety: like a std::vector. Const methods may run concurrently; a mutation needs
// exclusive access to this object, never to its copies (a shared piece is never written).

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

#include "absl/hash/hash.h"
#include "core/heap_chunk.h"

namespace shapeid {
namespace knn_internal {

// A piece may be written in place only while this object holds the only reference to it.
// The fence orders the write after the reads of a copy that has just let it go.
// ThreadSanitizer models no fences (GCC refuses one under it), so there every piece is copied.
template <typename Piece>
bool SoleOwner(const std::shared_ptr<Piece>& piece) {
#if defined(__SANITIZE_THREAD__)
  (void)piece;
  return false;
#else
  if (piece.use_count() != 1) return false;
  std::atomic_thread_fence(std::memory_order_acquire);
  return true;
#endif
}

// A sequence of T in chunks of kChunk entries (the last one partly filled), each held by a
// shared_ptr. PushBack and Set copy at most one chunk of kChunk entries.
template <typename T>
class SharedChunks {
 public:
  static constexpr int kShift = 12;
  static constexpr int64_t kChunk = int64_t{1} << kShift;  // 4,096 entries

  int64_t size() const { return size_; }
  bool empty() const { return size_ == 0; }
  const T& operator[](int64_t i) const {
    return (*chunks_[static_cast<std::size_t>(i >> kShift)])[static_cast<std::size_t>(
        i & (kChunk - 1))];
  }

  void PushBack(T value) {
    if ((size_ & (kChunk - 1)) == 0) {
      auto chunk = std::make_shared<std::vector<T>>();
      chunk->reserve(static_cast<std::size_t>(kChunk));
      chunks_.push_back(std::move(chunk));
    }
    Writable(chunks_.size() - 1).push_back(std::move(value));
    ++size_;
  }
  // Entry i (< size()) becomes `value`.
  void Set(int64_t i, T value) {
    Writable(static_cast<std::size_t>(i >> kShift))[static_cast<std::size_t>(i & (kChunk - 1))] =
        std::move(value);
  }
  // Keeps the first `n` (<= size()) entries; the chunks before entry n stay shared.
  void Truncate(int64_t n) {
    if (n >= size_) return;
    chunks_.resize(static_cast<std::size_t>((n + kChunk - 1) >> kShift));
    if ((n & (kChunk - 1)) != 0)
      Writable(chunks_.size() - 1).resize(static_cast<std::size_t>(n & (kChunk - 1)));
    size_ = n;
  }
  void Clear() { Truncate(0); }

  // The heap this object's chunks take (every chunk holds room for kChunk entries), counted
  // whole even where a copy shares them; entries' own heap (a long string's) not included. O(1).
  int64_t memory_bytes() const {
    return static_cast<int64_t>(chunks_.size() *
                                    (SharedHeapBytes<std::vector<T>>() +
                                     HeapChunkBytes(static_cast<std::size_t>(kChunk) * sizeof(T))) +
                                chunks_.capacity() * sizeof(chunks_[0]));
  }

  // For tests: chunk c, to see whether two copies share it.
  const void* chunk_address(int64_t c) const { return chunks_[static_cast<std::size_t>(c)].get(); }
  int64_t num_chunks() const { return static_cast<int64_t>(chunks_.size()); }

 private:
  std::vector<T>& Writable(std::size_t c) {
    std::shared_ptr<std::vector<T>>& chunk = chunks_[c];
    if (!SoleOwner(chunk)) {
      auto copy = std::make_shared<std::vector<T>>();
      copy->reserve(static_cast<std::size_t>(kChunk));
      copy->assign(chunk->begin(), chunk->end());
      chunk = std::move(copy);
    }
    return *chunk;
  }

  std::vector<std::shared_ptr<std::vector<T>>> chunks_;
  int64_t size_ = 0;
};

// A hash table (absl::flat_hash_set or flat_hash_map) in kShards shards, each held by a
// shared_ptr: Insert and Erase copy one shard (about size() / kShards entries). For the ids
// and labels of a gallery, where a whole-table copy per commit would be O(gallery).
template <typename Table>
class SharedHashTable {
 public:
  using key_type = typename Table::key_type;
  using value_type = typename Table::value_type;
  static constexpr int kShardBits = 10;
  static constexpr std::size_t kShards = std::size_t{1} << kShardBits;

  SharedHashTable() : shards_(kShards) {}

  int64_t size() const { return size_; }
  // The heap of this object's shards (each table's slots and control bytes, counted whole
  // even where a copy shares the shard) and of its shard pointers; the entries' own heap (a
  // long string key's, a shared_ptr's object) not included. O(1): kept as shards change.
  int64_t memory_bytes() const {
    return shard_bytes_ + static_cast<int64_t>(kShards * sizeof(shards_[0]));
  }
  bool contains(const key_type& key) const { return Find(key) != nullptr; }
  // The entry of `key`, or nullptr. Valid until the next mutation.
  const value_type* Find(const key_type& key) const {
    const auto& shard = shards_[ShardOf(key)];
    if (shard == nullptr) return nullptr;
    const auto it = shard->find(key);
    return it == shard->end() ? nullptr : &*it;
  }
  // False (and nothing changed) if the key was present.
  bool Insert(value_type value) {
    const key_type& key = KeyOf(value);
    auto& shard = shards_[ShardOf(key)];
    if (shard != nullptr && shard->contains(key)) return false;
    const int64_t before = ShardBytes(shard.get());
    if (shard == nullptr) {
      shard = std::make_shared<Table>();
    } else if (!SoleOwner(shard)) {
      shard = std::make_shared<Table>(*shard);
    }
    shard->insert(std::move(value));
    shard_bytes_ += ShardBytes(shard.get()) - before;
    ++size_;
    return true;
  }
  // False if the key was absent.
  bool Erase(const key_type& key) {
    auto& shard = shards_[ShardOf(key)];
    if (shard == nullptr || !shard->contains(key)) return false;
    const int64_t before = ShardBytes(shard.get());
    if (!SoleOwner(shard)) shard = std::make_shared<Table>(*shard);
    shard->erase(key);
    shard_bytes_ += ShardBytes(shard.get()) - before;
    --size_;
    return true;
  }
  void Clear() {
    for (auto& shard : shards_) shard.reset();
    size_ = 0;
    shard_bytes_ = 0;
  }

  // For tests: shard s, to see whether two copies share it.
  const void* shard_address(std::size_t s) const { return shards_[s].get(); }
  static std::size_t ShardOf(const key_type& key) {
    // The hash's top bits: a shard's own table probes with the low ones.
    return static_cast<std::size_t>(static_cast<uint64_t>(absl::Hash<key_type>{}(key)) >>
                                    (64 - kShardBits));
  }

 private:
  // A shard's heap: the shared table and its slot array (capacity slots, a control byte each
  // and a group's worth of cloned ones).
  static int64_t ShardBytes(const Table* table) {
    if (table == nullptr) return 0;
    std::size_t bytes = SharedHeapBytes<Table>();
    if (table->capacity() > 0) {
      bytes += HeapChunkBytes(table->capacity() * (sizeof(value_type) + 1) + 16);
    }
    return static_cast<int64_t>(bytes);
  }
  static const key_type& KeyOf(const key_type& key) { return key; }
  template <typename V>
  static const key_type& KeyOf(const std::pair<const key_type, V>& entry) {
    return entry.first;
  }

  std::vector<std::shared_ptr<Table>> shards_;
  int64_t size_ = 0;
  int64_t shard_bytes_ = 0;  // ShardBytes over every shard
};

}  // namespace knn_internal
}  // namespace shapeid

#endif  // SHAPEID_CORE_KNN_KNN_SHARED_CHUNKS_H_
