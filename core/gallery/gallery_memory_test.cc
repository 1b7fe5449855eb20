// What a gallery's samples cost in memory (GallerySnapshot::memory_bytes, provenance_bytes),
// and that a gallery rebuilt from a store holds what the trained one held. Linked with the
// heap meter (core/descriptors/heap_meter.h), which replaces this program's malloc.

#include <cstdint>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "core/descriptors/heap_meter.h"
#include "core/gallery/gallery.h"
#include "core/gallery/gallery_registry.h"
#include "core/gallery/gallery_store.h"
#include "core/gallery/gallery_store_testing.h"
#include "core/testing/gallery_shapes.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using gallery_testing::Box;
using gallery_testing::Line;
using gallery_testing::ProvenanceAtLimits;
using gallery_testing::Sphere;

// Nine clouds of three shapes, ids 1-9, each with provenance at the limits.
std::vector<LabeledCloud> ShapesWithProvenance() {
  std::vector<LabeledCloud> samples;
  for (uint32_t seed = 1; seed <= 3; ++seed) {
    samples.push_back({seed, "box", Box(seed), ProvenanceAtLimits(seed)});
    samples.push_back({seed + 3, "sphere", Sphere(seed), ProvenanceAtLimits(seed + 3)});
    samples.push_back({seed + 6, "line", Line(seed), ProvenanceAtLimits(seed + 6)});
  }
  return samples;
}

std::shared_ptr<Gallery> Augmented(std::shared_ptr<GalleryStore> store) {
  GalleryOptions options;
  options.augment.views = 3;
  absl::StatusOr<std::shared_ptr<Gallery>> g =
      Gallery::Create("shapes", options, {}, std::move(store));
  EXPECT_TRUE(g.ok()) << g.status();
  return *g;
}

TEST(GalleryMemoryTest, ProvenanceBytesFollowTrainingAndRemoval) {
  auto g = Augmented(nullptr);
  EXPECT_EQ(g->Snapshot()->provenance_bytes(), 0);
  const int64_t empty = g->Snapshot()->memory_bytes();
  std::vector<LabeledCloud> samples = ShapesWithProvenance();
  samples.push_back({10, "box", Box(10)});  // one without provenance
  ASSERT_TRUE(g->Train(samples).ok());
  const auto trained = g->Snapshot();
  // 4,096 bytes of source and 4,096 of keys and values, once per sample however many views.
  EXPECT_EQ(trained->index().num_rows(), 4 * 10);
  EXPECT_EQ(trained->provenance_bytes(), 9 * 8192);
  EXPECT_GT(trained->memory_bytes() - empty, 9 * int64_t{8192});

  ASSERT_TRUE(g->RemoveSamples({1, 10}).ok());
  EXPECT_EQ(g->Snapshot()->provenance_bytes(), 8 * 8192);
  EXPECT_LT(g->Snapshot()->memory_bytes(), trained->memory_bytes());
  EXPECT_EQ(trained->provenance_bytes(), 9 * 8192);  // the old snapshot is unchanged

  ASSERT_TRUE(g->RemoveSamples({}, {"box", "sphere", "line"}).ok());
  EXPECT_EQ(g->Snapshot()->provenance_bytes(), 0);
  EXPECT_EQ(g->Snapshot()->num_samples(), 0);
}

// What a server holds after a restart is what it held before it: the same provenance, shared
// once per sample (not per view), and the same estimate, whether the gallery comes back
// through Restore or, as at start-up, through the registry and GalleryStore::Load.
TEST(GalleryMemoryTest, ARestoredGalleryHoldsWhatTheTrainedOneHeld) {
  auto store = std::make_shared<InMemoryGalleryStore>();
  auto g = Augmented(store);
  ASSERT_TRUE(store->SaveGallery(g->Snapshot()->ToStored()).ok());
  ASSERT_TRUE(g->Train(ShapesWithProvenance()).ok());
  const auto trained = g->Snapshot();

  const absl::StatusOr<std::vector<StoredGallery>> stored = store->LoadAll();
  ASSERT_TRUE(stored.ok());
  ASSERT_EQ(stored->size(), 1u);
  auto restored = Gallery::Restore(stored->front(), {}, nullptr);
  ASSERT_TRUE(restored.ok()) << restored.status();
  GalleryRegistry registry({}, store);
  ASSERT_TRUE(registry.LoadFromStore().ok());
  auto loaded = registry.Get("shapes");
  ASSERT_TRUE(loaded.ok());

  for (const auto& snapshot : {(*restored)->Snapshot(), (*loaded)->Snapshot()}) {
    EXPECT_EQ(snapshot->index().num_rows(), trained->index().num_rows());
    EXPECT_EQ(snapshot->provenance_bytes(), trained->provenance_bytes());
    EXPECT_EQ(snapshot->memory_bytes(), trained->memory_bytes());
    ASSERT_NE(snapshot->Provenance(5), nullptr);
    EXPECT_EQ(*snapshot->Provenance(5), ProvenanceAtLimits(5));
  }
}

