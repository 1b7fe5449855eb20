#ifndef SHAPEID_CORE_KNN_KNN_FEATURE_STORAGE_H_
#define SHAPEID_CORE_KNN_KNN_FEATURE_STORAGE_H_

// Internal to core/knn: the feature vectors (rows) of a gallery in immutable fixed-size
// blocks shared between copies, the vector storage of KnnIndex.

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "core/knn/knn_kernels.h"
#include "core/simd.h"

namespace shapeid {
namespace knn_internal {

// Rows of `dim` floats, appended in order, in blocks of rows_per_block() rows. A block is
// rows_per_block() / kBlockLanes kernel blocks (knn_kernels.h's layout, zero-padded), held by
// a shared_ptr: a copy of the storage copies num_blocks() pointers and shares every block,
// and Append copies only the last, partly filled block if a copy shares it (O(block), never
// O(rows)). A full block is one 2 MiB transparent huge page (rows_per_block() the most whole
// kernel blocks that fit, at least one): scans then read long streams with few TLB misses,
// as fast as one contiguous array. The last block grows by doubling, so a small gallery does
// not hold 2 MiB.
//
// Thread safety: const methods may run concurrently; mutations need exclusive access to this
// object only (its copies' blocks are never written).
class FeatureStorage {
 public:
  explicit FeatureStorage(int dim);

  int dim() const { return dim_; }
  int64_t rows() const { return rows_; }
  int64_t rows_per_block() const { return rows_per_block_; }
  int64_t num_blocks() const { return static_cast<int64_t>(blocks_.size()); }
  // The heap of this object's blocks (allocated floats, padding and room to grow included,
  // counted whole even where a copy shares them) and of its block pointers. O(1).
  int64_t memory_bytes() const;

  // Block b's rows, [b * rows_per_block(), min((b + 1) * rows_per_block(), rows())), as a
  // view whose rows are reported as gallery rows (row_base).
  BlockedView BlockView(int64_t b) const;
  float At(int64_t row, int j) const {
    return Data(row / rows_per_block_)[FeatureOffset(row % rows_per_block_, dim_, j)];
  }
  // Writes row `row`'s dim() floats to out.
  void CopyRow(int64_t row, float* out) const;

  // Appends one row of dim() floats.
  void Append(const float* row);
  // Keeps rows [0, rows) (rows <= this->rows()); blocks before row `rows` stay shared.
  void Truncate(int64_t rows);

  // Offers rows [from, rows()) to `top` block by block (ScanBlocks per block, `from` a
  // multiple of kBlockLanes): the same distances and order as one scan of a contiguous copy.
  void Scan(SimdLevel level, int64_t from, const float* queries, int num_queries,
            const float* scale, bool abandon, TopK* top) const;

  // For tests: block b's address, to see whether two copies share it.
  const void* block_address(int64_t b) const { return blocks_[static_cast<std::size_t>(b)].get(); }

 private:
  // At least BlockFloats(dim) * (rows it holds, rounded up to a power of two) floats.
  using Block = AlignedFloats;

  const float* Data(int64_t b) const { return blocks_[static_cast<std::size_t>(b)]->data(); }
  // Floats of a block allocated for `rows` rows (1 .. rows_per_block()).
  std::size_t FloatsFor(int64_t rows) const;
  // The last block, able to hold `rows` rows: copied first if a copy shares it, grown if
  // it is too small.
  Block& WritableLast(int64_t rows);

  int dim_;
  int64_t rows_per_block_;
  int64_t rows_ = 0;
  std::vector<std::shared_ptr<Block>> blocks_;
  int64_t allocated_floats_ = 0;  // over every block
};

}  // namespace knn_internal
}  // namespace shapeid

#endif  // SHAPEID_CORE_KNN_KNN_FEATURE_STORAGE_H_
