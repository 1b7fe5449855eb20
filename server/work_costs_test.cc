#include "server/work_costs.h"

#include <memory>
#include <string>
#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "core/descriptor_registry.h"
#include "core/gallery/gallery.h"
#include "core/gallery/gallery_store.h"
#include "core/views/augment.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

// A gallery of `samples` rphsd samples (features made up: only the sizes matter here).
std::shared_ptr<const GallerySnapshot> GalleryOf(int64_t samples) {
  StoredGallery stored;
  stored.name = "costs";
  stored.options.descriptor_spec = "rphsd";
  stored.created = stored.updated = absl::Now();
  auto descriptor = CreateDescriptor(stored.options.descriptor_spec);
  EXPECT_TRUE(descriptor.ok()) << descriptor.status();
  stored.dimension = static_cast<int>((*descriptor)->dimension());
  stored.descriptor_version = FindDescriptorKind("rphsd")->version;
  for (int64_t i = 0; i < samples; ++i) {
    StoredSample sample{static_cast<uint64_t>(i + 1), absl::StrCat("c", i % 7),
                        std::vector<float>(stored.dimension)};
    for (int j = 0; j < stored.dimension; ++j)
      sample.features[j] = static_cast<float>((i + j) % 13);
    stored.samples.push_back(std::move(sample));
  }
  auto gallery = Gallery::Restore(stored, GalleryLimits{}, nullptr);
  EXPECT_TRUE(gallery.ok()) << gallery.status();
  return (*gallery)->Snapshot();
}

TEST(WorkCostsTest, AnAppendCostsTheSameWhateverTheGallerysSize) {
  const auto small = GalleryOf(10);
  const auto large = GalleryOf(20'000);
  EXPECT_EQ(EstimateCommit(*small, 1), EstimateCommit(*large, 1));
  EXPECT_GT(EstimateCommit(*large, 1'000), EstimateCommit(*large, 1));
  EXPECT_LT(EstimateCommit(*large, 1), absl::Milliseconds(20)) << "a one-sample commit is cheap";
}

TEST(WorkCostsTest, RemovalAndSearchGrowWithTheGallery) {
  const auto small = GalleryOf(10);
  const auto large = GalleryOf(20'000);
  EXPECT_GT(EstimateRemove(*large), 100 * EstimateRemove(*small));
  EXPECT_GT(EstimateClassify(*large, 1024).cpu, EstimateClassify(*small, 1024).cpu);
  EXPECT_EQ(EstimateClassify(*large, 1024).memory, EstimateClassify(*small, 1024).memory);
}

TEST(WorkCostsTest, TrainingViewsCostMoreThanThePlainSampleAndBuildsScaleWithTheirSize) {
  auto descriptor = CreateDescriptor("rphsd");
  ASSERT_TRUE(descriptor.ok());
  const WorkEstimate plain = EstimateTrainSample(**descriptor, AugmentOptions{}, 10'000);
  EXPECT_EQ(plain.cpu, EstimateDescribe(**descriptor, 10'000).cpu);
  AugmentOptions augment;
  augment.views = 8;
  EXPECT_GT(EstimateTrainSample(**descriptor, augment, 10'000).cpu, 8 * plain.cpu);
  EXPECT_NEAR(absl::FDivDuration(EstimateBuild(2'000'000, 240), EstimateBuild(1'000'000, 240)), 2.0,
              1e-9);
}

// A scene costs at least describing its whole frame and searching once, and more when the
// caller allows more RANSAC work or smaller objects (more of them to search).
TEST(WorkCostsTest, AScenesCostFollowsItsFrameAndItsParameters) {
  const auto gallery = GalleryOf(1'000);
  const SceneSegmentationOptions defaults;
  const WorkEstimate frame = EstimateScene(*gallery, 300'000, defaults);
  EXPECT_GT(frame.cpu, EstimateClassify(*gallery, 300'000).cpu);
  EXPECT_GT(frame.memory, EstimateClassify(*gallery, 300'000).memory);
  SceneSegmentationOptions heavy = defaults;
  heavy.max_planes = 16;
  heavy.plane_iterations = 10'000;
  EXPECT_GT(EstimateScene(*gallery, 300'000, heavy).cpu, frame.cpu + absl::Milliseconds(500));
  SceneSegmentationOptions small_objects = defaults;
  small_objects.min_cluster_points = 10;
  EXPECT_GT(EstimateScene(*gallery, 2'000, small_objects).cpu,
            EstimateScene(*gallery, 2'000, defaults).cpu);
}

}  // namespace
}  // namespace shapeid
