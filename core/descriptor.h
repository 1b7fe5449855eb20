#ifndef SHAPEID_CORE_DESCRIPTOR_H_
#define SHAPEID_CORE_DESCRIPTOR_H_

#include <array>
#include <cstddef>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/time/time.h"
#include "absl/types/span.h"
#include "core/descriptor_spec.h"
#include "core/point_cloud.h"

namespace shapeid {

// What describing a cloud costs, estimated before doing it, so that a server can admit work
// by cost and bound its memory.
struct DescribeCost {
  absl::Duration cpu;  // one core of a typical x86-64 server, ComputeWithPoseVariants
  size_t working_bytes =
      0;  // peak heap Compute(WithPoseVariants) allocates beyond the cloud itself
};

// A configured shape descriptor: a function from a point cloud to a fixed-length vector.
// Instances are immutable after creation and thread-safe: Compute may run concurrently on
// one object from many threads. Create them through the registry (core/descriptor_registry.h).
class Descriptor {
 public:
  virtual ~Descriptor() = default;
  Descriptor(const Descriptor&) = delete;
  Descriptor& operator=(const Descriptor&) = delete;

  // The canonical spec: every parameter present, defaults filled, values normalized, in the
  // kind's parameter order. Equal canonical text means equal output for every cloud.
  const DescriptorSpec& spec() const { return spec_; }

  // Length of every vector this descriptor produces.
  size_t dimension() const { return dimension_; }

  // Validates `cloud` (section 0 of docs/descriptors.md: at least 3 points, all finite, not
  // all identical, within `limits`) and computes its descriptor into `out`, resized to
  // dimension(). Deterministic: the same cloud gives the same bits on one build, whatever the
  // CPU's SIMD level. On error `out` is unspecified.
  absl::Status Compute(const PointCloud& cloud, std::vector<float>* out,
                       const CloudLimits& limits = {}) const;
  absl::StatusOr<std::vector<float>> Compute(const PointCloud& cloud,
                                             const CloudLimits& limits = {}) const;

  // Compute, and also the cloud's pose variants: the descriptors of the same object in the
  // other poses that this descriptor's canonical frame cannot tell apart. A frame fixed by
  // the shape alone (DFSD's frame=box) is ambiguous where two box extents are nearly equal
  // (which axis comes first?) or the points are nearly symmetric along an axis (which way
  // does it point?); the variants are the descriptor under those other axis orders and
  // signs. `variants` gets m * dimension() floats, m >= 0 (0 for descriptors without a
  // frame, or when the frame is clear). Match a query by the least distance over itself and
  // its variants: a wrong guess of the frame then costs nothing, because the right pose is
  // among those tried. Same errors as Compute.
  absl::Status ComputeWithPoseVariants(const PointCloud& cloud, std::vector<float>* out,
                                       std::vector<float>* variants,
                                       const CloudLimits& limits = {}) const;

  // What Compute or ComputeWithPoseVariants costs for a cloud of `num_points` points, from the
  // parameters alone: cheap, no allocation, thread-safe. `working_bytes` bounds the peak heap
  // the call allocates beyond the cloud (the output vectors included, starting empty) from
  // above, for every cloud of that size, with CloudLimits::max_threads = 1 (each further
  // thread may add one copy of the per-thread state, RPHSD's histograms). `cpu` is the
  // expected time on one thread, within about 2x for ordinary clouds (docs/performance.md,
  // "Describe cost"; degenerate clouds may take longer).
  virtual DescribeCost EstimateCost(size_t num_points) const = 0;

  // Which way is up (a unit vector) in the frame this descriptor expects its clouds in: +z
  // unless the spec says otherwise (DFSD's `up`). A caller's sensor `up` is turned onto it.
  virtual std::array<float, 3> up_direction() const { return {0, 0, 1}; }

 protected:
  Descriptor(DescriptorSpec canonical_spec, size_t dimension)
      : spec_(std::move(canonical_spec)), dimension_(dimension) {}

  // Computes the descriptor of a cloud that passed validation; `out` has dimension() floats.
  // `limits` is what the caller gave Compute (its max_threads may be used; see CloudLimits).
  virtual absl::Status ComputeValidated(const PointCloud& cloud, const CloudStats& stats,
                                        const CloudLimits& limits, absl::Span<float> out) const = 0;
  // ComputeValidated, plus the pose variants appended to `variants` (empty on entry). The
  // default has none.
  virtual absl::Status ComputeValidatedWithPoseVariants(const PointCloud& cloud,
                                                        const CloudStats& stats,
                                                        const CloudLimits& limits,
                                                        absl::Span<float> out,
                                                        std::vector<float>* variants) const {
    (void)variants;
    return ComputeValidated(cloud, stats, limits, out);
  }

 private:
  DescriptorSpec spec_;
  size_t dimension_;
};

}  // namespace shapeid

#endif  // SHAPEID_CORE_DESCRIPTOR_H_
