#ifndef SHAPEID_SERVER_WORK_COSTS_H_
#define SHAPEID_SERVER_WORK_COSTS_H_

// What the service's work costs, estimated before it runs, so that the scheduler
// (server/work_scheduler.h) can put it in its lane and share the workers fairly, and keep
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
// Describing a query and searching `snapshot` with it and its pose variants.
WorkEstimate EstimateClassify(const GallerySnapshot& snapshot, size_t points);
// Recognising a frame of `points` points with `segmentation`: every RANSAC hypothesis the
// parameters allow, clustering, describing every point once (the objects together hold at
// most the frame) and one search per object, as many as the frame could hold objects of
// min_cluster_points (at most 64 counted).
WorkEstimate EstimateScene(const GallerySnapshot& snapshot, size_t points,
                           const SceneSegmentationOptions& segmentation);
// Appending `vectors` descriptors to `snapshot`'s gallery: O(vectors), the index's blocks are
// shared with the snapshot (the store's write, mostly waiting on the disk, is not counted).
absl::Duration EstimateCommit(const GallerySnapshot& snapshot, int64_t vectors);
// Removing samples from `snapshot`'s gallery: the index is compacted, O(gallery).
absl::Duration EstimateRemove(const GallerySnapshot& snapshot);
// Building and storing a gallery of `vectors` descriptors of `dimension` floats (an import).
absl::Duration EstimateBuild(int64_t vectors, int dimension);

}  // namespace shapeid

#endif  // SHAPEID_SERVER_WORK_COSTS_H_
