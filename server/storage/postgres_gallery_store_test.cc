#include "server/storage/postgres_gallery_store.h"

#include <atomic>
#include <map>
#include <memory>
#include <random>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "core/gallery/gallery_store_testing.h"
#include "core/testing/gallery_shapes.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "server/replication/replication_follower.h"
#include "server/storage/testing/postgres_database_test.h"

namespace shapeid {
namespace {

using gallery_testing::Box;
using gallery_testing::ExpectSameStoredGallery;
using gallery_testing::MakeGallery;
using gallery_testing::Sphere;
using ::testing::HasSubstr;

class PostgresGalleryStoreTest : public PostgresDatabaseTest {
 protected:
  PostgresGalleryStoreTest() : PostgresDatabaseTest("t_") {}

  std::unique_ptr<PostgresGalleryStore> Open() {
    auto store = PostgresGalleryStore::Open({conninfo_, 4});
    EXPECT_TRUE(store.ok()) << store.status();
    return store.ok() ? *std::move(store) : nullptr;
  }

  // A replica: its store, its registry, loaded from the store, and its follower (refresh
  // 200 ms), which is the registry's catch-up function.
  struct Replica {
    std::shared_ptr<PostgresGalleryStore> store;
    std::unique_ptr<ReplicationFollower> follower;
    std::unique_ptr<GalleryRegistry> registry;
    std::atomic<int> unreachable_reports{0};
    std::atomic<bool> reachable{true};

    // Stop following before the registry goes.
    ~Replica() { follower->Stop(); }
  };
  std::unique_ptr<Replica> StartReplica() {
    auto replica = std::make_unique<Replica>();
    replica->store = Open();
    replica->follower = std::make_unique<ReplicationFollower>(
        replica->store, ReplicationFollowerOptions{absl::Milliseconds(200), nullptr});
    ReplicationFollower* follower = replica->follower.get();
    replica->registry = std::make_unique<GalleryRegistry>(
        GalleryLimits{}, replica->store,
        [follower](absl::string_view name) { return follower->CatchUp(name); });
    EXPECT_TRUE(replica->registry->LoadFromStore().ok());
    Replica* r = replica.get();
    replica->follower->Start(replica->registry.get(), [r](bool reachable) {
      r->reachable = reachable;
      if (!reachable) ++r->unreachable_reports;
    });
    return replica;
  }
};

TEST_F(PostgresGalleryStoreTest, EveryWriteSurvivesBitForBit) {
  StoredGallery a = MakeGallery("a", 12, 1500, 1);  // more than one INSERT statement
  a.samples[3].features[0] = -0.0f;
  {
    auto store = Open();
    ASSERT_NE(store, nullptr);
    ASSERT_TRUE(store->LoadAll().ok());
    ASSERT_TRUE(store->SaveGallery(a).ok());
    StoredGallery more = MakeGallery("a", 12, 3, 2);
    for (auto& s : more.samples) s.id += 100'000;
    a.updated += absl::Seconds(1);
    a.version = 1;
    ASSERT_TRUE(store->AppendSamples("a", more.samples, a.updated, 1).ok());
    a.samples.insert(a.samples.end(), more.samples.begin(), more.samples.end());
    const std::vector<uint64_t> gone = {a.samples[0].id, a.samples[1].id};
    a.version = 2;
    ASSERT_TRUE(store->RemoveSamples("a", gone, a.updated, 2).ok());
    a.samples.erase(a.samples.begin(), a.samples.begin() + 2);
    ASSERT_TRUE(store->SaveGallery(MakeGallery("b", 4, 0, 3)).ok());
    ASSERT_TRUE(store->DeleteGallery("b").ok());
  }
  auto reopened = Open();
  ASSERT_NE(reopened, nullptr);
  auto loaded = reopened->LoadAll();
  ASSERT_TRUE(loaded.ok()) << loaded.status();
  ASSERT_EQ(loaded->size(), 1u);
  ExpectSameStoredGallery((*loaded)[0], a);
  EXPECT_EQ((*loaded)[0].version, 2u);
  EXPECT_EQ((*loaded)[0].incarnation, a.incarnation);
}

// Rows as an earlier release wrote them (literal SQL; the sample's CRC-32 computed outside
// shapeid) load with every field, and take changes.
// Records what Load hands over: each gallery's name as it ends, and the head after it.
class HeadRecorder final : public GalleryLoader {
 public:
  absl::Status Begin(const GalleryMetadata& gallery) override {
    current_ = gallery.name;
    return absl::OkStatus();
  }
  absl::Status Add(StoredSample&) override { return absl::OkStatus(); }
  absl::Status End() override {
    ended_.push_back(current_);
    return absl::OkStatus();
  }
  absl::Status Head(absl::string_view bytes) override {
    heads_[ended_.back()] = std::string(bytes);
    return absl::OkStatus();
  }
  std::vector<std::string> ended_;
  std::map<std::string, std::string> heads_;