TEST(GalleryMemoryTest, TheRestorerTakesProvenanceWithoutCopyingIt) {
  StoredGallery stored;
  stored.name = "moved";
  stored.options.descriptor_spec = "dfsd";
  stored.dimension = 4;
  absl::StatusOr<Gallery::Restorer> restorer = Gallery::Restorer::Begin(stored);
  ASSERT_TRUE(restorer.ok()) << restorer.status();
  StoredSample sample{7, "box", {1, 2, 3, 4, 5, 6, 7, 8}, ProvenanceAtLimits(7)};
  const char* source = sample.provenance.source.data();
  const char* value = sample.provenance.metadata.back().second.data();
  ASSERT_TRUE(restorer->Add(std::move(sample)).ok());
  // A const sample is copied: its provenance stays with the caller.
  const StoredSample kept{8, "box", {1, 2, 3, 4}, ProvenanceAtLimits(8)};
  ASSERT_TRUE(restorer->Add(kept).ok());
  absl::StatusOr<std::shared_ptr<Gallery>> g = std::move(*restorer).Finish({}, nullptr);
  ASSERT_TRUE(g.ok()) << g.status();
  const auto snapshot = (*g)->Snapshot();
  ASSERT_NE(snapshot->Provenance(7), nullptr);
  EXPECT_EQ(snapshot->Provenance(7)->source.data(), source);
  EXPECT_EQ(snapshot->Provenance(7)->metadata.back().second.data(), value);
  EXPECT_EQ(*snapshot->Provenance(8), kept.provenance);
  EXPECT_NE(snapshot->Provenance(8)->source.data(), kept.provenance.source.data());
  EXPECT_EQ(snapshot->index().ViewsAt(0), 2);
}

// The estimate against the heap a Restore really takes (glibc's usable sizes, counted by the
// heap meter, which counts usable sizes, 8 bytes under each chunk the estimate counts): within
// 10 % for descriptors and for provenance at the limits. Under 2,176 rows,
// one feature block: a full block is aligned to a huge page, and the meter then counts the
// alignment's slack, which is address space, never touched (its size varies from run to run).
TEST(GalleryMemoryTest, MemoryBytesIsWithinTenPercentOfTheHeap) {
  if (!heap_meter::Available()) GTEST_SKIP() << "the heap meter is off (sanitizer build)";
  for (const bool provenance : {false, true}) {
    SCOPED_TRACE(provenance ? "with provenance" : "without provenance");
    StoredGallery stored;
    stored.name = "heap";
    stored.options.descriptor_spec = "dfsd";
    stored.dimension = 240;  // dfsd's
    std::mt19937 rng(1);
    std::uniform_real_distribution<float> u(0.f, 1.f);
    for (uint64_t i = 1; i <= 1000; ++i) {
      StoredSample s;
      s.id = i;
      s.label = absl::StrCat("class-", i % 40);
      s.features.resize(240 * (1 + i % 3));  // 1 to 3 views
      for (float& f : s.features) f = u(rng);
      if (provenance) s.provenance = ProvenanceAtLimits(i);
      stored.samples.push_back(std::move(s));
    }
    heap_meter::Start();
    absl::StatusOr<std::shared_ptr<Gallery>> g = Gallery::Restore(stored, {}, nullptr);
    const int64_t held = heap_meter::Live();
    heap_meter::Stop();
    ASSERT_TRUE(g.ok()) << g.status();
    ASSERT_LT((*g)->Snapshot()->index().num_rows(), 2176);
    const int64_t estimate = (*g)->Snapshot()->memory_bytes();
    EXPECT_GT(estimate, held * 9 / 10) << "held " << held;
    EXPECT_LT(estimate, held * 11 / 10) << "held " << held;
  }
}

}  // namespace
}  // namespace shapeid
