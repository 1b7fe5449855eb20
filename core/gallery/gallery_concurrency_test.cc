// Many threads training, removing and classifying one gallery at once; run under TSan too.

#include <atomic>
#include <cstdint>
#include <memory>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "absl/strings/str_cat.h"
#include "core/gallery/gallery.h"
#include "core/gallery/gallery_registry.h"
#include "core/gallery/gallery_store.h"
#include "core/testing/gallery_shapes.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using gallery_testing::Box;
using gallery_testing::Line;
using gallery_testing::Sphere;

constexpr int kThreads = 8;
constexpr int kOps = 50;

PointCloud Shape(int which, uint32_t seed) {
  switch (which % 3) {
    case 0:
      return Box(seed);
    case 1:
      return Sphere(seed);
    default:
      return Line(seed);
  }
}
const char* ShapeLabel(int which) {
  static const char* const kLabels[] = {"box", "sphere", "line"};
  return kLabels[which % 3];
}

TEST(GalleryConcurrencyTest, ConcurrentTrainsLoseNoSample) {
  auto store = std::make_shared<InMemoryGalleryStore>();
  GalleryRegistry registry({}, store);
  auto created = registry.Create("shared", {});
  ASSERT_TRUE(created.ok());
  std::shared_ptr<Gallery> gallery = *created;
  ASSERT_TRUE(
      gallery->Train({{0, "box", Box(1)}, {0, "sphere", Sphere(1)}, {0, "line", Line(1)}}).ok());

  // Per thread: the ids it owns at the end, and failures seen.
  std::vector<std::set<uint64_t>> owned(kThreads);
  std::atomic<int> failures{0};
  std::atomic<int> misclassified{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t) {
    threads.emplace_back([&, t] {
      uint64_t last_version = 0;
      for (int i = 0; i < kOps; ++i) {
        const uint32_t seed = static_cast<uint32_t>(1000 * t + i);
        if (i % 3 == 0) {
          // A batch of two: one client id (unique to the thread), one assigned.
          const uint64_t client_id = 1'000'000ull * static_cast<uint64_t>(t + 1) + i;
          auto r = gallery->Train({{client_id, ShapeLabel(i), Shape(i, seed)},
                                   {0, ShapeLabel(i + 1), Shape(i + 1, seed)}});
          if (!r.ok() || r->ids.size() != 2) {
            ++failures;
            continue;
          }
          owned[t].insert(r->ids.begin(), r->ids.end());
        } else if (i % 7 == 0 && !owned[t].empty()) {
          const uint64_t id = *owned[t].begin();
          auto removed = gallery->RemoveSamples({id});
          if (!removed.ok() || *removed != 1) {
            ++failures;
            continue;
          }
          owned[t].erase(id);
        } else {
          auto snap = gallery->Snapshot();
          if (snap->version() < last_version) ++failures;  // versions never go back
          last_version = snap->version();
          auto answer = snap->Classify(Shape(i, seed + 7));
          if (!answer.ok()) {
            ++failures;
          } else if (answer->label != ShapeLabel(i)) {
            ++misclassified;
          }
        }
      }
    });
  }
  for (std::thread& th : threads) th.join();

  EXPECT_EQ(failures.load(), 0);
  EXPECT_LE(misclassified.load(), kThreads);  // distinct shapes: nearly always right
  std::set<uint64_t> all;
  size_t expected = 3;
  for (const auto& ids : owned) {
    expected += ids.size();
    all.insert(ids.begin(), ids.end());
  }
  EXPECT_EQ(all.size(), expected - 3);  // no id handed out twice
  auto snap = gallery->Snapshot();
  EXPECT_EQ(snap->num_samples(), static_cast<int64_t>(expected));
  for (uint64_t id : all) EXPECT_TRUE(snap->Contains(id)) << id;
  EXPECT_EQ(store->NumSamples("shared"), static_cast<int64_t>(expected));
  int64_t by_label = 0;
  for (const auto& [label, count] : snap->LabelCounts()) by_label += count;
  EXPECT_EQ(by_label, snap->num_samples());
}

TEST(GalleryConcurrencyTest, RegistryUnderConcurrentCreateGetDelete) {
  GalleryRegistry registry;
  std::atomic<int> failures{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t) {
    threads.emplace_back([&, t] {
      for (int i = 0; i < kOps; ++i) {
        const std::string mine = absl::StrCat("t", t, "-", i % 5);
        auto g = registry.Get(mine);
        if (g.ok()) {
          if (!registry.Delete(mine).ok()) ++failures;
        } else if (!registry.Create(mine, {}).ok()) {
          ++failures;
        }
        // Everybody races on one shared name; exactly one of each pair of calls wins.
        auto shared = registry.Create("common", {});
        if (!shared.ok() && shared.status().code() != absl::StatusCode::kAlreadyExists) {
          ++failures;
        }
        (void)registry.List();
      }
    });
  }
  for (std::thread& th : threads) th.join();
  EXPECT_EQ(failures.load(), 0);
  // kOps = 50 toggles of each of 5 names per thread: every name was created 5 times and
  // deleted 5 times, so only "common" remains.
  EXPECT_EQ(registry.List(), std::vector<std::string>{"common"});
}

}  // namespace
}  // namespace shapeid
