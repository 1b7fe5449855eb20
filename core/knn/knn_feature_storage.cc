#include "core/knn/knn_feature_storage.h"

#include <algorithm>

#include "core/heap_chunk.h"
#include "core/knn/knn_shared_chunks.h"

namespace shapeid {
namespace knn_internal {

namespace {

// The most whole kernel blocks of `dim` floats per row that fit in a huge page, at least one.
int64_t RowsPerBlock(int dim) {
  const std::size_t kernel_block_bytes = BlockFloats(dim) * sizeof(float);
  return std::max<int64_t>(1, static_cast<int64_t>(kHugePageBytes / kernel_block_bytes)) *
         kBlockLanes;
}

}  // namespace

FeatureStorage::FeatureStorage(int dim) : dim_(dim), rows_per_block_(RowsPerBlock(dim)) {}

std::size_t FeatureStorage::FloatsFor(int64_t rows) const {
  int64_t lanes = kBlockLanes;
  while (lanes < rows) lanes *= 2;
  if (lanes < rows_per_block_)
    return static_cast<std::size_t>(lanes) * static_cast<std::size_t>(dim_);
  // A full block: whole huge pages (AlignedAllocator aligns and advises them).
  constexpr std::size_t kPageFloats = kHugePageBytes / sizeof(float);
  const std::size_t floats =
      static_cast<std::size_t>(rows_per_block_) * static_cast<std::size_t>(dim_);
  return (floats + kPageFloats - 1) / kPageFloats * kPageFloats;
}

int64_t FeatureStorage::memory_bytes() const {
  return allocated_floats_ * static_cast<int64_t>(sizeof(float)) +
         num_blocks() * static_cast<int64_t>(SharedHeapBytes<Block>()) +
         static_cast<int64_t>(blocks_.capacity() * sizeof(blocks_[0]));
}

BlockedView FeatureStorage::BlockView(int64_t b) const {
  const int64_t first = b * rows_per_block_;
  return BlockedView{Data(b), std::min(rows_per_block_, rows_ - first), dim_, first};
}

void FeatureStorage::CopyRow(int64_t row, float* out) const {
  const float* block = Data(row / rows_per_block_);
  const int64_t r = row % rows_per_block_;
  for (int j = 0; j < dim_; ++j) out[j] = block[FeatureOffset(r, dim_, j)];
}

FeatureStorage::Block& FeatureStorage::WritableLast(int64_t rows) {
  std::shared_ptr<Block>& last = blocks_.back();
  const std::size_t floats = std::max(FloatsFor(rows), last->size());
  if (SoleOwner(last) && last->size() == floats) return *last;
  // Copy (a copy shares it) or grow; the new part is zero padding.
  auto block = std::make_shared<Block>(floats, 0.0f);
  std::copy_n(last->data(), last->size(), block->data());
  allocated_floats_ += static_cast<int64_t>(floats) - static_cast<int64_t>(last->size());
  last = std::move(block);
  return *last;
}

void FeatureStorage::Append(const float* row) {
  const int64_t r = rows_ % rows_per_block_;
  if (r == 0) {
    blocks_.push_back(std::make_shared<Block>(FloatsFor(1), 0.0f));
    allocated_floats_ += static_cast<int64_t>(blocks_.back()->size());
  }
  Block& block = WritableLast(r + 1);
  for (int j = 0; j < dim_; ++j) block[FeatureOffset(r, dim_, j)] = row[j];
  ++rows_;
}

void FeatureStorage::Truncate(int64_t rows) {
  if (rows >= rows_) return;
  const std::size_t kept = static_cast<std::size_t>((rows + rows_per_block_ - 1) / rows_per_block_);
  for (std::size_t b = kept; b < blocks_.size(); ++b) {
    allocated_floats_ -= static_cast<int64_t>(blocks_[b]->size());
  }
  blocks_.resize(kept);
  const int64_t used = rows % rows_per_block_;
  if (used == 0) {
    rows_ = rows;
    return;
  }
  // Padding is zero, as a fresh block's.
  Block& block = WritableLast(used);
  rows_ = rows;
  const int64_t allocated = static_cast<int64_t>(block.size() / BlockFloats(dim_)) * kBlockLanes;
  for (int64_t r = used; r < allocated; ++r) {
    for (int j = 0; j < dim_; ++j) block[FeatureOffset(r, dim_, j)] = 0.0f;
  }
}

void FeatureStorage::Scan(SimdLevel level, int64_t from, const float* queries, int num_queries,
                          const float* scale, bool abandon, TopK* top) const {
  for (int64_t b = from / rows_per_block_; b < num_blocks(); ++b) {
    BlockedView view = BlockView(b);
    const int64_t skip = std::max<int64_t>(from - view.row_base, 0);  // a multiple of 32
    view.data += static_cast<std::size_t>(skip / kBlockLanes) * BlockFloats(dim_);
    view.size -= skip;
    view.row_base += skip;
    ScanBlocks(level, view, queries, num_queries, scale, abandon, top);
  }
}

}  // namespace knn_internal
}  // namespace shapeid
