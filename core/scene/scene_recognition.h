#ifndef SHAPEID_CORE_SCENE_SCENE_RECOGNITION_H_
#define SHAPEID_CORE_SCENE_SCENE_RECOGNITION_H_

// One sensor frame in, the objects on it out: SegmentScene (core/scene) finds them, the
// gallery classifies each as the partial view it is.

#include <cstdint>
#include <functional>
#include <optional>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/time/time.h"
#include "core/gallery/gallery_snapshot.h"
#include "core/point_cloud.h"
#include "core/rigid_transform.h"
#include "core/scene/scene_segmentation.h"

namespace shapeid {

struct SceneRecognitionOptions {
  SceneSegmentationOptions segmentation;
  // Neighbors per object; 0: the gallery's k.
  int k = 0;
  SearchMode mode = SearchMode::kDefault;
  // The caller's sensor frame (proto SensorFrame): the transform from the frame's
  // coordinates into the gallery's. When set, each object is moved by it before it is
  // described, and the up it implies (R^T times the descriptor's up) is the segmentation's
  // `up` unless that is set: only supports perpendicular to it are removed. Segmentation,
  // geometry and indices stay in the frame's own coordinates.
  std::optional<RigidTransform> frame_to_gallery;
  // Without a sensor frame: each object is turned so that the first removed plane's normal
  // (pointing to the sensor's side: up, for a table seen from above) becomes the
  // descriptor's up before it is described. Off, or with no plane, objects are described in
  // the frame's own axes.
  bool up_from_plane = true;
  // Limits each object's cloud as Classify's limits do.
  CloudLimits limits;
  // Asked between objects and between the segmentation's planes: a non-OK status (the
  // caller's deadline passed, its call was cancelled) stops the work and is returned. Empty:
  // never stop.
  std::function<absl::Status()> interrupt;
};

struct RecognizedObject {
  // The gallery's answer for this object's points, as Classify gives it (label, or
  // kUnknownLabel when rejected; neighbors, votes). When the object could not be described
  // (`status` not OK: its points lie on a line, or the descriptor refused them) the label
  // is kUnknownLabel with no neighbors.
  GalleryClassification classification;
  absl::Status status;
  ClusterGeometry geometry;       // in the frame's coordinates
  std::vector<uint32_t> indices;  // into the frame, ascending
};

struct SceneRecognition {
  // The planes and the accounting of the frame's points (its `clusters` are moved into
  // `objects`, so they are empty here).
  SceneSegmentation segmentation;
  std::vector<RecognizedObject> objects;  // largest first, as SegmentScene orders clusters
  absl::Duration segment_time;
  absl::Duration classify_time;  // all objects
};

// Errors: SegmentScene's (options out of range: InvalidArgument); the gallery's
// (FailedPrecondition for an empty or incompatible gallery), checked before any work;
// options.interrupt's. An object that fails to be described does not fail the frame: see
// RecognizedObject::status. The same as SegmentSceneForGallery, then ClassifySceneObjects.
absl::StatusOr<SceneRecognition> RecognizeScene(const GallerySnapshot& gallery,
                                                const PointCloud& frame,
                                                const SceneRecognitionOptions& options);

// RecognizeScene's first half: the frame's planes and clusters, with the segmentation's up
// taken from options.frame_to_gallery when it does not give one. For callers that plan the
// second half's cost from the clusters found (a server's scheduler). Errors as
// RecognizeScene's.
absl::StatusOr<SceneSegmentation> SegmentSceneForGallery(const GallerySnapshot& gallery,
                                                         const PointCloud& frame,
                                                         const SceneRecognitionOptions& options);

// RecognizeScene's second half, for a frame segmented elsewhere (another library's planes
// and clusters, with indices into `frame`): classifies each cluster as RecognizeScene does,
// turned by options.frame_to_gallery or the first plane. `segmentation`'s clusters must be
// non-empty and index finite points of `frame`. Errors: the gallery's and options.interrupt's,
// as RecognizeScene.
absl::StatusOr<SceneRecognition> ClassifySceneObjects(const GallerySnapshot& gallery,
                                                      const PointCloud& frame,
                                                      SceneSegmentation segmentation,
                                                      const SceneRecognitionOptions& options);

}  // namespace shapeid

#endif  // SHAPEID_CORE_SCENE_SCENE_RECOGNITION_H_
