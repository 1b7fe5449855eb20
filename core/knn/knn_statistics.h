#ifndef SHAPEID_CORE_KNN_KNN_STATISTICS_H_
#define SHAPEID_CORE_KNN_KNN_STATISTICS_H_

// Internal to core/knn: the running per-dimension statistics of a gallery's rows and the
// scale factors queries multiply feature differences by (FeatureScaling).

#include <cstdint>
#include <vector>

#include "core/knn/knn_options.h"

namespace shapeid {
namespace knn_internal {

// Mean and squared deviations (Welford, double) and max |x| per dimension over the rows
// added so far, in order, and the float factors of each FeatureScaling. The stored rows never
// depend on these (queries scale differences), so adding a row is O(dim) and changes nothing
// else. Adding the same rows in the same order gives the same bits. O(dim) to copy.
class RunningStatistics {
 public:
  // The least spread a factor divides by (KnnIndex::kMinScaleSpread).
  RunningStatistics(int dim, double min_spread);

  int64_t count() const { return count_; }
  // Folds one row of dim floats in. Call UpdateFactors() before the next query.
  void Add(const float* row);
  void Reset();
  // Recomputes the factors from the statistics: O(dim), so once per batch of Add.
  void UpdateFactors();

  // The dim factors of `scaling`, or nullptr for kNone (all ones).
  const float* Factors(FeatureScaling scaling) const;
  // The heap of the per-dimension arrays. O(1).
  int64_t memory_bytes() const;

 private:
  double min_spread_;
  int64_t count_ = 0;
  std::vector<double> mean_;
  std::vector<double> m2_;
  std::vector<float> max_abs_;
  std::vector<float> zscore_scale_;
  std::vector<float> maxabs_scale_;
};

}  // namespace knn_internal
}  // namespace shapeid

#endif  // SHAPEID_CORE_KNN_KNN_STATISTICS_H_
