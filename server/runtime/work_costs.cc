#include "server/runtime/work_costs.h"

#include <algorithm>
#include <cstdint>
#include <vector>

#include "core/gallery/sample_provenance.h"

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
// One object of a scene beyond describing and searching it: its geometry (a covariance and
// its eigenvectors over its points) and the copy of its points, per point; and its
// answer's fixed part (centroid, box, times, votes).
constexpr double kObjectSecondsPerPoint = 30e-9;
constexpr size_t kObjectAnswerBytes = 256;
// One neighbor of an answer: built into the proto (id, label, distance, view, provenance
// copied) and serialized; its bytes without provenance (a label of up to ~40 bytes).
constexpr double kNeighborSeconds = 0.5e-6;
constexpr size_t kNeighborBytes = 96;
// An answer's bytes: copied into the proto (provenance's sources and metadata maps), then
// serialized on the same worker (work_costs_test: 2,000 neighbors with provenance at its
// limits, 17 MB, in ~30 ms), rounded up.
constexpr double kAnswerSecondsPerByte = 3e-9;
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

namespace {

// Searching `snapshot` once with a query and its pose variants.
absl::Duration SearchCost(const GallerySnapshot& snapshot) {
  const double floats =
      static_cast<double>(snapshot.index().num_rows()) * snapshot.dimension() * kQueryVectors;
  return absl::Seconds(kSearchSecondsPerFloat * floats);
}

// The neighbors an answer with `k` (0: the gallery's) holds.
size_t NeighborsOf(const GallerySnapshot& snapshot, int k) {
  const int64_t wanted = k > 0 ? k : snapshot.options().knn.k;
  return static_cast<size_t>(std::max<int64_t>(0, std::min(wanted, snapshot.num_samples())));
}

}  // namespace

size_t EstimateNeighborBytes(const GallerySnapshot& snapshot, int k) {
  const size_t neighbors = NeighborsOf(snapshot, k);
  // A neighbor's provenance is within the documented limits, and all of them together are
  // never more than the gallery holds.
  const size_t provenance =
      std::min(static_cast<size_t>(std::max<int64_t>(snapshot.provenance_bytes(), 0)),
               neighbors * (kMaxSourceBytes + kMaxMetadataBytes + 4 * kMaxMetadataEntries));
  return neighbors * kNeighborBytes + provenance;
}

WorkEstimate EstimateClassify(const GallerySnapshot& snapshot, size_t points, int k) {
  WorkEstimate estimate;
  if (const std::shared_ptr<const Descriptor>& descriptor = snapshot.shared_descriptor()) {
    estimate = EstimateDescribe(*descriptor, points);
  }
  const size_t answer = EstimateNeighborBytes(snapshot, k);
  estimate.cpu += SearchCost(snapshot) +
                  absl::Seconds(kNeighborSeconds * static_cast<double>(NeighborsOf(snapshot, k)) +
                                kAnswerSecondsPerByte * static_cast<double>(answer));
  estimate.memory += answer;
  return estimate;
}

WorkEstimate EstimateSceneSegmentation(size_t points,
                                       const SceneSegmentationOptions& segmentation) {
  // Each hypothesis tests at most 4,096 drawn points (SegmentScene's scoring sample); the
  // adaptive stop usually ends far sooner, but a caller may ask for the most.
  const double ransac_tests = static_cast<double>(std::max(segmentation.max_planes, 0)) *
                              std::max(segmentation.plane_iterations, 0) *
                              static_cast<double>(std::min<size_t>(points, 4096));
  WorkEstimate estimate;
  estimate.cpu = absl::Seconds(kSegmentSecondsPerPoint * static_cast<double>(points) +
                               kPlaneTestSeconds * ransac_tests);
  estimate.memory = kSegmentBytesPerPoint * points;
  return estimate;
}

WorkEstimate EstimateSceneObjects(const GallerySnapshot& snapshot,
                                  const SceneSegmentation& segmentation, int k, bool indices) {
  WorkEstimate estimate;
  const Descriptor* descriptor = snapshot.shared_descriptor().get();
  const absl::Duration search = SearchCost(snapshot);
  const size_t neighbor_bytes = EstimateNeighborBytes(snapshot, k);
  const double neighbor_seconds = kNeighborSeconds * static_cast<double>(NeighborsOf(snapshot, k));
  size_t working = 0;
  for (const std::vector<uint32_t>& cluster : segmentation.clusters) {
    const size_t points = cluster.size();
    if (descriptor != nullptr) {
      const DescribeCost describe = descriptor->EstimateCost(points);
      estimate.cpu += describe.cpu;
      working = std::max(working, describe.working_bytes + points * 12);
    }
    estimate.cpu += search + absl::Seconds(neighbor_seconds +
                                           kObjectSecondsPerPoint * static_cast<double>(points));
    // The answer: each object with its neighbors, and its indices when asked for.
    estimate.memory += kObjectAnswerBytes + neighbor_bytes + (indices ? 4 * points : 0);
  }
  estimate.memory += working;
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
