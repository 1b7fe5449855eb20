#ifndef SHAPEID_SERVER_RUNTIME_WORK_COSTS_H_
#define SHAPEID_SERVER_RUNTIME_WORK_COSTS_H_

// What the service's work costs, estimated before it runs, so that the scheduler
// (server/runtime/work_scheduler.h) can put it in its lane and share the workers fairly, and keep
// working memory within the budget. From the descriptors' own estimates
// (Descriptor::EstimateCost) and the size of galleries; docs/reliability.md has the figures
// they come from.

#include <cstddef>
#include <cstdint>

#include "absl/time/time.h"
#include "core/descriptor.h"
#include "core/gallery/gallery_snapshot.h"
#include "core/scene/scene_segmentation.h"
#include "core/views/augment.h"

namespace shapeid {

struct WorkEstimate {
  absl::Duration cpu;
  size_t memory = 0;  // working memory beyond the cloud, which the call holds already
};

// Describing a cloud of `points` points.
WorkEstimate EstimateDescribe(const Descriptor& descriptor, size_t points);
// Describing a training cloud and, with `augment` on, making and describing its views.
WorkEstimate EstimateTrainSample(const Descriptor& descriptor, const AugmentOptions& augment,
                                 size_t points);
// Describing a query, searching `snapshot` with it and its pose variants, and answering
// with `k` neighbors (0: the gallery's k). Its memory counts the answer, which may carry
// each neighbor's provenance (EstimateNeighborBytes).
WorkEstimate EstimateClassify(const GallerySnapshot& snapshot, size_t points, int k = 0);
// The bytes `k` neighbors (0: the gallery's k) of `snapshot` can add to an answer: ids,
// labels, distances and, for samples trained with provenance, their source and metadata.
size_t EstimateNeighborBytes(const GallerySnapshot& snapshot, int k);
// A scene's first half: finding the supports and the clusters of a frame of `points` points
// with `segmentation` (every RANSAC hypothesis the parameters allow, then clustering).
WorkEstimate EstimateSceneSegmentation(size_t points, const SceneSegmentationOptions& segmentation);
// Its second half, planned once the clusters are known: describing each cluster and
// searching `snapshot` with it, and the answer (each object with `k` neighbors, and its
// points' indices when `indices`).
WorkEstimate EstimateSceneObjects(const GallerySnapshot& snapshot,
                                  const SceneSegmentation& segmentation, int k, bool indices);
// Appending `vectors` descriptors to `snapshot`'s gallery: O(vectors), the index's blocks are
// shared with the snapshot (the store's write, mostly waiting on the disk, is not counted).
absl::Duration EstimateCommit(const GallerySnapshot& snapshot, int64_t vectors);
// Removing samples from `snapshot`'s gallery: the index is compacted, O(gallery).
absl::Duration EstimateRemove(const GallerySnapshot& snapshot);
// Building and storing a gallery of `vectors` descriptors of `dimension` floats (an import).
absl::Duration EstimateBuild(int64_t vectors, int dimension);

}  // namespace shapeid

#endif  // SHAPEID_SERVER_RUNTIME_WORK_COSTS_H_