 private:
  std::string current_;
};

TEST_F(PostgresGalleryStoreTest, ATrainedHeadSurvivesARestartAndGoesWithItsGallery) {
  const std::string head(std::string("SHPDHEAD\0\xff binary bytes", 23));
  {
    auto store = Open();
    ASSERT_NE(store, nullptr);
    ASSERT_TRUE(store->LoadAll().ok());
    ASSERT_TRUE(store->SaveGallery(MakeGallery("a", 4, 3, 1)).ok());
    ASSERT_TRUE(store->SaveGallery(MakeGallery("b", 4, 3, 2)).ok());
    ASSERT_TRUE(store->SaveHead("a", "an older head").ok());
    ASSERT_TRUE(store->SaveHead("a", head).ok()) << "a later fit replaces the head";
    ASSERT_TRUE(store->SaveHead("b", "b's head").ok());
    ASSERT_TRUE(store->SaveHead("gone", "nobody's head").ok()) << "no gallery: nothing kept";
  }
  auto reopened = Open();
  ASSERT_NE(reopened, nullptr);
  HeadRecorder loaded;
  ASSERT_TRUE(reopened->Load(loaded).ok());
  EXPECT_EQ(loaded.ended_, (std::vector<std::string>{"a", "b"}));
  EXPECT_EQ(loaded.heads_, (std::map<std::string, std::string>{{"a", head}, {"b", "b's head"}}));
  // Deleted with its gallery; a new gallery of the same name starts without one.
  ASSERT_TRUE(reopened->DeleteGallery("a").ok());
  ASSERT_TRUE(reopened->SaveGallery(MakeGallery("a", 4, 3, 3)).ok());
  HeadRecorder after;
  ASSERT_TRUE(Open()->Load(after).ok());
  EXPECT_EQ(after.heads_, (std::map<std::string, std::string>{{"b", "b's head"}}));
}

TEST_F(PostgresGalleryStoreTest, RowsAnEarlierReleaseWroteLoadAndTakeChanges) {
  auto store = Open();  // creates the tables
  ASSERT_NE(store, nullptr);
  auto c = PgConnection::Connect(conninfo_);
  ASSERT_TRUE(c.ok()) << c.status();
  ASSERT_TRUE((*c)->ExecScript("write old rows", R"sql(
INSERT INTO shapeid_galleries (name, incarnation, descriptor_spec, dimension, k, weighting,
  scaling, reject_distance_bits, augment, descriptor_version, software_version, created_unix_ns,
  updated_unix_ns, version)
VALUES ('old', 12345, 'rphsd:refs=cross7,bins=10,variant=reduced', 2, 3, 'distance', 'zscore',
  4604930618986332160, 'views=2,noise=0.01,points=300-500,pose=fixed,seed=1', 1, '0.1.0',
  1795814593221890089, 1795814601502715857, 7);
INSERT INTO shapeid_samples (incarnation, id, label, features, crc)
VALUES (12345, 5, 'box'::bytea, '\x0000803f00000040'::bytea, 3434098435);
)sql")
                  .ok());
  auto loaded = store->LoadAll();
  ASSERT_TRUE(loaded.ok()) << loaded.status();
  ASSERT_EQ(loaded->size(), 1u);
  StoredGallery g = (*loaded)[0];
  EXPECT_EQ(g.name, "old");
  EXPECT_EQ(g.incarnation, 12345u);
  EXPECT_EQ(g.options.descriptor_spec, "rphsd:refs=cross7,bins=10,variant=reduced");
  EXPECT_EQ(g.dimension, 2);
  EXPECT_EQ(g.options.knn.k, 3);
  EXPECT_EQ(g.options.knn.weighting, VoteWeighting::kDistance);
  EXPECT_EQ(g.options.knn.scaling, FeatureScaling::kZScore);
  EXPECT_EQ(g.options.reject_distance, 0.75);
  EXPECT_EQ(g.options.augment.views, 2);
  EXPECT_EQ(g.descriptor_version, 1u);
  EXPECT_EQ(g.software_version, "0.1.0");
  EXPECT_EQ(absl::ToUnixNanos(g.created), 1795814593221890089);
  EXPECT_EQ(absl::ToUnixNanos(g.updated), 1795814601502715857);
  EXPECT_EQ(g.version, 7u);
  ASSERT_EQ(g.samples.size(), 1u);
  EXPECT_EQ(g.samples[0].id, 5u);
  EXPECT_EQ(g.samples[0].label, "box");
  EXPECT_EQ(g.samples[0].features, std::vector<float>({1.0f, 2.0f}));

  StoredSample more{6, "rod", {3.0f, 4.0f}};
  g.updated += absl::Seconds(1);
  g.version = 8;
  ASSERT_TRUE(store->AppendSamples("old", {more}, g.updated, 8).ok());
  g.samples.push_back(more);
  auto reloaded = Open()->LoadAll();
  ASSERT_TRUE(reloaded.ok()) << reloaded.status();
  ASSERT_EQ(reloaded->size(), 1u);
  ExpectSameStoredGallery((*reloaded)[0], g);
  EXPECT_EQ((*reloaded)[0].version, 8u);
}

TEST_F(PostgresGalleryStoreTest, ANameTakenThroughAnotherReplicaIsAlreadyExists) {
  auto one = Open();
  auto two = Open();
  ASSERT_TRUE(one->LoadAll().ok());
  ASSERT_TRUE(two->LoadAll().ok());
  ASSERT_TRUE(one->SaveGallery(MakeGallery("g", 4, 2, 1)).ok());
  const absl::Status again = two->SaveGallery(MakeGallery("g", 4, 2, 1));
  EXPECT_EQ(again.code(), absl::StatusCode::kAlreadyExists);
  EXPECT_THAT(again.message(), HasSubstr("another replica"));
}

TEST_F(PostgresGalleryStoreTest, ReplicasSeeEachOthersChanges) {
  auto a = StartReplica();
  auto b = StartReplica();
  auto on_a = a->registry->Create("g", {});
  ASSERT_TRUE(on_a.ok()) << on_a.status();
  auto trained = (*on_a)->Train({{0, "box", Box(1)}, {5, "sphere", Sphere(1)}});
  ASSERT_TRUE(trained.ok()) << trained.status();
  ASSERT_TRUE(b->follower->Sync().ok());

  auto on_b = b->registry->Get("g");
  ASSERT_TRUE(on_b.ok()) << on_b.status();
  EXPECT_EQ((*on_b)->Snapshot()->version(), trained->version);
  EXPECT_EQ((*on_b)->Snapshot()->num_samples(), 2);
  EXPECT_EQ((*on_b)->Snapshot()->Classify(Sphere(2))->label, "sphere");

  // Removal through B, seen by A.
  ASSERT_TRUE((*on_b)->RemoveSamples({5}).ok());
  ASSERT_TRUE(a->follower->Sync().ok());
  EXPECT_EQ((*on_a)->Snapshot()->num_samples(), 1);
  EXPECT_EQ((*on_a)->Snapshot()->version(), (*on_b)->Snapshot()->version());

  // Deleted through A and made again under the same name: B drops the old one and loads the
  // new one, whose ids start afresh.
  ASSERT_TRUE(a->registry->Delete("g").ok());
  ASSERT_TRUE(a->registry->Create("g", {}).ok());
  ASSERT_TRUE((*a->registry->Get("g"))->Train({{9, "cube", Box(3)}}).ok());
  ASSERT_TRUE(b->follower->Sync().ok());
  auto again = b->registry->Get("g");
  ASSERT_TRUE(again.ok());
  EXPECT_NE(again->get(), on_b->get());
  EXPECT_EQ((*again)->Snapshot()->num_samples(), 1);
  EXPECT_TRUE((*again)->Snapshot()->Contains(9));
  // The old copy a stream might still hold refuses writes.
  EXPECT_EQ((*on_b)->Train({{0, "box", Box(4)}}).status().code(), absl::StatusCode::kNotFound);
}

TEST_F(PostgresGalleryStoreTest, FollowingAppliesChangesWithoutBeingAsked) {
  auto a = StartReplica();
  auto b = StartReplica();
  ASSERT_TRUE(a->registry->Create("g", {}).ok());
  ASSERT_TRUE((*a->registry->Get("g"))->Train({{1, "box", Box(1)}}).ok());
  // NOTIFY wakes B's follower; 10 s is far beyond any reasonable delay and never reached.
  const absl::Time deadline = absl::Now() + absl::Seconds(10);
  while (absl::Now() < deadline) {
    auto g = b->registry->Get("g");
    if (g.ok() && (*g)->Snapshot()->num_samples() == 1) break;
    absl::SleepFor(absl::Milliseconds(5));
  }
  auto g = b->registry->Get("g");
  ASSERT_TRUE(g.ok());
  EXPECT_EQ((*g)->Snapshot()->num_samples(), 1);
  EXPECT_GE(b->follower->changes_applied(), 1);  // the create (read whole, with its sample)
}

TEST_F(PostgresGalleryStoreTest, ConcurrentWritersThroughTwoReplicasLoseNothing) {
  auto a = StartReplica();
  auto b = StartReplica();
  ASSERT_TRUE(a->registry->Create("g", {}).ok());
  ASSERT_TRUE(b->follower->Sync().ok());
  constexpr int kThreads = 3;
  constexpr int kBatches = 8;
  std::atomic<int> failures{0};
  std::vector<std::thread> writers;
  for (Replica* replica : {a.get(), b.get()}) {
    for (int t = 0; t < kThreads; ++t) {
      writers.emplace_back([&, replica, t] {
        auto gallery = replica->registry->Get("g");
        for (int i = 0; i < kBatches; ++i) {
          // Assigned ids: the ones a stale replica would pick clash unless it catches up.
          auto done = (*gallery)->Train({{0, "box", Box(static_cast<uint32_t>(t * 100 + i))},
                                         {0, "sphere", Sphere(static_cast<uint32_t>(i))}});
          if (!done.ok()) {
            ADD_FAILURE() << done.status();
            ++failures;
          }
        }
      });
    }
  }
  for (auto& w : writers) w.join();
  EXPECT_EQ(failures.load(), 0);
  ASSERT_TRUE(a->follower->Sync().ok());
  ASSERT_TRUE(b->follower->Sync().ok());
  const int expected = 2 * kThreads * kBatches * 2;
  for (Replica* replica : {a.get(), b.get()}) {
    auto snapshot = (*replica->registry->Get("g"))->Snapshot();
    EXPECT_EQ(snapshot->num_samples(), expected);
    EXPECT_EQ(snapshot->version(), static_cast<uint64_t>(2 * kThreads * kBatches));
  }
  auto fresh = Open();
  auto loaded = fresh->LoadAll();
  ASSERT_TRUE(loaded.ok());
  std::set<uint64_t> ids;
  for (const auto& s : (*loaded)[0].samples) ids.insert(s.id);
  EXPECT_EQ(ids.size(), static_cast<size_t>(expected));
}

TEST_F(PostgresGalleryStoreTest, AReplicaReportsPostgresLossAndCatchesUpAfter) {
  auto a = StartReplica();
  auto b = StartReplica();
  ASSERT_TRUE(a->registry->Create("g", {}).ok());
  ASSERT_TRUE(b->follower->Sync().ok());

  ASSERT_TRUE(pg_->Stop().ok());
  // Both followers notice within `refresh` (200 ms here) plus the time to fail a connect.
  const absl::Time deadline = absl::Now() + absl::Seconds(10);
  while (absl::Now() < deadline && (a->reachable || b->reachable)) {
    absl::SleepFor(absl::Milliseconds(10));
  }
  EXPECT_FALSE(a->reachable);
  EXPECT_FALSE(b->reachable);
  std::printf("both replicas unreachable %s after PostgreSQL stopped (refresh 200 ms)\n",
              absl::FormatDuration(absl::Now() - (deadline - absl::Seconds(10))).c_str());
  const absl::Status write = (*a->registry->Get("g"))->Train({{1, "box", Box(1)}}).status();
  EXPECT_EQ(write.code(), absl::StatusCode::kUnavailable) << write;
  EXPECT_EQ((*a->registry->Get("g"))->Snapshot()->num_samples(), 0);  // nothing published

  ASSERT_TRUE(pg_->StartServer().ok());
  // The first write after the restart reconnects (the pooled connections died with it).
  auto trained = (*a->registry->Get("g"))->Train({{1, "box", Box(1)}});
  ASSERT_TRUE(trained.ok()) << trained.status();
  const absl::Time back = absl::Now() + absl::Seconds(20);
  while (absl::Now() < back && (!a->reachable || !b->reachable ||
                                (*b->registry->Get("g"))->Snapshot()->num_samples() != 1)) {
    absl::SleepFor(absl::Milliseconds(10));
  }
  EXPECT_TRUE(a->reachable);
  EXPECT_TRUE(b->reachable);
  EXPECT_EQ((*b->registry->Get("g"))->Snapshot()->num_samples(), 1);
  EXPECT_GE(a->unreachable_reports.load(), 1);
}

TEST_F(PostgresGalleryStoreTest, AChangeThatDoesNotApplyReloadsTheGalleryInsteadOfStopping) {
  auto a = StartReplica();
  auto b = StartReplica();
  ASSERT_TRUE(a->registry->Create("g", {}).ok());
  ASSERT_TRUE((*a->registry->Get("g"))->Train({{1, "box", Box(1)}}).ok());
  ASSERT_TRUE(b->follower->Sync().ok());
  const std::shared_ptr<Gallery> held_by_a_stream = *b->registry->Get("g");
  // A log entry B's copy cannot take: it appends id 1, which B holds already (the state a
  // torn read would leave). B must read the gallery again from the store, not stop there.
  auto admin = PgConnection::Connect(conninfo_);
  ASSERT_TRUE(admin.ok());
  // One transaction, as a real write is: a follower (both replicas follow) must never read
  // the log entry before the version it names (it would reload version 1 and stay there).
  ASSERT_TRUE((*admin)
                  ->ExecScript("log and bump",
                               "INSERT INTO shapeid_changes (gallery, incarnation, version, kind, "
                               "ids, updated_unix_ns) SELECT name, incarnation, version + 1, "
                               "'append', '{1}', updated_unix_ns FROM shapeid_galleries WHERE "
                               "name = 'g'; UPDATE shapeid_galleries SET version = version + 1")
                  .ok());
  ASSERT_TRUE(b->follower->Sync().ok());
  auto on_b = (*b->registry->Get("g"))->Snapshot();
  EXPECT_EQ(on_b->version(), 2u);
  EXPECT_EQ(on_b->num_samples(), 1);
  // The same gallery took the stored state: a stream holding it goes on.
  EXPECT_EQ(b->registry->Get("g")->get(), held_by_a_stream.get());
  EXPECT_EQ(held_by_a_stream->Snapshot()->version(), 2u);
  // And the log goes on: a later change through A reaches B.
  ASSERT_TRUE(a->follower->Sync().ok());
  ASSERT_TRUE((*a->registry->Get("g"))->Train({{2, "box", Box(2)}}).ok());
  ASSERT_TRUE(b->follower->Sync().ok());
  EXPECT_EQ((*b->registry->Get("g"))->Snapshot()->num_samples(), 2);
}

TEST_F(PostgresGalleryStoreTest, AReplicaAwayLongerThanTheLogKeepsReloadsEverything) {
  auto a = StartReplica();
  auto b = StartReplica();
  ASSERT_TRUE(a->registry->Create("kept", {}).ok());
  ASSERT_TRUE(a->registry->Create("dropped", {}).ok());
  ASSERT_TRUE(b->follower->Sync().ok());
  b->follower->Stop();  // B is away...
  ASSERT_TRUE((*a->registry->Get("kept"))->Train({{1, "box", Box(1)}}).ok());
  ASSERT_TRUE(a->registry->Delete("dropped").ok());
  // ...for longer than the log keeps: every row pruned, as the follower's prune would.
  auto admin = PgConnection::Connect(conninfo_);
  ASSERT_TRUE(admin.ok());
  ASSERT_TRUE((*admin)
                  ->Exec("prune",
                         "WITH gone AS (DELETE FROM shapeid_changes RETURNING seq) UPDATE "
                         "shapeid_log_floor SET seq = greatest(seq, (SELECT coalesce(max(seq), 0) "
                         "FROM gone))")
                  .ok());
  // An empty log must not read as "nothing happened": the floor says rows were lost.
  ASSERT_TRUE(b->follower->Sync().ok());
  EXPECT_EQ(b->registry->Get("dropped").status().code(), absl::StatusCode::kNotFound);
  auto kept = b->registry->Get("kept");
  ASSERT_TRUE(kept.ok());
  EXPECT_EQ((*kept)->Snapshot()->num_samples(), 1);
  // And it follows the log from there.
  ASSERT_TRUE((*a->registry->Get("kept"))->Train({{2, "box", Box(2)}}).ok());
  ASSERT_TRUE(b->follower->Sync().ok());
  EXPECT_EQ((*b->registry->Get("kept"))->Snapshot()->num_samples(), 2);
}

// Not a test: the figures docs/scaling.md quotes for loading from PostgreSQL (a replica's
// start-up), run by hand:
//   build/ci/server/storage/postgres_gallery_store_test --gtest_also_run_disabled_tests
//       --gtest_filter='*LoadCost*'
TEST_F(PostgresGalleryStoreTest, DISABLED_LoadCost) {
  for (const int dimension : {81, 240}) {
    constexpr int kSamples = 100'000;
    const std::string name = absl::StrCat("d", dimension);
    StoredGallery g = MakeGallery(name, dimension, kSamples, 7);
    auto store = Open();
    ASSERT_TRUE(store->LoadAll().ok());
    absl::Time start = absl::Now();
    ASSERT_TRUE(store->SaveGallery(g).ok());
    const absl::Duration save = absl::Now() - start;
    auto reader = Open();
    start = absl::Now();
    auto loaded = reader->LoadAll();
    const absl::Duration load = absl::Now() - start;
    ASSERT_TRUE(loaded.ok());
    std::printf("%d samples x %d floats: saved (one import) in %s, loaded in %s (%.0f samples/s)\n",
                kSamples, dimension, absl::FormatDuration(save).c_str(),
                absl::FormatDuration(load).c_str(), kSamples / absl::ToDoubleSeconds(load));
    ASSERT_TRUE(store->DeleteGallery(name).ok());
  }
}

}  // namespace
}  // namespace shapeid
