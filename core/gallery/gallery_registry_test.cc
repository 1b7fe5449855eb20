#include "core/gallery/gallery_registry.h"

#include <condition_variable>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "core/gallery/gallery_store.h"
#include "core/status_macros.h"
#include "core/testing/gallery_shapes.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using gallery_testing::Box;
using gallery_testing::Sphere;
using ::testing::AllOf;
using ::testing::ElementsAre;
using ::testing::HasSubstr;
using ::testing::IsEmpty;
using ::testing::Not;

TEST(GalleryRegistryTest, CreateGetListDelete) {
  GalleryRegistry registry;
  EXPECT_THAT(registry.List(), IsEmpty());
  GalleryOptions options;
  options.knn.k = 3;
  auto b = registry.Create("ycb", options);
  ASSERT_TRUE(b.ok()) << b.status();
  auto a = registry.Create("Modelnet10", {});
  ASSERT_TRUE(a.ok()) << a.status();
  EXPECT_THAT(registry.List(), ElementsAre("Modelnet10", "ycb"));  // sorted, byte order
  EXPECT_EQ(registry.size(), 2u);
  // All: the galleries themselves, in the same order.
  EXPECT_THAT(registry.All(), ElementsAre(*a, *b));

  auto got = registry.Get("ycb");
  ASSERT_TRUE(got.ok());
  EXPECT_EQ(*got, *b);
  EXPECT_EQ((*got)->Snapshot()->options().knn.k, 3);

  ASSERT_TRUE(registry.Delete("ycb").ok());
  EXPECT_THAT(registry.List(), ElementsAre("Modelnet10"));
  EXPECT_THAT(registry.All(), ElementsAre(*a));
  EXPECT_EQ(registry.Get("ycb").status().code(), absl::StatusCode::kNotFound);
  // The name is free again, for a new empty gallery.
  auto again = registry.Create("ycb", {});
  ASSERT_TRUE(again.ok());
  EXPECT_NE(*again, *b);
}

