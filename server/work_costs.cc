#include "server/work_costs.h"

#include <algorithm>

namespace shapeid {
namespace {

// Exact search reads every stored float once per query vector (bench/knn_bench: 100,000 x
// 81 floats in ~0.6 ms, 0.075 ns a float, on the 2-core VM); rounded up.
constexpr double kSearchSecondsPerFloat = 0.1e-9;
// A query is searched with itself and its pose variants (dfsd's box frame: up to 8, most
// often 2); an estimate, not a bound.
constexpr double kQueryVectors = 3;
// Writing a row into the index, or rewriting one when a removal compacts it, per float
// (2-5 ns a float copied and folded into the statistics).
constexpr double kCommitSecondsPerFloat = 4e-9;
// An append's fixed part: the index's last block (at most 2 MiB) and a chunk of each table
// copied (bench/commit_bench: one sample into 10^6 x 240 in 0.2 ms), rounded up.
constexpr double kAppendFixedSeconds = 0.5e-3;
// Scene segmentation per frame point, planes and clusters (bench/pcl/scene_segmentation_bench:
// 13-15 ms for a 307,000-point frame), rounded up; and its working memory per point (the
// candidate and cluster index lists, the grid, each object's copy).
constexpr double kSegmentSecondsPerPoint = 60e-9;
constexpr size_t kSegmentBytesPerPoint = 40;
constexpr size_t kMaxCountedObjects = 64;
// One point tested against one RANSAC hypothesis (a multiply-add and a compare, vectorised).
constexpr double kPlaneTestSeconds = 1e-9;
// The sensor simulator's cost per input point for one synthetic view
// (core/views/scan_simulator_bench), rounded up.
constexpr double kViewSecondsPerPoint = 100e-9;

}  // namespace

WorkEstimate EstimateDescribe(const Descriptor& descriptor, size_t points) {
  const DescribeCost cost = descriptor.EstimateCost(points);
  return WorkEstimate{cost.cpu, cost.working_bytes};
}

WorkEstimate EstimateTrainSample(const Descriptor& descriptor, const AugmentOptions& augment,
                                 size_t points) {
  WorkEstimate estimate = EstimateDescribe(descriptor, points);
  if (!augment.enabled()) return estimate;
  const size_t view_points = std::min(points, augment.sensor.max_points);
  const DescribeCost view = descriptor.EstimateCost(view_points);
  estimate.cpu += augment.views *
                  (view.cpu + absl::Seconds(kViewSecondsPerPoint * static_cast<double>(points)));
  // Views are made and described one after another; each view holds its own points.
  estimate.memory = std::max(estimate.memory, view.working_bytes + view_points * 12 + points * 12);
  return estimate;
}

WorkEstimate EstimateClassify(const GallerySnapshot& snapshot, size_t points) {
  WorkEstimate estimate;
  if (const std::shared_ptr<const Descriptor>& descriptor = snapshot.shared_descriptor()) {
    estimate = EstimateDescribe(*descriptor, points);
  }
  const double floats =
      static_cast<double>(snapshot.index().num_rows()) * snapshot.dimension() * kQueryVectors;
  estimate.cpu += absl::Seconds(kSearchSecondsPerFloat * floats);
  return estimate;
}

WorkEstimate EstimateScene(const GallerySnapshot& snapshot, size_t points,
                           const SceneSegmentationOptions& segmentation) {
  WorkEstimate estimate;
  if (const std::shared_ptr<const Descriptor>& descriptor = snapshot.shared_descriptor()) {
    estimate = EstimateDescribe(*descriptor, points);
  }
  const size_t objects =
      std::min(kMaxCountedObjects, points / std::max<size_t>(segmentation.min_cluster_points, 1));
  // Each hypothesis tests at most 4,096 drawn points (SegmentScene's scoring sample); the
  // adaptive stop usually ends far sooner, but a caller may ask for the most.
  const double ransac_tests = static_cast<double>(std::max(segmentation.max_planes, 0)) *
                              std::max(segmentation.plane_iterations, 0) *
                              static_cast<double>(std::min<size_t>(points, 4096));
  const double floats = static_cast<double>(snapshot.index().num_rows()) * snapshot.dimension() *
                        kQueryVectors * static_cast<double>(objects);
  estimate.cpu += absl::Seconds(kSearchSecondsPerFloat * floats +
                                kSegmentSecondsPerPoint * static_cast<double>(points) +
                                kPlaneTestSeconds * ransac_tests);
  estimate.memory += kSegmentBytesPerPoint * points;
  return estimate;
}

absl::Duration EstimateCommit(const GallerySnapshot& snapshot, int64_t vectors) {
  const double floats = static_cast<double>(std::max<int64_t>(vectors, 0)) * snapshot.dimension();
  return absl::Seconds(kAppendFixedSeconds + kCommitSecondsPerFloat * floats);
}

absl::Duration EstimateRemove(const GallerySnapshot& snapshot) {
  const double floats = static_cast<double>(snapshot.index().num_rows()) * snapshot.dimension();
  return absl::Seconds(kCommitSecondsPerFloat * floats);
}

absl::Duration EstimateBuild(int64_t vectors, int dimension) {
  return absl::Seconds(kCommitSecondsPerFloat * static_cast<double>(vectors) * dimension);
}

}  // namespace shapeid
