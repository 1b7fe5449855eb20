#include "core/knn/knn_statistics.h"

#include <algorithm>
#include <cmath>
#include <cstddef>

#include "core/heap_chunk.h"

namespace shapeid {
namespace knn_internal {

RunningStatistics::RunningStatistics(int dim, double min_spread)
    : min_spread_(min_spread),
      mean_(static_cast<std::size_t>(dim), 0.0),
      m2_(static_cast<std::size_t>(dim), 0.0),
      max_abs_(static_cast<std::size_t>(dim), 0.0f),
      zscore_scale_(static_cast<std::size_t>(dim), 1.0f),
      maxabs_scale_(static_cast<std::size_t>(dim), 1.0f) {}

void RunningStatistics::Add(const float* row) {
  // Welford's update: numerically stable, and recomputing over the same rows in the same
  // order reproduces it bit for bit (KnnIndex::Remove relies on that).
  const double count = static_cast<double>(++count_);
  for (std::size_t j = 0; j < mean_.size(); ++j) {
    const float xf = row[j];
    const double x = xf;
    const double delta = x - mean_[j];
    mean_[j] += delta / count;
    m2_[j] += delta * (x - mean_[j]);
    max_abs_[j] = std::max(max_abs_[j], std::fabs(xf));
  }
}

int64_t RunningStatistics::memory_bytes() const {
  const std::size_t dim = mean_.size();
  if (dim == 0) return 0;
  return static_cast<int64_t>(2 * HeapChunkBytes(dim * sizeof(double)) +
                              3 * HeapChunkBytes(dim * sizeof(float)));
}

void RunningStatistics::Reset() {
  count_ = 0;
  std::fill(mean_.begin(), mean_.end(), 0.0);
  std::fill(m2_.begin(), m2_.end(), 0.0);
  std::fill(max_abs_.begin(), max_abs_.end(), 0.0f);
  UpdateFactors();
}

void RunningStatistics::UpdateFactors() {
  // 1 / spread, but at most 1 / min_spread_, which keeps every scaled distance finite; a
  // spread of 0 leaves the dimension unscaled.
  auto factor = [this](double spread) {
    return static_cast<float>(1.0 / std::max(spread, min_spread_));
  };
  const double n = static_cast<double>(count_);
  for (std::size_t j = 0; j < mean_.size(); ++j) {
    const double std_dev = n > 0 ? std::sqrt(m2_[j] / n) : 0.0;
    zscore_scale_[j] = std_dev > 0.0 ? factor(std_dev) : 1.0f;
    maxabs_scale_[j] = max_abs_[j] > 0.0f ? factor(max_abs_[j]) : 1.0f;
  }
}

const float* RunningStatistics::Factors(FeatureScaling scaling) const {
  switch (scaling) {
    case FeatureScaling::kZScore:
      return zscore_scale_.data();
    case FeatureScaling::kMaxAbs:
      return maxabs_scale_.data();
    case FeatureScaling::kNone:
      break;
  }
  return nullptr;
}

}  // namespace knn_internal
}  // namespace shapeid
