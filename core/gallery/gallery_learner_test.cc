#include "core/gallery/gallery_learner.h"

#include <memory>
#include <string>
#include <vector>

#include "absl/time/clock.h"
#include "core/gallery/gallery.h"
#include "core/gallery/gallery_registry.h"
#include "core/gallery/gallery_snapshot.h"
#include "core/gallery/gallery_store.h"
#include "core/testing/gallery_shapes.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using gallery_testing::Box;
using gallery_testing::Line;
using gallery_testing::Sphere;

GalleryLearnerOptions Quick() {
  GalleryLearnerOptions options;
  options.head.mlp.hidden = {16};
  options.head.mlp.epochs = 10;
  options.head.min_samples = 6;
  options.settle = absl::ZeroDuration();
  options.poll = absl::Milliseconds(5);
  options.low_priority = false;
  return options;
}

std::vector<LabeledCloud> Shapes(int per_label, uint32_t first_seed = 1) {
  std::vector<LabeledCloud> samples;
  for (uint32_t seed = first_seed; seed < first_seed + static_cast<uint32_t>(per_label); ++seed) {
    samples.push_back({0, "box", Box(seed)});
    samples.push_back({0, "sphere", Sphere(seed)});
    samples.push_back({0, "line", Line(seed)});
  }
  return samples;
}

// Waits up to 60 s for `done` (a fit takes milliseconds here; TSan slows it a hundredfold).
template <typename Done>
bool WaitFor(const Done& done) {
  const absl::Time deadline = absl::Now() + absl::Seconds(60);
  while (!done()) {
    if (absl::Now() > deadline) return false;
    absl::SleepFor(absl::Milliseconds(5));
  }
  return true;
}

TEST(GalleryLearnerTest, FitsAGalleryOnceItSettlesAndAgainAfterItChanges) {
  GalleryRegistry registry;
  GalleryLearner learner(Quick(), &registry);
  std::shared_ptr<Gallery> gallery = *registry.Create("shapes", GalleryOptions{});
  ASSERT_TRUE(gallery->Train(Shapes(4)).ok());
  ASSERT_TRUE(WaitFor([&] { return gallery->Snapshot()->head() != nullptr; }));
  std::shared_ptr<const GallerySnapshot> snapshot = gallery->Snapshot();
  EXPECT_EQ(snapshot->head()->fitted_version, snapshot->version());
  EXPECT_TRUE(snapshot->head_answers());
  EXPECT_TRUE(snapshot->Classify(Sphere(50))->by_head);
  EXPECT_GE(learner.fits(), 1);
  // More samples: the old head answers until the new one, fitted on the new version, lands.
  ASSERT_TRUE(gallery->Train(Shapes(2, 10)).ok());
  const uint64_t version = gallery->Snapshot()->version();
  ASSERT_TRUE(WaitFor([&] { return gallery->Snapshot()->head()->fitted_version == version; }));
  EXPECT_EQ(
      gallery->Snapshot()->head()->fitted_samples + gallery->Snapshot()->head()->holdout_samples,
      18);
}

TEST(GalleryLearnerTest, LeavesSmallAndSingleLabelGalleriesToKnn) {
  GalleryRegistry registry;
  GalleryLearner learner(Quick(), &registry);
  std::shared_ptr<Gallery> small = *registry.Create("small", GalleryOptions{});
  ASSERT_TRUE(small->Train(Shapes(1)).ok());  // 3 samples < 6
  std::shared_ptr<Gallery> boxes = *registry.Create("boxes", GalleryOptions{});
  std::vector<LabeledCloud> only_boxes;
  for (uint32_t seed = 1; seed <= 8; ++seed) only_boxes.push_back({0, "box", Box(seed)});
  ASSERT_TRUE(boxes->Train(only_boxes).ok());
  std::shared_ptr<Gallery> shapes = *registry.Create("shapes", GalleryOptions{});
  ASSERT_TRUE(shapes->Train(Shapes(3)).ok());
  // The learner looks at galleries in name order: once "shapes" has its head, it has looked
  // at the two others too.
  ASSERT_TRUE(WaitFor([&] { return shapes->Snapshot()->head() != nullptr; }));
  learner.Nudge();
  absl::SleepFor(absl::Milliseconds(50));
  EXPECT_EQ(small->Snapshot()->head(), nullptr);
  EXPECT_EQ(boxes->Snapshot()->head(), nullptr);
  EXPECT_EQ(learner.failures(), 0);
}