TEST(GalleryRegistryTest, Errors) {
  GalleryRegistry registry;
  ASSERT_TRUE(registry.Create("a", {}).ok());

  const absl::Status exists = registry.Create("a", {}).status();
  EXPECT_EQ(exists.code(), absl::StatusCode::kAlreadyExists);
  EXPECT_THAT(exists.message(), HasSubstr("'a'"));

  const absl::Status bad_name = registry.Create("no/slash", {}).status();
  EXPECT_EQ(bad_name.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(bad_name.message(), HasSubstr("[A-Za-z0-9][A-Za-z0-9_.-]{0,127}"));

  GalleryOptions bad_spec;
  bad_spec.descriptor_spec = "rphsd:nosuch=1";
  const absl::Status spec = registry.Create("b", bad_spec).status();
  EXPECT_EQ(spec.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(spec.message(), HasSubstr("nosuch"));

  GalleryOptions bad_reject;
  bad_reject.reject_distance = -1;
  EXPECT_EQ(registry.Create("b", bad_reject).status().code(), absl::StatusCode::kInvalidArgument);

  const absl::Status missing = registry.Get("zzz").status();
  EXPECT_EQ(missing.code(), absl::StatusCode::kNotFound);
  EXPECT_THAT(missing.message(), AllOf(HasSubstr("'zzz'"), Not(HasSubstr("'a'"))));
  EXPECT_EQ(registry.Delete("zzz").code(), absl::StatusCode::kNotFound);
  // A name no gallery can have says what is wrong with it, not that it is missing.
  for (const char* bad : {"../x", "", "a/b", ".hidden"}) {
    EXPECT_EQ(registry.Get(bad).status().code(), absl::StatusCode::kInvalidArgument) << bad;
    EXPECT_EQ(registry.Delete(bad).code(), absl::StatusCode::kInvalidArgument) << bad;
  }
  EXPECT_EQ(registry.Get(std::string(129, 'a')).status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(registry.List(), ElementsAre("a"));
}

TEST(GalleryRegistryTest, MaxGalleries) {
  GalleryLimits limits;
  limits.max_galleries = 2;
  GalleryRegistry registry(limits);
  ASSERT_TRUE(registry.Create("a", {}).ok());
  ASSERT_TRUE(registry.Create("b", {}).ok());
  const absl::Status full = registry.Create("c", {}).status();
  EXPECT_EQ(full.code(), absl::StatusCode::kResourceExhausted);
  EXPECT_THAT(full.message(), AllOf(HasSubstr("2 galleries exist"), HasSubstr("is 2")));
  ASSERT_TRUE(registry.Delete("a").ok());
  EXPECT_TRUE(registry.Create("c", {}).ok());
}

TEST(GalleryRegistryTest, StoreSeesChangesBeforeTheyArePublished) {
  auto store = std::make_shared<InMemoryGalleryStore>();
  GalleryRegistry registry({}, store);

  store->SetFailure(absl::UnavailableError("store down"));
  EXPECT_EQ(registry.Create("a", {}).status(), absl::UnavailableError("store down"));
  EXPECT_THAT(registry.List(), IsEmpty());

  store->SetFailure(absl::OkStatus());
  auto a = registry.Create("a", {});
  ASSERT_TRUE(a.ok());
  EXPECT_EQ(store->NumSamples("a"), 0);
  ASSERT_TRUE((*a)->Train({{0, "box", Box(1)}, {0, "sphere", Sphere(1)}}).ok());
  EXPECT_EQ(store->NumSamples("a"), 2);

  store->SetFailure(absl::UnavailableError("store down"));
  EXPECT_EQ(registry.Delete("a"), absl::UnavailableError("store down"));
  EXPECT_THAT(registry.List(), ElementsAre("a"));
  store->SetFailure(absl::OkStatus());
  EXPECT_TRUE((*a)->Train({{0, "box", Box(2)}}).ok());  // still writable
  ASSERT_TRUE(registry.Delete("a").ok());
  EXPECT_EQ(store->NumSamples("a"), -1);
}

TEST(GalleryRegistryTest, DeletedGalleryNeverWritesToItsSuccessor) {
  auto store = std::make_shared<InMemoryGalleryStore>();
  GalleryRegistry registry({}, store);
  auto old = registry.Create("g", {});
  ASSERT_TRUE(old.ok());
  TrainBatch in_flight = (*old)->NewBatch();  // a stream that outlives the delete
  ASSERT_TRUE(in_flight.AddSample(0, "box", Box(1)).ok());
  ASSERT_TRUE(registry.Delete("g").ok());
  auto fresh = registry.Create("g", {});
  ASSERT_TRUE(fresh.ok());

  const auto late = in_flight.Commit();
  EXPECT_EQ(late.status().code(), absl::StatusCode::kNotFound);
  EXPECT_THAT(late.status().message(), HasSubstr("was deleted"));
  EXPECT_EQ((*old)->RemoveSamples({}, {"box"}).status().code(), absl::StatusCode::kNotFound);
  EXPECT_EQ((*fresh)->Snapshot()->num_samples(), 0);
  EXPECT_EQ(store->NumSamples("g"), 0);
  // Readers holding the old gallery still read it.
  EXPECT_EQ((*old)->Snapshot()->name(), "g");
}

TEST(GalleryRegistryTest, LoadFromStoreRestoresEveryGallery) {
  auto store = std::make_shared<InMemoryGalleryStore>();
  {
    GalleryRegistry first({}, store);
    GalleryOptions options;
    options.descriptor_spec = "rphsd:bins=30";
    auto a = first.Create("a", options);
    ASSERT_TRUE(a.ok());
    ASSERT_TRUE((*a)->Train({{5, "box", Box(1)}, {0, "sphere", Sphere(1)}}).ok());
    ASSERT_TRUE(first.Create("b", {}).ok());
  }
  GalleryRegistry second({}, store);
  ASSERT_TRUE(second.LoadFromStore().ok());
  EXPECT_THAT(second.List(), ElementsAre("a", "b"));
  auto a = second.Get("a");
  ASSERT_TRUE(a.ok());
  auto snap = (*a)->Snapshot();
  EXPECT_EQ(snap->num_samples(), 2);
  EXPECT_THAT(snap->options().descriptor_spec, HasSubstr("bins=30"));
  EXPECT_EQ(snap->Classify(Sphere(7))->label, "sphere");
  // Writes go on reaching the store.
  auto more = (*a)->Train({{0, "box", Box(3)}});
  ASSERT_TRUE(more.ok());
  EXPECT_THAT(more->ids, ElementsAre(kFirstAssignedId + 1));
  EXPECT_EQ(store->NumSamples("a"), 3);

  // Loading twice clashes and adds nothing.
  EXPECT_EQ(second.LoadFromStore().code(), absl::StatusCode::kAlreadyExists);
  EXPECT_EQ(second.size(), 2u);
}

// A loaded gallery that needs an approximate index serves exactly at once and gets its index
// from the background build.
TEST(GalleryRegistryTest, LoadFromStoreBuildsApproximateIndexesInTheBackground) {
  auto store = std::make_shared<InMemoryGalleryStore>();
  GalleryLimits limits;
  limits.approximate.min_vectors = 64;
  {
    GalleryRegistry first({}, store);
    auto big = first.Create("big", {});
    ASSERT_TRUE(big.ok());
    std::vector<LabeledCloud> samples;
    for (uint32_t i = 0; i < 70; ++i) {
      samples.push_back({0, i % 2 == 0 ? "box" : "sphere", i % 2 == 0 ? Box(i) : Sphere(i)});
    }
    ASSERT_TRUE((*big)->Train(samples).ok());
    ASSERT_TRUE(first.Create("small", {}).ok());
  }
  GalleryRegistry second(limits, store);
  ASSERT_TRUE(second.LoadFromStore().ok());
  // Serving already: exact or approximate, the answer is there.
  auto snapshot = second.Get("big").value()->Snapshot();
  EXPECT_EQ(snapshot->version(), 1u);  // as stored: one training batch
  auto answer = snapshot->Classify(Sphere(3));
  ASSERT_TRUE(answer.ok()) << answer.status();
  EXPECT_EQ(answer->label, "sphere");

  second.WaitForApproximateIndexes();
  snapshot = second.Get("big").value()->Snapshot();
  EXPECT_TRUE(snapshot->index().approximate());
  EXPECT_EQ(snapshot->version(), 1u);  // the same samples: not a change of the gallery
  EXPECT_EQ(snapshot->num_samples(), 70);
  EXPECT_TRUE(snapshot->Classify(Sphere(3))->knn.approximate);
  EXPECT_FALSE(second.Get("small").value()->Snapshot()->index().approximate());
}

TEST(GalleryRegistryTest, DestroyingTheRegistryStopsTheBackgroundBuild) {
  auto store = std::make_shared<InMemoryGalleryStore>();
  GalleryLimits limits;
  limits.approximate.min_vectors = 64;
  {
    GalleryRegistry first({}, store);
    for (const char* name : {"a", "b", "c"}) {
      auto g = first.Create(name, {});
      ASSERT_TRUE(g.ok());
      std::vector<LabeledCloud> samples;
      for (uint32_t i = 0; i < 70; ++i) samples.push_back({0, "box", Box(i)});
      ASSERT_TRUE((*g)->Train(samples).ok());
    }
  }
  // Destroyed at once, while the build may be running: it must stop and be joined.
  GalleryRegistry second(limits, store);
  ASSERT_TRUE(second.LoadFromStore().ok());
}

TEST(GalleryRegistryTest, ImportAddsAWholeGalleryInOneStoreWrite) {
  auto store = std::make_shared<InMemoryGalleryStore>();
  GalleryRegistry source;
  auto a = source.Create("a", {});
  ASSERT_TRUE(a.ok());
  ASSERT_TRUE((*a)->Train({{5, "box", Box(1)}, {0, "sphere", Sphere(1)}}).ok());
  StoredGallery exported = (*a)->Snapshot()->ToStored();

  GalleryRegistry target({}, store);
  exported.name = "copy";
  auto imported = target.Import(exported);
  ASSERT_TRUE(imported.ok()) << imported.status();
  EXPECT_EQ(store->NumSamples("copy"), 2);
  EXPECT_EQ((*imported)->Snapshot()->created(), (*a)->Snapshot()->created());
  EXPECT_EQ((*imported)->Snapshot()->Classify(Sphere(4))->label, "sphere");

  EXPECT_EQ(target.Import(exported).status().code(), absl::StatusCode::kAlreadyExists);

  StoredGallery other = exported;
  other.name = "other";
  other.descriptor_version += 7;
  const auto refused = target.Import(other);
  EXPECT_EQ(refused.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(refused.status().message(), HasSubstr("cannot import"));

  other.descriptor_version = exported.descriptor_version;
  other.samples[1].id = other.samples[0].id;
  EXPECT_EQ(target.Import(other).status().code(), absl::StatusCode::kAlreadyExists);

  GalleryLimits small;
  small.max_samples_per_gallery = 1;
  GalleryRegistry tiny(small, store);
  EXPECT_EQ(tiny.Import(exported).status().code(), absl::StatusCode::kResourceExhausted);

  store->SetFailure(absl::ResourceExhaustedError("disk full"));
  other = exported;
  other.name = "third";
  EXPECT_EQ(target.Import(other).status(), absl::ResourceExhaustedError("disk full"));
  EXPECT_THAT(target.List(), ElementsAre("copy"));
}

// A store whose SaveGallery waits until released: a large import being written.
class SlowSaveStore final : public GalleryStore {
 public:
  absl::Status SaveGallery(const StoredGallery& gallery) override {
    {
      std::unique_lock<std::mutex> lock(mu_);
      saving_ = true;
      cv_.notify_all();
      cv_.wait(lock, [&] { return released_; });
    }
    return inner_.SaveGallery(gallery);
  }
  absl::Status DeleteGallery(absl::string_view name) override { return inner_.DeleteGallery(name); }
  absl::Status AppendSamples(absl::string_view name, absl::Span<const StoredSample> batch,
                             absl::Time updated, uint64_t version) override {
    return inner_.AppendSamples(name, batch, updated, version);
  }
  absl::Status RemoveSamples(absl::string_view name, absl::Span<const uint64_t> ids,
                             absl::Time updated, uint64_t version) override {
    return inner_.RemoveSamples(name, ids, updated, version);
  }
  absl::StatusOr<std::vector<StoredGallery>> LoadAll() override { return inner_.LoadAll(); }

  void WaitUntilSaving() {
    std::unique_lock<std::mutex> lock(mu_);
    cv_.wait(lock, [&] { return saving_; });
  }
  void Release() {
    std::lock_guard<std::mutex> lock(mu_);
    released_ = true;
    cv_.notify_all();
  }

 private:
  InMemoryGalleryStore inner_;
  std::mutex mu_;
  std::condition_variable cv_;
  bool saving_ = false;
  bool released_ = false;
};

TEST(GalleryRegistryTest, ASlowStoreWriteBlocksNeitherLookupsNorOtherNames) {
  auto slow_store = std::make_shared<SlowSaveStore>();
  GalleryRegistry slow({}, slow_store);
  std::thread creator([&] { EXPECT_TRUE(slow.Create("big", {}).ok()); });
  slow_store->WaitUntilSaving();
  // While "big" is being written: lookups answer (they would hang if the registry's lock were
  // held across the write), the name is taken, and it is not listed yet.
  EXPECT_EQ(slow.Get("big").status().code(), absl::StatusCode::kNotFound);
  EXPECT_THAT(slow.List(), IsEmpty());
  EXPECT_EQ(slow.Create("big", {}).status().code(), absl::StatusCode::kAlreadyExists);
  EXPECT_EQ(slow.Delete("big").code(), absl::StatusCode::kNotFound);
  slow_store->Release();
  creator.join();
  EXPECT_THAT(slow.List(), ElementsAre("big"));
}

// Two servers over one shared store, as PostgreSQL makes them (server/storage): the store
// keeps a log of changes, answers Aborted when a write is built on a stale copy, and CatchUp
// (each registry's catch-up function) applies the log through the replication entry points.
class SharedLog {
 public:
  struct Change {
    std::string gallery;
    std::vector<StoredSample> added;
    std::vector<uint64_t> removed;
    absl::Time updated;
    uint64_t version = 0;
  };
  std::mutex mu;
  std::map<std::string, uint64_t> versions;
  std::vector<Change> log;
};

class ReplicaStore final : public GalleryStore {
 public:
  explicit ReplicaStore(SharedLog* shared) : shared_(shared) {}
  void Attach(GalleryRegistry* registry) { registry_ = registry; }

  absl::Status SaveGallery(const StoredGallery& gallery) override {
    std::lock_guard<std::mutex> lock(shared_->mu);
    shared_->versions[gallery.name] = gallery.version;
    return absl::OkStatus();
  }
  absl::Status DeleteGallery(absl::string_view) override { return absl::OkStatus(); }
  absl::Status AppendSamples(absl::string_view name, absl::Span<const StoredSample> batch,
                             absl::Time updated, uint64_t version) override {
    return Write({std::string(name), {batch.begin(), batch.end()}, {}, updated, version});
  }
  absl::Status RemoveSamples(absl::string_view name, absl::Span<const uint64_t> ids,
                             absl::Time updated, uint64_t version) override {
    return Write({std::string(name), {}, {ids.begin(), ids.end()}, updated, version});
  }
  absl::StatusOr<std::vector<StoredGallery>> LoadAll() override {
    return std::vector<StoredGallery>{};
  }
  absl::Status CatchUp(absl::string_view) {
    ++catch_ups;
    std::vector<SharedLog::Change> pending;
    {
      std::lock_guard<std::mutex> lock(shared_->mu);
      pending.assign(shared_->log.begin() + static_cast<ptrdiff_t>(applied_), shared_->log.end());
      applied_ = shared_->log.size();
    }
    for (const SharedLog::Change& change : pending) {
      auto gallery = registry_->Get(change.gallery);
      if (!gallery.ok()) return gallery.status();
      SHAPEID_RETURN_IF_ERROR(
          change.added.empty()
              ? (*gallery)->ApplyStoredRemove(change.removed, change.updated, change.version)
              : (*gallery)->ApplyStoredAppend(change.added, change.updated, change.version));
    }
    return absl::OkStatus();
  }

  int catch_ups = 0;

 private:
  absl::Status Write(SharedLog::Change change) {
    std::lock_guard<std::mutex> lock(shared_->mu);
    uint64_t& stored = shared_->versions[change.gallery];
    if (change.version != stored + 1) {
      return absl::AbortedError(absl::StrCat("stale: store at ", stored));
    }
    stored = change.version;
    shared_->log.push_back(std::move(change));
    return absl::OkStatus();
  }

  SharedLog* const shared_;
  GalleryRegistry* registry_ = nullptr;
  size_t applied_ = 0;  // entries of shared_->log this replica holds (its own included)
};

TEST(GalleryRegistryTest, AWriteOnAStaleReplicaCatchesUpAndRetriesWithFreshIds) {
  SharedLog shared;
  auto store_a = std::make_shared<ReplicaStore>(&shared);
  auto store_b = std::make_shared<ReplicaStore>(&shared);
  GalleryRegistry a({}, store_a, [&](absl::string_view name) { return store_a->CatchUp(name); });
  GalleryRegistry b({}, store_b, [&](absl::string_view name) { return store_b->CatchUp(name); });
  store_a->Attach(&a);
  store_b->Attach(&b);

  auto on_a = a.Create("g", {});
  ASSERT_TRUE(on_a.ok()) << on_a.status();
  ASSERT_TRUE(b.ApplyStoredGallery((*on_a)->Snapshot()->ToStored()).ok());
  auto on_b = b.Get("g");
  ASSERT_TRUE(on_b.ok());

  auto first = (*on_a)->Train({{0, "box", Box(1)}, {0, "box", Box(2)}});
  ASSERT_TRUE(first.ok()) << first.status();
  EXPECT_EQ(first->version, 1u);

  // B has not seen A's batch: its first attempt is refused, it applies A's batch, retries.
  auto second = (*on_b)->Train({{0, "sphere", Sphere(1)}, {7, "sphere", Sphere(2)}});
  ASSERT_TRUE(second.ok()) << second.status();
  EXPECT_EQ(store_b->catch_ups, 1);
  EXPECT_EQ(second->version, 2u);
  // The assigned id is chosen again after catching up: not one of A's.
  EXPECT_EQ(second->ids, (std::vector<uint64_t>{first->ids[1] + 1, 7}));
  EXPECT_EQ((*on_b)->Snapshot()->num_samples(), 4);

  // A removal on A, which has not seen B's spheres: it catches up and finds them. Then both
  // copies agree.
  auto removed = (*on_a)->RemoveSamples({}, {"sphere"});
  ASSERT_TRUE(removed.ok()) << removed.status();
  EXPECT_EQ(*removed, 2);
  ASSERT_TRUE(store_b->CatchUp("g").ok());
  for (const auto& gallery : {*on_a, *on_b}) {
    EXPECT_EQ(gallery->Snapshot()->version(), 3u);
    EXPECT_EQ(gallery->Snapshot()->num_samples(), 2);
    EXPECT_EQ(gallery->Snapshot()->Classify(Sphere(3))->label, "box");
  }
}

TEST(GalleryRegistryTest, StoredChangesApplyOnceAndInOrder) {
  GalleryRegistry registry;
  auto g = registry.Create("g", {});
  ASSERT_TRUE(g.ok());
  const std::vector<float> features = (*g)->Snapshot()->Describe(Box(1)).value();
  const StoredSample sample{kFirstAssignedId + 41, "box", features};
  const absl::Time now = absl::Now();
  ASSERT_TRUE((*g)->ApplyStoredAppend({sample}, now, 1).ok());
  // Again (a notification and a poll both delivered it): skipped, not an error.
  ASSERT_TRUE((*g)->ApplyStoredAppend({sample}, now, 1).ok());
  EXPECT_EQ((*g)->Snapshot()->num_samples(), 1);
  // A gap: refused, so that the caller reloads the gallery instead.
  EXPECT_EQ((*g)->ApplyStoredRemove({sample.id}, now, 3).code(),
            absl::StatusCode::kFailedPrecondition);
  // Assigned ids continue above the replicated one.
  auto trained = (*g)->Train({{0, "box", Box(2)}});
  ASSERT_TRUE(trained.ok());
  EXPECT_EQ(trained->ids[0], kFirstAssignedId + 42);
  EXPECT_EQ(trained->version, 2u);

  const uint64_t incarnation = (*g)->Snapshot()->incarnation();
  EXPECT_NE(incarnation, 0u);
  registry.ApplyStoredDelete("g", incarnation + 1);  // another incarnation: kept
  EXPECT_TRUE(registry.Get("g").ok());
  registry.ApplyStoredDelete("g", incarnation);
  EXPECT_EQ(registry.Get("g").status().code(), absl::StatusCode::kNotFound);
  EXPECT_EQ((*g)->Train({{0, "box", Box(3)}}).status().code(), absl::StatusCode::kNotFound);
  registry.ApplyStoredDelete("g", incarnation);  // absent: nothing to do
}

}  // namespace
}  // namespace shapeid
