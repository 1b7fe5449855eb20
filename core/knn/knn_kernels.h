#ifndef SHAPEID_CORE_KNN_KNN_KERNELS_H_
#define SHAPEID_CORE_KNN_KNN_KERNELS_H_

// Internal to core/knn: the brute-force distance kernels and the bounded best-k set they
// feed. Not part of the kNN API; KnnIndex is.

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <new>
#include <utility>
#include <vector>

#include "core/simd.h"

namespace shapeid {
namespace knn_internal {

// Samples are stored in blocks of kBlockLanes, dimension-major inside a block:
//   block b = [dim 0: s0 .. s31][dim 1: s0 .. s31] ... [dim d-1: s0 .. s31]
// so one query accumulates 32 distances per block with vertical SIMD only (two AVX-512 or
// four AVX2 registers per dimension, i.e. independent add chains): no horizontal sums, no
// dimension tails, and the gallery is read once, front to back, as one sequential stream.
// (Blocks of 16 scanned two at a time read two interleaved streams and measured ~1.6x
// slower on 100k x 81; see bench/knn_bench.cc.) The last block is zero-padded; padding
// lanes are never reported. Sample `slot` lives at block slot / 32, lane slot % 32.
inline constexpr int kBlockLanes = 32;
inline constexpr std::size_t kStorageAlignment = 64;  // one cache line, one zmm load

inline std::size_t BlockFloats(int dim) { return static_cast<std::size_t>(dim) * kBlockLanes; }
inline std::size_t FeatureOffset(int64_t slot, int dim, int j) {
  return static_cast<std::size_t>(slot / kBlockLanes) * BlockFloats(dim) +
         static_cast<std::size_t>(j) * kBlockLanes + static_cast<std::size_t>(slot % kBlockLanes);
}

// Galleries of 2 MiB and more are aligned to 2 MiB and marked for transparent huge pages.
// Every commit copies the gallery into fresh memory (core/gallery), and on a VM each 4 KiB
// page's first touch is a costly fault: a 100k x 81 gallery (32 MB) took 8,000 faults per
// commit, most of a 50 ms commit; with huge pages it takes 16. Scans also miss the TLB less.
inline constexpr std::size_t kHugePageBytes = std::size_t{2} << 20;

// Asks the kernel for huge pages over [p, p + bytes); a hint, so failure is harmless.
void AdviseHugePages(void* p, std::size_t bytes);

template <typename T>
struct AlignedAllocator {
  using value_type = T;
  AlignedAllocator() = default;
  template <typename U>
  AlignedAllocator(const AlignedAllocator<U>&) {}  // NOLINT: allocator rebinding
  static std::size_t AlignmentFor(std::size_t n) {
    return n * sizeof(T) >= kHugePageBytes ? kHugePageBytes : kStorageAlignment;
  }
  T* allocate(std::size_t n) {
    const std::size_t alignment = AlignmentFor(n);
    void* p = ::operator new(n * sizeof(T), std::align_val_t(alignment));
    if (alignment == kHugePageBytes) AdviseHugePages(p, n * sizeof(T));
    return static_cast<T*>(p);
  }
  void deallocate(T* p, std::size_t n) { ::operator delete(p, std::align_val_t(AlignmentFor(n))); }
  friend bool operator==(const AlignedAllocator&, const AlignedAllocator&) { return true; }
  friend bool operator!=(const AlignedAllocator&, const AlignedAllocator&) { return false; }
};
using AlignedFloats = std::vector<float, AlignedAllocator<float>>;

// A candidate neighbour: squared distance in the scaled space and storage slot. Candidates
// are ordered by (distance, slot), so among equal distances the earlier-added sample wins.
struct Candidate {
  float distance_sq;
  int64_t slot;
};
inline bool Before(const Candidate& a, const Candidate& b) {
  return a.distance_sq < b.distance_sq || (a.distance_sq == b.distance_sq && a.slot < b.slot);
}

// The best k candidates seen so far: a max-heap on (distance, slot), so the current k-th
// is at the front. Kernels offer candidates in increasing slot order and only call Offer
// for lanes that pass the cheap `!full() || d < threshold()` test; Offer itself accepts any
// order (the kd-tree path offers out of order).
class TopK {
 public:
  explicit TopK(int k) : k_(static_cast<std::size_t>(k)) { heap_.reserve(k_); }

  bool full() const { return heap_.size() == k_; }
  // Squared distance of the current k-th; meaningful only when full().
  float threshold() const { return heap_.front().distance_sq; }

  void Offer(float distance_sq, int64_t slot) {
    const Candidate c{distance_sq, slot};
    if (heap_.size() < k_) {
      heap_.push_back(c);
      std::push_heap(heap_.begin(), heap_.end(), Before);
    } else if (Before(c, heap_.front())) {
      std::pop_heap(heap_.begin(), heap_.end(), Before);
      heap_.back() = c;
      std::push_heap(heap_.begin(), heap_.end(), Before);
    }
  }

  // The kept candidates, best first. Leaves the set empty.
  std::vector<Candidate> TakeSorted() {
    std::sort_heap(heap_.begin(), heap_.end(), Before);
    return std::move(heap_);
  }

 private:
  std::size_t k_;
  std::vector<Candidate> heap_;
};

// A read-only view of blocked storage holding `size` samples of `dim` features.
struct BlockedView {
  const float* data;  // kStorageAlignment-aligned, ceil(size / kBlockLanes) blocks
  int64_t size;
  int dim;
};

// Offers every sample of `view` to `top`, in slot order. `scale` (dim factors) or nullptr
// for unscaled features. The squared distance of one sample is, in float and in this order:
//   acc = 0; for j in 0..dim-1: { e = query[j] - x[j]; e = e * scale[j]; acc = acc + e * e; }
// at every SIMD level (build uses -ffp-contract=off), so all levels give bit-identical
// distances, and nullptr equals a scale of all ones.
void ScanBlocks(SimdLevel level, const BlockedView& view, const float* query, const float* scale,
                TopK* top);

// The same squared distance for one sample whose feature j is at x[j * stride].
float DistanceSq(const float* query, const float* scale, const float* x, std::ptrdiff_t stride,
                 int dim);

}  // namespace knn_internal
}  // namespace shapeid

#endif  // SHAPEID_CORE_KNN_KNN_KERNELS_H_
