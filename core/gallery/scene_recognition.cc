#include "core/gallery/scene_recognition.h"

#include <array>
#include <string>
#include <utility>

#include "absl/strings/str_cat.h"
#include "core/gallery/gallery_options.h"
#include "core/rigid_transform.h"

namespace shapeid {

absl::StatusOr<SceneRecognition> RecognizeScene(const GallerySnapshot& gallery,
                                                const PointCloud& frame,
                                                const SceneRecognitionOptions& options) {
  if (!gallery.incompatible().empty()) {
    return absl::FailedPreconditionError(gallery.incompatible());
  }
  if (gallery.empty()) {
    return absl::FailedPreconditionError(absl::StrCat(
        "gallery '", gallery.name(), "' has no samples; train it before recognising scenes"));
  }
  SceneRecognition result;
  const absl::Time start = absl::Now();
  absl::StatusOr<SceneSegmentation> segmentation = SegmentScene(frame, options.segmentation);
  if (!segmentation.ok()) return segmentation.status();
  result.segmentation = std::move(segmentation).value();
  const absl::Time segmented = absl::Now();
  result.segment_time = segmented - start;

  RigidTransform turn;  // identity unless a plane gives up
  if (options.up_from_plane && !result.segmentation.planes.empty()) {
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
    RecognizedObject& object = result.objects[c];
    object.indices = std::move(clusters[c]);
    object.geometry = DescribeClusterGeometry(frame, object.indices);
    PointCloud cloud;
    cloud.Reserve(object.indices.size());
    for (const uint32_t i : object.indices) cloud.Add(frame.point(i));
    if (!turn.is_identity()) ApplyRigidTransform(turn, cloud.data(), cloud.size());
    absl::StatusOr<GalleryClassification> answer =
        gallery.Classify(cloud, options.limits, options.k);
    if (answer.ok()) {
      object.classification = std::move(answer).value();
    } else {
      object.status = answer.status();
      object.classification.label = std::string(kUnknownLabel);
      object.classification.unknown = true;
    }
  }
  result.classify_time = absl::Now() - segmented;
  return result;
}

}  // namespace shapeid
