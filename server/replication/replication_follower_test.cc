#include "server/replication/replication_follower.h"

#include <memory>
#include <string>

#include "absl/strings/str_cat.h"
#include "core/testing/gallery_shapes.h"
#include "gtest/gtest.h"
#include "server/storage/testing/postgres_database_test.h"

namespace shapeid {
namespace {

using gallery_testing::Box;

// The follower's own contract; replication end to end (two replicas, PostgreSQL lost and
// back, a pruned log) is in server/storage/postgres_gallery_store_test.cc.
class ReplicationFollowerTest : public PostgresDatabaseTest {
 protected:
  ReplicationFollowerTest() : PostgresDatabaseTest("f_") {}

  std::shared_ptr<PostgresGalleryStore> Open() {
    auto store = PostgresGalleryStore::Open({conninfo_, 4});
    EXPECT_TRUE(store.ok()) << store.status();
    return store.ok() ? std::shared_ptr<PostgresGalleryStore>(*std::move(store)) : nullptr;
  }
};

TEST_F(ReplicationFollowerTest, AppliesFromWhereTheRegistryWasLoadedOnceStarted) {
  GalleryRegistry writer({}, Open());
  ASSERT_TRUE(writer.LoadFromStore().ok());
  std::shared_ptr<PostgresGalleryStore> store = Open();
  GalleryRegistry registry({}, store);
  ReplicationFollower follower(store, {absl::Milliseconds(200), nullptr});
  EXPECT_TRUE(follower.reachable());
  ASSERT_TRUE(registry.LoadFromStore().ok());
  ASSERT_TRUE(writer.Create("g", {}).ok());

  // Not started: there is nothing to apply to.
  ASSERT_TRUE(follower.Sync().ok());
  EXPECT_EQ(registry.size(), 0u);
  EXPECT_EQ(follower.changes_applied(), 0);

  follower.Start(&registry, nullptr);
  ASSERT_TRUE(follower.Sync().ok());
  EXPECT_TRUE(registry.Get("g").ok());
  ASSERT_TRUE((*writer.Get("g"))->Train({{1, "box", Box(1)}}).ok());
  follower.Stop();
  follower.Stop();  // idempotent
  // Stopped, it still applies when asked.
  ASSERT_TRUE(follower.Sync().ok());
  EXPECT_EQ((*registry.Get("g"))->Snapshot()->num_samples(), 1);
  EXPECT_EQ(follower.changes_applied(), 2);  // the create (read whole) and the append
}

TEST_F(ReplicationFollowerTest, AStaleWriteCatchesUpThroughTheFollowerAndRetries) {
  GalleryRegistry writer({}, Open());
  ASSERT_TRUE(writer.LoadFromStore().ok());
  std::shared_ptr<PostgresGalleryStore> store = Open();
  ReplicationFollower follower(store, {absl::Milliseconds(200), nullptr});
  GalleryRegistry registry({}, store,
                           [&](absl::string_view name) { return follower.CatchUp(name); });
  ASSERT_TRUE(registry.LoadFromStore().ok());
  follower.Start(&registry, nullptr);
  follower.Stop();  // from here on only the catch-up applies changes: no race with the thread

  ASSERT_TRUE(writer.Create("g", {}).ok());
  ASSERT_TRUE(follower.Sync().ok());
  ASSERT_TRUE((*writer.Get("g"))->Train({{1, "box", Box(1)}}).ok());
  // This copy is at version 0, the store at 1: refused, caught up, retried.
  auto trained = (*registry.Get("g"))->Train({{2, "box", Box(2)}});
  ASSERT_TRUE(trained.ok()) << trained.status();
  EXPECT_EQ(trained->version, 2u);
  EXPECT_EQ((*registry.Get("g"))->Snapshot()->num_samples(), 2);
}

}  // namespace
}  // namespace shapeid
