#ifndef SHAPEID_CORE_DESCRIPTORS_RPHSD_H_
#define SHAPEID_CORE_DESCRIPTORS_RPHSD_H_

// RPHSD, the Reference Points Histograms Shape Descriptor (dissertation chapter 6;
// docs/descriptors.md). For each reference point, a histogram of the distances from it to
// every point of the normalized cloud; three statistics per histogram.

#include <memory>
#include <vector>

#include "absl/status/statusor.h"
#include "core/descriptor.h"
#include "core/descriptor_registry.h"
#include "core/descriptors/reference_points.h"
#include "core/simd.h"

namespace shapeid {

struct RphsdOptions {
  // Where the histograms are taken from; default the paper's best, cubic27 (K = 27).
  ReferenceArrangement references{"cubic27", Cubic27References()};
  // Histogram size M in [1, 100000]; the paper's best is 100. Larger M resolves finer
  // distance differences but makes sparse clouds' histograms noisier.
  int bins = 100;
  // complete: 3K values [variances, entropies, IDMs], one per reference (most accurate,
  // orientation dependent). reduced: 6 values, mean and population std of each feature over
  // the references (invariant to the rotations that permute the references).
  enum class Variant { kComplete, kReduced } variant = Variant::kComplete;
};

class Rphsd final : public Descriptor {
 public:
  static absl::StatusOr<std::unique_ptr<Rphsd>> Create(RphsdOptions options);

  // For tests and benchmarks: the same descriptor computed at an explicit SIMD level
  // (must not exceed DetectedSimdLevel()). Compute() uses ActiveSimdLevel().
  absl::Status ComputeAtLevel(const PointCloud& cloud, SimdLevel level, std::vector<float>* out,
                              const CloudLimits& limits = {}) const;

  // Clouds are split across CloudLimits::max_threads threads in parts of at least this many
  // points: each part counts into its own histograms, which are then summed (integers, so
  // the result does not depend on the split).
  static constexpr int64_t kMinPointsPerThread = 65536;

  const RphsdOptions& options() const { return options_; }

  DescribeCost EstimateCost(size_t num_points) const override;

 protected:
  absl::Status ComputeValidated(const PointCloud& cloud, const CloudStats& stats,
                                const CloudLimits& limits, absl::Span<float> out) const override;

 private:
  Rphsd(DescriptorSpec spec, size_t dimension, RphsdOptions options);
  absl::Status ComputeWith(const PointCloud& cloud, const CloudStats& stats, SimdLevel level,
                           int max_threads, absl::Span<float> out) const;

  RphsdOptions options_;
  // Reference coordinates, structure-of-arrays and zero-padded for the SIMD kernels.
  std::vector<float> ref_x_, ref_y_, ref_z_;
  std::vector<double> idm_weights_;  // 1 / (1 + i^2) for each bin i
};

// Registry entry: rphsd:refs=cubic27,bins=100,variant=complete.
DescriptorKind RphsdKind();

}  // namespace shapeid

#endif  // SHAPEID_CORE_DESCRIPTORS_RPHSD_H_