TEST(GalleryLearnerTest, AFitItCannotHoldMemoryForIsNotRunAndIsTriedLater) {
  GalleryLearnerOptions options = Quick();
  std::atomic<int> asked{0};
  options.reserve = [&](int64_t bytes) -> absl::StatusOr<std::shared_ptr<void>> {
    EXPECT_GT(bytes, 0);
    ++asked;
    return absl::ResourceExhaustedError("no memory");
  };
  GalleryRegistry registry;
  GalleryLearner learner(options, &registry);
  std::shared_ptr<Gallery> gallery = *registry.Create("shapes", GalleryOptions{});
  ASSERT_TRUE(gallery->Train(Shapes(3)).ok());
  ASSERT_TRUE(WaitFor([&] { return learner.failures() >= 1; }));
  absl::SleepFor(absl::Milliseconds(50));
  EXPECT_EQ(asked, 1);  // not again at once: after the retry delay
  EXPECT_EQ(gallery->Snapshot()->head(), nullptr);
}

TEST(GalleryLearnerTest, StopsAFitInProgressAtOnce) {
  GalleryLearnerOptions options = Quick();
  options.head.mlp.epochs = 10000;  // minutes of work
  GalleryRegistry registry;
  auto learner = std::make_unique<GalleryLearner>(options, &registry);
  std::shared_ptr<Gallery> gallery = *registry.Create("shapes", GalleryOptions{});
  ASSERT_TRUE(gallery->Train(Shapes(4)).ok());
  ASSERT_TRUE(WaitFor([&] { return learner->fitting() == "shapes"; }));
  const absl::Time start = absl::Now();
  learner.reset();
  EXPECT_LT(absl::Now() - start, absl::Seconds(5));
  EXPECT_EQ(gallery->Snapshot()->head(), nullptr);
}

TEST(GalleryLearnerTest, ADeletedGallerysFitIsAbandoned) {
  GalleryLearnerOptions options = Quick();
  options.head.mlp.epochs = 10000;
  GalleryRegistry registry;
  GalleryLearner learner(options, &registry);
  std::shared_ptr<Gallery> gallery = *registry.Create("shapes", GalleryOptions{});
  ASSERT_TRUE(gallery->Train(Shapes(4)).ok());
  ASSERT_TRUE(WaitFor([&] { return learner.fitting() == "shapes"; }));
  ASSERT_TRUE(registry.Delete("shapes").ok());
  EXPECT_TRUE(WaitFor([&] { return learner.fitting().empty(); }));
  EXPECT_EQ(learner.fits(), 0);
}

TEST(GalleryLearnerTest, AStoreGivesTheHeadBackAtTheNextStartForTheSameSamplesOnly) {
  auto store = std::make_shared<InMemoryGalleryStore>();
  std::shared_ptr<const GalleryHead> fitted;
  {
    GalleryRegistry registry({}, store);
    GalleryLearner learner(Quick(), &registry);
    std::shared_ptr<Gallery> gallery = *registry.Create("shapes", GalleryOptions{});
    ASSERT_TRUE(gallery->Train(Shapes(4)).ok());
    ASSERT_TRUE(WaitFor([&] { return gallery->Snapshot()->head() != nullptr; }));
    fitted = gallery->Snapshot()->head();
  }
  {
    GalleryRegistry restarted({}, store);  // no learner: whatever head it has was kept
    ASSERT_TRUE(restarted.LoadFromStore().ok());
    std::shared_ptr<Gallery> gallery = *restarted.Get("shapes");
    const std::shared_ptr<const GallerySnapshot> snapshot = gallery->Snapshot();
    ASSERT_NE(snapshot->head(), nullptr);
    EXPECT_EQ(snapshot->head()->classifier.Serialize(), fitted->classifier.Serialize());
    EXPECT_EQ(snapshot->head()->fitted_version, snapshot->version());
    EXPECT_TRUE(snapshot->head_answers());
    // A change without a refit: the kept head no longer matches the samples.
    ASSERT_TRUE(gallery->Train({{0, "box", Box(99)}}).ok());
  }
  GalleryRegistry again({}, store);
  ASSERT_TRUE(again.LoadFromStore().ok());
  EXPECT_EQ((*again.Get("shapes"))->Snapshot()->head(), nullptr);
  // Deleting the gallery drops its head with it.
  ASSERT_TRUE(again.Delete("shapes").ok());
  EXPECT_EQ(store->SaveHead("shapes", "x").code(), absl::StatusCode::kInternal);  // no gallery
}

}  // namespace
}  // namespace shapeid
