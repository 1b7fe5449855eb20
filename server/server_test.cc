#include "server/server.h"

#include <unistd.h>

#include <cstdlib>
#include <string>

#include "absl/strings/str_cat.h"
#include "client/client.h"
#include "core/gallery/gallery_registry.h"
#include "core/testing/test_clouds.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "server/storage/sqlite_gallery_store.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;

std::string ScratchDir() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const std::string dir =
      absl::StrCat(::testing::TempDir(), "/server_test_", getpid(), "_", info->name());
  std::system(absl::StrCat("rm -rf '", dir, "'").c_str());
  return dir;
}

// A data directory holding gallery "stored" with 5 samples, written through the store.
void WriteStoredGallery(const std::string& dir) {
  auto store = SqliteGalleryStore::Open({dir, false});
  ASSERT_TRUE(store.ok()) << store.status();
  std::shared_ptr<SqliteGalleryStore> shared = *std::move(store);
  GalleryRegistry registry({}, shared);
  ASSERT_TRUE(registry.LoadFromStore().ok());
  auto gallery = registry.Create("stored", {});
  ASSERT_TRUE(gallery.ok());
  std::vector<LabelledCloud> samples;
  for (uint32_t i = 0; i < 5; ++i) {
    samples.push_back({0, "box", testing_clouds::ShapeCloud(0, i, 200)});
  }
  ASSERT_TRUE((*gallery)->Train(samples).ok());
}

std::unique_ptr<Client> ClientFor(const ShapeIdServer& server) {
  ClientOptions options;
  options.target = server.address();
  options.max_attempts = 1;
  auto client = Client::Connect(options);
  EXPECT_TRUE(client.ok());
  return *std::move(client);
}

TEST(ShapeIdServerTest, NotServingUntilEveryGalleryIsLoaded) {
  const std::string dir = ScratchDir();
  WriteStoredGallery(dir);
  ServerOptions options;
  options.listen = "127.0.0.1:0";
  options.data_dir = dir;
  auto server = ShapeIdServer::Bind(options);
  ASSERT_TRUE(server.ok()) << server.status();
  auto client = ClientFor(**server);

  // Bound, but loading: health says NOT_SERVING and calls are refused, not answered from an
  // empty registry.
  EXPECT_EQ(client->CheckHealth().code(), absl::StatusCode::kUnavailable);
  const auto early = client->ListGalleries();
  EXPECT_EQ(early.status().code(), absl::StatusCode::kUnavailable);
  EXPECT_THAT(early.status().message(), HasSubstr("loading"));

  auto report = (*server)->LoadGalleries();
  ASSERT_TRUE(report.ok()) << report.status();
  EXPECT_EQ(report->galleries, 1);
  EXPECT_EQ(report->samples, 5);
  EXPECT_TRUE(report->persistent);
  EXPECT_FALSE(report->read_only);
  EXPECT_TRUE(client->CheckHealth().ok());
  const auto galleries = client->ListGalleries();
  ASSERT_TRUE(galleries.ok()) << galleries.status();
  ASSERT_EQ(galleries->size(), 1u);
  EXPECT_EQ((*galleries)[0].sample_count(), 5u);
}

TEST(ShapeIdServerTest, ADamagedStoreNeverServes) {
  const std::string dir = ScratchDir();
  WriteStoredGallery(dir);
  ASSERT_EQ(truncate((dir + "/galleries/stored.gallery").c_str(), 1000), 0);
  ServerOptions options;
  options.listen = "127.0.0.1:0";
  options.data_dir = dir;
  auto server = ShapeIdServer::Bind(options);
  ASSERT_TRUE(server.ok()) << server.status();
  auto report = (*server)->LoadGalleries();
  EXPECT_EQ(report.status().code(), absl::StatusCode::kDataLoss);
  EXPECT_THAT(report.status().message(), HasSubstr("stored.gallery"));
  auto client = ClientFor(**server);
  EXPECT_EQ(client->CheckHealth().code(), absl::StatusCode::kUnavailable);
  EXPECT_EQ(ShapeIdServer::Start(options).status().code(), absl::StatusCode::kFailedPrecondition)
      << "the first server still holds the directory's lock";
}

TEST(ShapeIdServerTest, EmptyDataDirMeansMemoryOnly) {
  ServerOptions options;
  options.listen = "127.0.0.1:0";
  auto server = ShapeIdServer::Start(options);
  ASSERT_TRUE(server.ok()) << server.status();
  EXPECT_FALSE((*server)->load_report().persistent);
  EXPECT_TRUE(ClientFor(**server)->CheckHealth().ok());
}

}  // namespace
}  // namespace shapeid
