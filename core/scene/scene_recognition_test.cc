#include "core/scene/scene_recognition.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "Eigen/Geometry"
#include "core/gallery/gallery.h"
#include "core/testing/test_clouds.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;
using testing_clouds::kShapeNames;
using testing_clouds::kTableHeight;
using testing_clouds::ShapeCloud;
using testing_clouds::TableWithShapes;

std::shared_ptr<Gallery> ShapesGallery(bool trained) {
  GalleryOptions options;
  options.descriptor_spec = "rphsd";
  options.knn.k = 1;
  absl::StatusOr<std::shared_ptr<Gallery>> gallery =
      Gallery::Create("shapes", options, {}, nullptr);
  EXPECT_TRUE(gallery.ok()) << gallery.status();
  if (!trained) return *gallery;
  TrainBatch batch = (*gallery)->NewBatch();
  uint64_t id = 1;
  for (int kind = 0; kind < 3; ++kind) {
    for (uint32_t seed = 1; seed <= 3; ++seed) {
      EXPECT_TRUE(batch.AddSample(id++, kShapeNames[kind], ShapeCloud(kind, seed, 2000)).ok());
    }
  }
  EXPECT_TRUE(batch.Commit().ok());
  return *gallery;
}

TEST(SceneRecognitionTest, FindsAndNamesEachObjectOnTheTable) {
  const std::shared_ptr<Gallery> gallery = ShapesGallery(true);
  std::vector<std::vector<uint32_t>> truth;
  const PointCloud frame = TableWithShapes(&truth);
  const absl::StatusOr<SceneRecognition> scene =
      RecognizeScene(*gallery->Snapshot(), frame, SceneRecognitionOptions());
  ASSERT_TRUE(scene.ok()) << scene.status();
  ASSERT_EQ(scene->segmentation.planes.size(), 1u);
  EXPECT_NEAR(scene->segmentation.planes[0].coefficients[2], 1.0f, 1e-4f);
  EXPECT_TRUE(scene->segmentation.clusters.empty());  // moved into the objects
  ASSERT_EQ(scene->objects.size(), 3u);
  std::vector<std::string> labels;
  for (const RecognizedObject& object : scene->objects) {
    EXPECT_TRUE(object.status.ok()) << object.status;
    ASSERT_EQ(object.indices.size(), 3000u);
    const int kind = static_cast<int>((object.indices.front() - truth[0].front()) / 3000);
    EXPECT_EQ(object.indices, truth[static_cast<size_t>(kind)]);
    EXPECT_EQ(object.classification.label, kShapeNames[kind]);
    EXPECT_FALSE(object.classification.knn.neighbors.empty());
    EXPECT_EQ(object.classification.provenance.size(), object.classification.knn.neighbors.size());
    // The sphere's centroid is where it was put; its box about 10 cm on each side.
    if (kind == 1) {
      EXPECT_LT(
          (object.geometry.centroid - Eigen::Vector3f(-0.3f, -0.1f, kTableHeight + 0.08f)).norm(),
          0.005f);
      EXPECT_NEAR(object.geometry.box.size[0], 0.1f, 0.005f);
    }
  }
  EXPECT_GE(scene->segment_time, absl::ZeroDuration());
}

