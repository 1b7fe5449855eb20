#ifndef SHAPEID_CORE_DESCRIPTORS_CNSD_H_
#define SHAPEID_CORE_DESCRIPTORS_CNSD_H_

#include <vector>

#include "absl/status/status.h"
#include "absl/types/span.h"
#include "core/descriptor_registry.h"
#include "core/point_cloud.h"
#include "core/simd.h"

namespace shapeid {

// CNSD-3D, the complex network shape descriptor (docs/descriptors.md section 3):
//   cnsd:t_start=0.05,t_end=0.95,t_step=0.05,max_points=8000,downsample=voxel,seed=0
// Every point is a vertex, the edge (i, j) weighs d(i, j) / d_max, and for each threshold
// T_k = t_start + k * t_step <= t_end the graph keeping edges with weight <= T_k gives the
// mean and the maximum of degree / n. Dimension 2 * (number of thresholds), laid out
// [D_avg(T_0), D_max(T_0), D_avg(T_1), D_max(T_1), ...]. Time O(n^2 + n S); memory O(n S)
// up to 31 thresholds, O(n + S) beyond (cnsd_kernels.h).
DescriptorKind CnsdKind();

// Building blocks, exposed for tests and benchmarks. Not a stable API. The pair passes are in
// cnsd_kernels.h, downsampling in cnsd_downsample.h.
namespace cnsd_internal {

// T_k = t_start + k * t_step for k = 0, 1, ... while T_k <= t_end + 1e-9; a T_k within 1e-9
// of t_end is snapped to t_end, so t_end = 1 always means "every pair".
std::vector<double> Thresholds(double t_start, double t_end, double t_step);

// The coordinates the pair loop works on: each point minus the bounding-box center, times the
// power of two that brings the largest centered coordinate into [0.5, 1), rounded to float.
// Interleaved xyz like PointCloud. Exact under permutation and power-of-two scaling.
std::vector<float> NormalizedXyz(const PointCloud& cloud);

// The squared-distance bound of threshold `t`: the largest float that is <= t * t * max_d2
// evaluated in double. A pair is joined at `t` exactly when its float squared distance
// (dx*dx + dy*dy) + dz*dz, on NormalizedXyz coordinates, is <= this bound; for t = 1 the
// bound is max_d2 itself, so the farthest pair is always joined at T = 1.
float SquaredThreshold(double t, float max_d2);

// The descriptor of `cloud` as it is (no downsampling), with the pair kernels of `level`
// (lowered to DetectedSimdLevel(); every level gives the same bits). `thresholds` ascend;
// when they are not evenly spaced at least 1e-4 apart, as Thresholds() makes them, the scalar
// kernel runs whatever `level` says. `out` has 2 * thresholds.size() floats.
// InvalidArgument when the cloud has fewer than 2 points or all of them coincide.
absl::Status ComputeFeatures(const PointCloud& cloud, absl::Span<const double> thresholds,
                             SimdLevel level, absl::Span<float> out);

}  // namespace cnsd_internal
}  // namespace shapeid

#endif  // SHAPEID_CORE_DESCRIPTORS_CNSD_H_
