// The fast, data-free slice of the scene accuracy run (bench/scene_accuracy.cc,
// docs/accuracy.md, "Scenes"): a gallery of primitive shapes trained with the project's
// simulated views, tested on frames of the independent ray-caster
// (core/testing/tabletop_frames.h), so no test frame comes from the code that made the
// gallery's views.

#include <algorithm>
#include <cmath>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "core/gallery/gallery.h"
#include "core/scene/scene_recognition.h"
#include "core/testing/tabletop_frames.h"
#include "core/views/test_surfaces.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using testing_frames::MakeTabletopFrame;
using testing_frames::ObjectKind;
using testing_frames::TabletopFrame;
using testing_frames::TabletopFrameOptions;

constexpr const char* kLabels[] = {"sphere", "box", "cylinder"};  // by ObjectKind

// n points uniform on a closed upright cylinder of diameter d and height h, its base at z = 0.
PointCloud CylinderSurface(float d, float h, size_t n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  const float r = d / 2, side = 2 * 3.14159265f * r * h, cap = 3.14159265f * r * r;
  PointCloud cloud;
  for (size_t i = 0; i < n; ++i) {
    const float pick = u(rng) * (side + 2 * cap), angle = 2 * 3.14159265f * u(rng);
    const float rho = pick < side ? r : r * std::sqrt(u(rng));
    const float z = pick < side ? h * u(rng) : pick < side + cap ? 0.0f : h;
    cloud.Add(rho * std::cos(angle), rho * std::sin(angle), z);
  }
  return cloud;
}

// Each kind at the proportions the frames draw (sides 4 to 20 cm), upright, each with 16
// simulated sensor views from above the table.
std::shared_ptr<const GallerySnapshot> PrimitiveGallery() {
  GalleryOptions options;
  options.descriptor_spec = "dfsd:frame=upright";
  options.augment.views = 16;
  options.augment.sensor.view.min_up = 0;  // a camera above the table: 0 to 80 degrees up
  options.augment.sensor.view.max_up = std::sin(80 * 3.14159265358979323846 / 180);
  absl::StatusOr<std::shared_ptr<Gallery>> gallery =
      Gallery::Create("primitives", options, {}, nullptr);
  EXPECT_TRUE(gallery.ok()) << gallery.status();
  std::vector<LabeledCloud> samples;
  const float sizes[] = {0.05f, 0.11f, 0.19f};
  uint32_t seed = 1;
  for (const float d : {0.06f, 0.15f}) {
    samples.push_back({0, "sphere", test_surfaces::SphereSurface(2000, seed++, d / 2), {}});
  }
  for (const float a : sizes) {
    for (const float b : sizes) {
      for (const float c : sizes) {
        samples.push_back(
            {0,
             "box",
             test_surfaces::BoxSurface({0, 0, c / 2}, {a / 2, b / 2, c / 2}, 2000, seed++),
             {}});
      }
      samples.push_back({0, "cylinder", CylinderSurface(a, b, 2000, seed++), {}});
    }
  }
  EXPECT_TRUE((*gallery)->Train(samples).ok());
  return (*gallery)->Snapshot();
}

struct Counts {
  int separated = 0, found = 0, labeled = 0, correct = 0;
};

// Found: a cluster holds >= 50 % of the object's points (ScoreClusters). Labeled: found,
// and the object holds most of that cluster's points, so the answer is about it.
void Score(const TabletopFrame& frame, const SceneRecognition& scene, bool separated,
           Counts* counts) {
  std::vector<std::vector<uint32_t>> clusters;
  for (const RecognizedObject& o : scene.objects) clusters.push_back(o.indices);
  const testing_frames::ClusterScore score = ScoreClusters(frame, clusters, 50);
  if (separated) {
    counts->separated += score.visible;
    counts->found += score.found;
  }
  for (const RecognizedObject& o : scene.objects) {
    if (frame.objects.empty()) continue;
    std::vector<size_t> per_object(frame.objects.size());
    for (const uint32_t i : o.indices) {
      if (frame.truth[i] >= 0) ++per_object[static_cast<size_t>(frame.truth[i])];
    }
    const size_t k = static_cast<size_t>(std::max_element(per_object.begin(), per_object.end()) -
                                         per_object.begin());
    if (2 * per_object[k] < frame.objects[k].points) continue;
    ++counts->labeled;
    counts->correct +=
        o.classification.label == kLabels[static_cast<int>(frame.objects[k].kind)] ? 1 : 0;
  }
}

TEST(SceneAccuracyTest, PrimitivesOnATableAreFoundAndNamed) {
  const std::shared_ptr<const GallerySnapshot> gallery = PrimitiveGallery();
  ASSERT_EQ(gallery->num_samples(), 2 + 27 + 9);
  Counts counts;
  for (uint64_t seed = 1; seed <= 8; ++seed) {
    TabletopFrameOptions options;
    options.width = 320;
    options.height = 240;
    options.touching = seed % 2 == 0;
    options.seed = seed;
    const TabletopFrame frame = MakeTabletopFrame(options);
    const absl::StatusOr<SceneRecognition> scene =
        RecognizeScene(*gallery, frame.cloud, SceneRecognitionOptions());
    ASSERT_TRUE(scene.ok()) << scene.status();
    Score(frame, *scene, !options.touching, &counts);
  }
  ASSERT_GE(counts.separated, 15);
  EXPECT_GE(counts.found, 0.95 * counts.separated) << counts.found << "/" << counts.separated;
  ASSERT_GE(counts.labeled, 25);
  EXPECT_GE(counts.correct, 0.75 * counts.labeled) << counts.correct << "/" << counts.labeled;
}

}  // namespace
}  // namespace shapeid