// An object that cannot be described (here every point identical) is answered unknown with
// its reason; the other objects are still recognized.
TEST(SceneRecognitionTest, AnObjectThatCannotBeDescribedIsUnknownNotAFailure) {
  const std::shared_ptr<Gallery> gallery = ShapesGallery(true);
  std::vector<std::vector<uint32_t>> truth;
  PointCloud frame = TableWithShapes(&truth);
  for (int i = 0; i < 150; ++i) frame.Add(0.5f, 0.5f, kTableHeight + 0.2f);
  const absl::StatusOr<SceneRecognition> scene =
      RecognizeScene(*gallery->Snapshot(), frame, SceneRecognitionOptions());
  ASSERT_TRUE(scene.ok()) << scene.status();
  ASSERT_EQ(scene->objects.size(), 4u);
  const RecognizedObject& stuck = scene->objects.back();  // the smallest
  EXPECT_EQ(stuck.indices.size(), 150u);
  EXPECT_EQ(stuck.status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(stuck.classification.label, kUnknownLabel);
  EXPECT_TRUE(stuck.classification.unknown);
  EXPECT_TRUE(stuck.classification.knn.neighbors.empty());
  for (size_t i = 0; i < 3; ++i) EXPECT_TRUE(scene->objects[i].status.ok());
}

// As the proto says: a cluster on a line (a wire, a scan line's streak) gets an error and
// "unknown", though the default descriptor could describe it.
TEST(SceneRecognitionTest, AnObjectOnALineIsUnknownWithTheReason) {
  const std::shared_ptr<Gallery> gallery = ShapesGallery(true);
  PointCloud frame = TableWithShapes();
  for (int i = 0; i < 150; ++i) {
    frame.Add(0.5f + 0.002f * static_cast<float>(i), 0.5f, kTableHeight + 0.2f);
  }
  const absl::StatusOr<SceneRecognition> scene =
      RecognizeScene(*gallery->Snapshot(), frame, SceneRecognitionOptions());
  ASSERT_TRUE(scene.ok()) << scene.status();
  ASSERT_EQ(scene->objects.size(), 4u);
  const RecognizedObject& wire = scene->objects.back();
  EXPECT_EQ(wire.indices.size(), 150u);
  EXPECT_EQ(wire.status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(wire.status.message(), HasSubstr("lie on a line"));
  EXPECT_EQ(wire.classification.label, kUnknownLabel);
  EXPECT_TRUE(wire.classification.knn.neighbors.empty());
}

// A caller's deadline or cancellation stops the work between objects, not after the frame.
TEST(SceneRecognitionTest, AnInterruptionStopsTheWorkBetweenObjects) {
  const std::shared_ptr<Gallery> gallery = ShapesGallery(true);
  const PointCloud frame = TableWithShapes();
  int asked = 0;
  SceneRecognitionOptions options;
  options.interrupt = [&asked] {
    return ++asked > 3 ? absl::DeadlineExceededError("the caller's deadline passed")
                       : absl::OkStatus();
  };
  // One plane, then clustering, then the first object: the second object is never described.
  const absl::StatusOr<SceneRecognition> scene =
      RecognizeScene(*gallery->Snapshot(), frame, options);
  EXPECT_EQ(scene.status().code(), absl::StatusCode::kDeadlineExceeded);
  EXPECT_EQ(asked, 4);
  options.interrupt = [] { return absl::CancelledError("the call was cancelled"); };
  EXPECT_EQ(RecognizeScene(*gallery->Snapshot(), frame, options).status().code(),
            absl::StatusCode::kCancelled);
}

TEST(SceneRecognitionTest, EmptyGalleryIsRefusedBeforeAnyWork) {
  std::vector<std::vector<uint32_t>> truth;
  const absl::StatusOr<SceneRecognition> scene =
      RecognizeScene(*ShapesGallery(false)->Snapshot(), TableWithShapes(&truth), {});
  EXPECT_EQ(scene.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(scene.status().message(), HasSubstr("'shapes' has no samples"));
}

TEST(SceneRecognitionTest, BadSegmentationOptionsAreInvalidArgument) {
  SceneRecognitionOptions options;
  options.segmentation.cluster_tolerance = 0;
  std::vector<std::vector<uint32_t>> truth;
  const absl::StatusOr<SceneRecognition> scene =
      RecognizeScene(*ShapesGallery(true)->Snapshot(), TableWithShapes(&truth), options);
  EXPECT_EQ(scene.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(scene.status().message(), HasSubstr("cluster_tolerance"));
}

// A frame whose table is tilted (about an axis in the table) is turned back so that the
// table's normal is the descriptor's up: each object then matches its nearest sample as
// closely as on the level table. Without up_from_plane, in the frame's own axes, it does not.
TEST(SceneRecognitionTest, TheTableGivesUp) {
  const std::shared_ptr<Gallery> gallery = ShapesGallery(true);
  std::vector<std::vector<uint32_t>> truth;
  const PointCloud level = TableWithShapes(&truth);
  const Eigen::Matrix3f tilt =
      Eigen::AngleAxisf(0.7f, Eigen::Vector3f(1, 0.3f, 0).normalized()).toRotationMatrix();
  PointCloud tilted;
  for (size_t i = 0; i < level.size(); ++i) tilted.Add(tilt * level.point(i));
  SceneRecognitionOptions frame_axes;
  frame_axes.up_from_plane = false;
  const auto snapshot = gallery->Snapshot();
  const absl::StatusOr<SceneRecognition> on_level = RecognizeScene(*snapshot, level, {});
  const absl::StatusOr<SceneRecognition> turned = RecognizeScene(*snapshot, tilted, {});
  const absl::StatusOr<SceneRecognition> unturned = RecognizeScene(*snapshot, tilted, frame_axes);
  ASSERT_TRUE(on_level.ok() && turned.ok() && unturned.ok());
  ASSERT_EQ(turned->objects.size(), 3u);
  ASSERT_EQ(unturned->objects.size(), 3u);
  double largest_unturned_change = 0;
  for (size_t i = 0; i < 3; ++i) {
    const double reference = on_level->objects[i].classification.knn.neighbors[0].distance;
    const double with_up = turned->objects[i].classification.knn.neighbors[0].distance;
    const double without = unturned->objects[i].classification.knn.neighbors[0].distance;
    EXPECT_NEAR(with_up, reference, 1e-3 * reference + 1e-6) << "object " << i;
    largest_unturned_change =
        std::max(largest_unturned_change, std::fabs(without - reference) / reference);
    EXPECT_EQ(turned->objects[i].classification.label, on_level->objects[i].classification.label);
  }
  EXPECT_GT(largest_unturned_change, 0.05);
}

// The caller's sensor frame replaces the plane: the tilted frame with its transform back to
// the table's axes gives the level frame's distances, and the geometry stays in the frame's
// own coordinates.
TEST(SceneRecognitionTest, ASensorFrameTurnsTheObjectsAndKeepsTheFramesCoordinates) {
  const std::shared_ptr<Gallery> gallery = ShapesGallery(true);
  std::vector<std::vector<uint32_t>> truth;
  const PointCloud level = TableWithShapes(&truth);
  const Eigen::Matrix3f tilt =
      Eigen::AngleAxisf(0.7f, Eigen::Vector3f(1, 0.3f, 0).normalized()).toRotationMatrix();
  PointCloud tilted;
  for (size_t i = 0; i < level.size(); ++i) tilted.Add(tilt * level.point(i));
  SceneRecognitionOptions options;
  RigidTransform back;
  const Eigen::Matrix3f inverse = tilt.transpose();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) back.rotation[3 * r + c] = inverse(r, c);
  }
  options.frame_to_gallery = back;
  options.up_from_plane = false;  // the frame, not the plane, gives up
  const auto snapshot = gallery->Snapshot();
  const absl::StatusOr<SceneRecognition> on_level = RecognizeScene(*snapshot, level, {});
  const absl::StatusOr<SceneRecognition> turned = RecognizeScene(*snapshot, tilted, options);
  ASSERT_TRUE(on_level.ok() && turned.ok());
  ASSERT_EQ(turned->objects.size(), 3u);
  ASSERT_EQ(turned->segmentation.planes.size(), 1u);
  // The table's normal, in the tilted frame, along the frame's up (tilt times +z).
  const Eigen::Vector3f up = tilt.col(2);
  EXPECT_GT(turned->segmentation.planes[0].coefficients.head<3>().dot(up), 0.9999f);
  for (size_t i = 0; i < 3; ++i) {
    const double reference = on_level->objects[i].classification.knn.neighbors[0].distance;
    EXPECT_NEAR(turned->objects[i].classification.knn.neighbors[0].distance, reference,
                1e-3 * reference + 1e-6)
        << "object " << i;
    EXPECT_EQ(turned->objects[i].indices, on_level->objects[i].indices);
    EXPECT_LT((turned->objects[i].geometry.centroid - tilt * on_level->objects[i].geometry.centroid)
                  .norm(),
              1e-4f);
  }
}

// A frame segmented elsewhere (here by SegmentScene itself) is classified exactly as
// RecognizeScene classifies it.
TEST(SceneRecognitionTest, ClustersFromElsewhereAreClassifiedTheSameWay) {
  const std::shared_ptr<Gallery> gallery = ShapesGallery(true);
  std::vector<std::vector<uint32_t>> truth;
  const PointCloud frame = TableWithShapes(&truth);
  const auto snapshot = gallery->Snapshot();
  const absl::StatusOr<SceneRecognition> whole = RecognizeScene(*snapshot, frame, {});
  absl::StatusOr<SceneSegmentation> segmentation = SegmentScene(frame, {});
  ASSERT_TRUE(whole.ok() && segmentation.ok());
  const absl::StatusOr<SceneRecognition> halves =
      ClassifySceneObjects(*snapshot, frame, *std::move(segmentation), {});
  ASSERT_TRUE(halves.ok()) << halves.status();
  ASSERT_EQ(halves->objects.size(), whole->objects.size());
  for (size_t i = 0; i < whole->objects.size(); ++i) {
    EXPECT_EQ(halves->objects[i].indices, whole->objects[i].indices);
    EXPECT_EQ(halves->objects[i].classification.label, whole->objects[i].classification.label);
    EXPECT_EQ(halves->objects[i].classification.knn.neighbors[0].distance,
              whole->objects[i].classification.knn.neighbors[0].distance);
  }
  EXPECT_EQ(ClassifySceneObjects(*ShapesGallery(false)->Snapshot(), frame, {}, {}).status().code(),
            absl::StatusCode::kFailedPrecondition);
}

}  // namespace
}  // namespace shapeid
