#include "core/scene/scene_recognition.h"

#include <array>
#include <string>
#include <utility>

#include "absl/strings/str_cat.h"
#include "core/gallery/gallery_options.h"
#include "core/rigid_transform.h"
#include "core/status_macros.h"

namespace shapeid {

namespace {

absl::Status CheckGallery(const GallerySnapshot& gallery) {
  SHAPEID_RETURN_IF_ERROR(gallery.CheckCompatible());
  return gallery.RequireSamples("recognizing scenes");
}

// Whether the cluster's points lie on a line: its box has no second extent, so no
// descriptor could tell what it is (a wire, a scan line's streak).
bool OnALine(const ClusterGeometry& geometry) {
  return !(geometry.box.size[1] > 1e-5f * geometry.box.size[0]);
}

// Classifies the clusters of `result.segmentation`, moving them into `result.objects`.
absl::Status ClassifyClusters(const GallerySnapshot& gallery, const PointCloud& frame,
                              const SceneRecognitionOptions& options, SceneRecognition& result) {
  const absl::Time start = absl::Now();
  RigidTransform turn;  // identity unless the caller's frame or a plane gives up
  if (options.frame_to_gallery.has_value()) {
    turn = *options.frame_to_gallery;
  } else if (options.up_from_plane && !result.segmentation.planes.empty()) {
    const Eigen::Vector4f& plane = result.segmentation.planes.front().coefficients;
    const std::array<double, 3> up = {plane[0], plane[1], plane[2]};
    absl::StatusOr<RigidTransform> rotation =
        RotationTakingUpTo(up, gallery.shared_descriptor()->up_direction());
    if (rotation.ok()) turn = *rotation;  // a plane's normal is a unit vector: always ok
  }
  std::vector<std::vector<uint32_t>> clusters = std::move(result.segmentation.clusters);
  result.segmentation.clusters.clear();
  result.objects.resize(clusters.size());
  for (size_t c = 0; c < clusters.size(); ++c) {
    if (options.interrupt) {
      if (absl::Status stop = options.interrupt(); !stop.ok()) return stop;
    }
    RecognizedObject& object = result.objects[c];
    object.indices = std::move(clusters[c]);
    object.geometry = DescribeClusterGeometry(frame, object.indices);
    if (OnALine(object.geometry)) {
      object.status = absl::InvalidArgumentError(
          absl::StrCat("the object's ", object.indices.size(), " points ",
                       object.geometry.box.size[0] > 0 ? "lie on a line" : "are all one point",
                       ": there is no shape to recognize"));
      object.classification.label = std::string(kUnknownLabel);
      object.classification.unknown = true;
      continue;
    }
    PointCloud cloud;
    cloud.Reserve(object.indices.size());
    for (const uint32_t i : object.indices) cloud.Add(frame.point(i));
    if (!turn.is_identity()) ApplyRigidTransform(turn, cloud.data(), cloud.size());
    absl::StatusOr<GalleryClassification> answer =
        gallery.Classify(cloud, options.limits, options.k, options.mode);
    if (answer.ok()) {
      object.classification = std::move(answer).value();
    } else {
      object.status = answer.status();
      object.classification.label = std::string(kUnknownLabel);
      object.classification.unknown = true;
    }
  }
  result.classify_time = absl::Now() - start;
  return absl::OkStatus();
}

}  // namespace

absl::StatusOr<SceneSegmentation> SegmentSceneForGallery(const GallerySnapshot& gallery,
                                                         const PointCloud& frame,
                                                         const SceneRecognitionOptions& options) {
  if (absl::Status s = CheckGallery(gallery); !s.ok()) return s;
  const std::array<float, 3> gallery_up = gallery.shared_descriptor()->up_direction();
  SceneSegmentationOptions segmentation_options = options.segmentation;
  if (options.frame_to_gallery.has_value() && !segmentation_options.up.has_value()) {
    // Rotations are orthonormal: the frame's up is the gallery's turned back, R^T up.
    const std::array<float, 9>& r = options.frame_to_gallery->rotation;
    segmentation_options.up =
        Eigen::Vector3f(r[0] * gallery_up[0] + r[3] * gallery_up[1] + r[6] * gallery_up[2],
                        r[1] * gallery_up[0] + r[4] * gallery_up[1] + r[7] * gallery_up[2],
                        r[2] * gallery_up[0] + r[5] * gallery_up[1] + r[8] * gallery_up[2]);
  }
  if (options.interrupt) segmentation_options.interrupt = options.interrupt;
  return SegmentScene(frame, segmentation_options);
}

absl::StatusOr<SceneRecognition> RecognizeScene(const GallerySnapshot& gallery,
                                                const PointCloud& frame,
                                                const SceneRecognitionOptions& options) {
  const absl::Time start = absl::Now();
  absl::StatusOr<SceneSegmentation> segmentation = SegmentSceneForGallery(gallery, frame, options);
  if (!segmentation.ok()) return segmentation.status();
  const absl::Duration segment_time = absl::Now() - start;
  absl::StatusOr<SceneRecognition> result =
      ClassifySceneObjects(gallery, frame, *std::move(segmentation), options);
  if (result.ok()) result->segment_time = segment_time;
  return result;
}

absl::StatusOr<SceneRecognition> ClassifySceneObjects(const GallerySnapshot& gallery,
                                                      const PointCloud& frame,
                                                      SceneSegmentation segmentation,
                                                      const SceneRecognitionOptions& options) {
  if (absl::Status s = CheckGallery(gallery); !s.ok()) return s;
  SceneRecognition result;
  result.segmentation = std::move(segmentation);
  if (absl::Status s = ClassifyClusters(gallery, frame, options, result); !s.ok()) return s;
  return result;
}

}  // namespace shapeid
