#include "server/storage/sqlite_gallery_store.h"

#include <sys/mount.h>
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "core/gallery/gallery_store_testing.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "server/storage/file_util.h"

namespace shapeid {
namespace {

using gallery_testing::ExpectSameStoredGallery;
using gallery_testing::MakeGallery;

using ::testing::AllOf;
using ::testing::ElementsAre;
using ::testing::HasSubstr;
using ::testing::IsEmpty;

// A scratch directory per process and test (ctest runs tests in parallel processes).
std::string ScratchDir(absl::string_view what) {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const std::string dir =
      absl::StrCat(::testing::TempDir(), "/sqlite_store_", getpid(), "_", info->name(), "_", what);
  std::system(absl::StrCat("rm -rf '", dir, "'").c_str());
  return dir;
}

std::unique_ptr<SqliteGalleryStore> OpenStore(const std::string& dir, bool set_aside = false) {
  auto store = SqliteGalleryStore::Open({dir, set_aside});
  EXPECT_TRUE(store.ok()) << store.status();
  return store.ok() ? *std::move(store) : nullptr;
}

TEST(SqliteGalleryStoreTest, EverythingSurvivesReopeningBitForBit) {
  const std::string dir = ScratchDir("data");
  StoredGallery a = MakeGallery("a", 81, 40, 1);
  const StoredGallery b = MakeGallery("b.2", 6, 0, 2);
  {
    auto store = OpenStore(dir);
    ASSERT_NE(store, nullptr);
    ASSERT_THAT(*store->LoadAll(), IsEmpty());
    ASSERT_TRUE(store->SaveGallery(a).ok());
    ASSERT_TRUE(store->SaveGallery(b).ok());
    StoredGallery more = MakeGallery("a", 81, 3, 9);
    for (StoredSample& s : more.samples) s.id += 1000;
    a.updated += absl::Seconds(1);
    ASSERT_TRUE(store->AppendSamples("a", more.samples, a.updated, 0).ok());
    a.samples.insert(a.samples.end(), more.samples.begin(), more.samples.end());
    const std::vector<uint64_t> gone = {a.samples[3].id, a.samples[10].id};
    a.updated += absl::Seconds(1);
    ASSERT_TRUE(store->RemoveSamples("a", gone, a.updated, 0).ok());
    a.samples.erase(a.samples.begin() + 10);
    a.samples.erase(a.samples.begin() + 3);
  }
  auto store = OpenStore(dir);
  auto loaded = store->LoadAll();
  ASSERT_TRUE(loaded.ok()) << loaded.status();
  ASSERT_EQ(loaded->size(), 2u);
  ExpectSameStoredGallery((*loaded)[0], a);  // sorted by name
  ExpectSameStoredGallery((*loaded)[1], b);
  // And it goes on accepting writes after a load.
  StoredGallery later = MakeGallery("a", 81, 1, 5);
  later.samples[0].id = 5000;
  EXPECT_TRUE(store->AppendSamples("a", later.samples, absl::Now(), 0).ok());
}

TEST(SqliteGalleryStoreTest, DeleteIsDurableAndANewGalleryOfTheSameNameStartsEmpty) {
  const std::string dir = ScratchDir("data");
  {
    auto store = OpenStore(dir);
    ASSERT_TRUE(store->LoadAll().ok());
    ASSERT_TRUE(store->SaveGallery(MakeGallery("x", 8, 10, 1)).ok());
    ASSERT_TRUE(store->DeleteGallery("x").ok());
    EXPECT_FALSE(FileExists(store->GalleryPath("x")));
    EXPECT_EQ(store->AppendSamples("x", {}, absl::Now(), 0).code(), absl::StatusCode::kInternal);
    ASSERT_TRUE(store->SaveGallery(MakeGallery("x", 8, 2, 2)).ok());
  }
  auto store = OpenStore(dir);
  auto loaded = store->LoadAll();
  ASSERT_TRUE(loaded.ok());
  ASSERT_EQ(loaded->size(), 1u);
  ExpectSameStoredGallery((*loaded)[0], MakeGallery("x", 8, 2, 2));
}

TEST(SqliteGalleryStoreTest, StartUpFinishesInterruptedCreatesAndDeletes) {
  const std::string dir = ScratchDir("data");
  {
    auto store = OpenStore(dir);
    ASSERT_TRUE(store->LoadAll().ok());
    ASSERT_TRUE(store->SaveGallery(MakeGallery("kept", 4, 2, 1)).ok());
  }
  // What a crash between the steps of SaveGallery or DeleteGallery leaves behind.
  for (const char* leftover : {".half.tmp", ".half.tmp-wal", ".gone.deleted"}) {
    std::ofstream(absl::StrCat(dir, "/galleries/", leftover)) << "partial";
  }
  auto store = OpenStore(dir);
  auto loaded = store->LoadAll();
  ASSERT_TRUE(loaded.ok()) << loaded.status();
  ASSERT_EQ(loaded->size(), 1u);
  EXPECT_EQ((*loaded)[0].name, "kept");
  EXPECT_THAT(*ListDirectory(dir + "/galleries"),
              ElementsAre("kept.gallery", "kept.gallery-shm", "kept.gallery-wal"));
}

TEST(SqliteGalleryStoreTest, OneDirectoryOneServer) {
  const std::string dir = ScratchDir("data");
  auto first = OpenStore(dir);
  ASSERT_NE(first, nullptr);
  auto second = SqliteGalleryStore::Open({dir, false});
  EXPECT_EQ(second.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(second.status().message(),
              AllOf(HasSubstr("in use by another shapeid-server"), HasSubstr(dir)));
  first.reset();
  EXPECT_TRUE(SqliteGalleryStore::Open({dir, false}).ok());
}

// Writes `bytes` at `offset` of `path`.
void Overwrite(const std::string& path, long offset, const std::string& bytes) {
  std::FILE* f = std::fopen(path.c_str(), "r+b");
  ASSERT_NE(f, nullptr);
  std::fseek(f, offset, SEEK_SET);
  std::fwrite(bytes.data(), 1, bytes.size(), f);
  std::fclose(f);
}

// Offset of the first occurrence of `needle` in the file.
long Find(const std::string& path, const std::string& needle) {
  std::ifstream in(path, std::ios::binary);
  const std::string data((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const size_t at = data.find(needle);
  return at == std::string::npos ? -1 : static_cast<long>(at);
}

// A store holding galleries "good" and "bad", closed (so everything is in the main files).
std::string StoreWithTwoGalleries(StoredGallery* bad) {
  const std::string dir = ScratchDir("data");
  *bad = MakeGallery("bad", 16, 30, 3);
  auto store = OpenStore(dir);
  EXPECT_TRUE(store->LoadAll().ok());
  EXPECT_TRUE(store->SaveGallery(MakeGallery("good", 16, 30, 4)).ok());
  EXPECT_TRUE(store->SaveGallery(*bad).ok());
  return dir;
}

TEST(SqliteGalleryStoreTest, FlippedFeatureBitIsReportedNotServed) {
  StoredGallery bad;
  const std::string dir = StoreWithTwoGalleries(&bad);
  const std::string path = dir + "/galleries/bad.gallery";
  const float* f = bad.samples[17].features.data();
  const long at = Find(path, std::string(reinterpret_cast<const char*>(f), 16 * sizeof(float)));
  ASSERT_GE(at, 0);
  float flipped = f[5];
  uint32_t bits;
  std::memcpy(&bits, &flipped, 4);
  bits ^= 1u << 3;
  Overwrite(path, at + 5 * 4, std::string(reinterpret_cast<const char*>(&bits), 4));

  auto store = OpenStore(dir);
  auto loaded = store->LoadAll();
  EXPECT_EQ(loaded.status().code(), absl::StatusCode::kDataLoss);
  EXPECT_THAT(loaded.status().message(),
              AllOf(HasSubstr("cannot load gallery 'bad'"), HasSubstr(path),
                    HasSubstr(absl::StrCat("sample id ", bad.samples[17].id)),
                    HasSubstr("checksum mismatch")));
  EXPECT_TRUE(FileExists(path));  // refusing touches nothing
}

TEST(SqliteGalleryStoreTest, TruncatedFileIsReported) {
  StoredGallery bad;
  const std::string dir = StoreWithTwoGalleries(&bad);
  const std::string path = dir + "/galleries/bad.gallery";
  ASSERT_EQ(truncate(path.c_str(), 4096 + 100), 0);
  auto store = OpenStore(dir);
  auto loaded = store->LoadAll();
  EXPECT_EQ(loaded.status().code(), absl::StatusCode::kDataLoss);
  EXPECT_THAT(loaded.status().message(),
              AllOf(HasSubstr("cannot load gallery 'bad'"), HasSubstr(path)));
  std::printf("truncated: %s\n", std::string(loaded.status().message()).c_str());
}

TEST(SqliteGalleryStoreTest, NotAGalleryAndNewerFormatAreReported) {
  const std::string dir = ScratchDir("data");
  ASSERT_TRUE(MakeDirectories(dir + "/galleries").ok());
  std::ofstream(dir + "/galleries/text.gallery") << "just some text, not a database at all\n";
  {
    auto store = OpenStore(dir);
    auto loaded = store->LoadAll();
    EXPECT_EQ(loaded.status().code(), absl::StatusCode::kDataLoss);
    EXPECT_THAT(loaded.status().message(), HasSubstr("text.gallery"));
  }
  ASSERT_TRUE(RemoveFileIfExists(dir + "/galleries/text.gallery").ok());
  {
    auto store = OpenStore(dir);
    ASSERT_TRUE(store->LoadAll().ok());
    ASSERT_TRUE(store->SaveGallery(MakeGallery("future", 4, 1, 1)).ok());
  }
  {
    auto db = SqliteDb::Open(dir + "/galleries/future.gallery", SqliteDb::Mode::kReadWrite);
    ASSERT_TRUE(db.ok());
    ASSERT_TRUE(
        (*db)
            ->Exec(absl::StrCat("PRAGMA user_version=", SqliteGalleryStore::kFormatVersion + 1))
            .ok());
  }
  auto store = OpenStore(dir);
  auto loaded = store->LoadAll();
  EXPECT_EQ(loaded.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(
      loaded.status().message(),
      AllOf(HasSubstr(absl::StrCat("format version ", SqliteGalleryStore::kFormatVersion + 1)),
            HasSubstr("newer shapeid")));
}

TEST(SqliteGalleryStoreTest, AugmentedGalleriesKeepTheirOptionsAndEveryView) {
  const std::string dir = ScratchDir("data");
  StoredGallery g = MakeGallery("views", 12, 6, 3);
  g.options.augment.views = 8;
  g.options.augment.sensor.random_pose = true;
  g.options.augment.seed = 5;
  // Samples with 1, 3 and 9 views of 12 floats.
  for (size_t i = 0; i < g.samples.size(); ++i) {
    const size_t views = i % 3 == 0 ? 1 : i % 3 == 1 ? 3 : 9;
    std::vector<float>& f = g.samples[i].features;
    for (size_t v = 1; v < views; ++v) {
      for (int j = 0; j < 12; ++j) f.push_back(static_cast<float>(i * 100 + v * 10 + j));
    }
  }
  {
    auto store = OpenStore(dir);
    ASSERT_TRUE(store->LoadAll().ok());
    ASSERT_TRUE(store->SaveGallery(g).ok());
  }
  auto store = OpenStore(dir);
  auto loaded = store->LoadAll();
  ASSERT_TRUE(loaded.ok()) << loaded.status();
  ASSERT_EQ(loaded->size(), 1u);
  ExpectSameStoredGallery((*loaded)[0], g);
  EXPECT_EQ(AugmentOptionsToString((*loaded)[0].options.augment),
            "views=8,noise=0.01,points=300-500,pose=random,seed=5");
}

TEST(SqliteGalleryStoreTest, FormatOneGalleriesLoadAndKeepAcceptingSamples) {
  // A format-1 file: today's schema without the augment column, user_version 1.
  const std::string dir = ScratchDir("data");
  StoredGallery g = MakeGallery("old", 6, 4, 8);
  {
    auto store = OpenStore(dir);
    ASSERT_TRUE(store->LoadAll().ok());
    ASSERT_TRUE(store->SaveGallery(g).ok());
  }
  {
    auto db = SqliteDb::Open(dir + "/galleries/old.gallery", SqliteDb::Mode::kReadWrite);
    ASSERT_TRUE(db.ok());
    ASSERT_TRUE((*db)->Exec("ALTER TABLE gallery DROP COLUMN augment; PRAGMA user_version=1").ok());
  }
  StoredGallery more = MakeGallery("old", 6, 2, 9);
  for (StoredSample& sample : more.samples) sample.id += 1000;
  {
    auto store = OpenStore(dir);
    auto loaded = store->LoadAll();
    ASSERT_TRUE(loaded.ok()) << loaded.status();
    ASSERT_EQ(loaded->size(), 1u);
    ExpectSameStoredGallery((*loaded)[0], g);
    EXPECT_FALSE((*loaded)[0].options.augment.enabled());
    g.updated += absl::Seconds(1);
    ASSERT_TRUE(store->AppendSamples("old", more.samples, g.updated, 0).ok());
    g.samples.insert(g.samples.end(), more.samples.begin(), more.samples.end());
  }
  auto store = OpenStore(dir);
  auto loaded = store->LoadAll();
  ASSERT_TRUE(loaded.ok()) << loaded.status();
  ExpectSameStoredGallery((*loaded)[0], g);
}

TEST(SqliteGalleryStoreTest, SetAsideMovesTheDamagedGalleryAndLoadsTheRest) {
  StoredGallery bad;
  const std::string dir = StoreWithTwoGalleries(&bad);
  ASSERT_EQ(truncate((dir + "/galleries/bad.gallery").c_str(), 2000), 0);
  auto store = OpenStore(dir, /*set_aside=*/true);
  auto loaded = store->LoadAll();
  ASSERT_TRUE(loaded.ok()) << loaded.status();
  ASSERT_EQ(loaded->size(), 1u);
  EXPECT_EQ((*loaded)[0].name, "good");
  const auto aside = store->set_aside();
  ASSERT_EQ(aside.size(), 1u);
  EXPECT_EQ(aside[0].name, "bad");
  EXPECT_THAT(aside[0].moved_to, HasSubstr(dir + "/damaged/bad."));
  EXPECT_TRUE(FileExists(aside[0].moved_to));
  EXPECT_FALSE(FileExists(dir + "/galleries/bad.gallery"));
  // The name is free again, and the new gallery does not inherit anything.
  ASSERT_TRUE(store->SaveGallery(MakeGallery("bad", 4, 2, 8)).ok());
  store.reset();
  auto reopened = OpenStore(dir);
  auto again = reopened->LoadAll();
  ASSERT_TRUE(again.ok()) << again.status();
  ASSERT_EQ(again->size(), 2u);
  ExpectSameStoredGallery((*again)[0], MakeGallery("bad", 4, 2, 8));
}

// A small tmpfs the test mounts, to fill or make read-only. Skips (saying why) where the
// machine forbids mounting.
class MountedStoreTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = ScratchDir("mnt");
    ASSERT_TRUE(MakeDirectories(dir_).ok());
    if (mount("tmpfs", dir_.c_str(), "tmpfs", 0, "size=1m") != 0) {
      GTEST_SKIP() << "cannot mount a tmpfs here (" << std::strerror(errno)
                   << "); the full and read-only disk cases need it";
    }
    mounted_ = true;
  }
  void TearDown() override {
    store_.reset();
    if (mounted_) umount2(dir_.c_str(), MNT_DETACH);
  }

  std::string dir_;
  bool mounted_ = false;
  std::unique_ptr<SqliteGalleryStore> store_;
};

TEST_F(MountedStoreTest, FullDiskFailsWritesCleanlyAndLosesNothing) {
  store_ = OpenStore(dir_);
  ASSERT_TRUE(store_->LoadAll().ok());
  const StoredGallery g = MakeGallery("g", 81, 50, 1);
  ASSERT_TRUE(store_->SaveGallery(g).ok());
  // Fill the file system.
  {
    std::ofstream filler(dir_ + "/filler", std::ios::binary);
    const std::string block(64 * 1024, 'x');
    for (int i = 0; i < 64 && filler; ++i) filler.write(block.data(), block.size());
  }
  StoredGallery more = MakeGallery("g", 81, 400, 2);
  for (StoredSample& s : more.samples) s.id += 100000;
  const absl::Status append = store_->AppendSamples("g", more.samples, absl::Now(), 0);
  EXPECT_EQ(append.code(), absl::StatusCode::kResourceExhausted) << append;
  EXPECT_THAT(append.message(), AllOf(HasSubstr("gallery 'g'"), HasSubstr("full")));
  const absl::Status create = store_->SaveGallery(MakeGallery("h", 81, 400, 3));
  EXPECT_EQ(create.code(), absl::StatusCode::kResourceExhausted) << create;
  EXPECT_FALSE(FileExists(store_->GalleryPath("h")));

  // After space is freed, writes work again and nothing stored was lost.
  ASSERT_TRUE(RemoveFileIfExists(dir_ + "/filler").ok());
  more.samples.resize(5);
  ASSERT_TRUE(store_->AppendSamples("g", more.samples, g.updated, 0).ok());
  store_.reset();
  store_ = OpenStore(dir_);
  auto loaded = store_->LoadAll();
  ASSERT_TRUE(loaded.ok()) << loaded.status();
  ASSERT_EQ(loaded->size(), 1u);
  StoredGallery expected = g;
  expected.samples.insert(expected.samples.end(), more.samples.begin(), more.samples.end());
  ExpectSameStoredGallery((*loaded)[0], expected);
}

TEST_F(MountedStoreTest, ReadOnlyDiskServesAndFailsWritesAsUnavailable) {
  store_ = OpenStore(dir_);
  ASSERT_TRUE(store_->LoadAll().ok());
  const StoredGallery g = MakeGallery("g", 8, 5, 1);
  ASSERT_TRUE(store_->SaveGallery(g).ok());
  store_.reset();
  // Linux refuses to remount read-only while files are open for writing, so the store is
  // closed first: the case of a volume mounted read-only (a classify-only replica).
  ASSERT_EQ(mount(nullptr, dir_.c_str(), nullptr, MS_REMOUNT | MS_RDONLY, nullptr), 0)
      << std::strerror(errno);
  store_ = OpenStore(dir_);
  ASSERT_NE(store_, nullptr);
  EXPECT_TRUE(store_->read_only());
  // Read-only servers share the directory.
  auto second = SqliteGalleryStore::Open({dir_, false});
  EXPECT_TRUE(second.ok()) << second.status();
  auto loaded = store_->LoadAll();
  ASSERT_TRUE(loaded.ok()) << loaded.status();
  ASSERT_EQ(loaded->size(), 1u);
  ExpectSameStoredGallery((*loaded)[0], g);

  StoredGallery more = MakeGallery("g", 8, 2, 2);
  for (StoredSample& s : more.samples) s.id += 100;
  const absl::Status append = store_->AppendSamples("g", more.samples, absl::Now(), 0);
  EXPECT_EQ(append.code(), absl::StatusCode::kUnavailable) << append;
  EXPECT_THAT(append.message(), AllOf(HasSubstr("gallery 'g'"), HasSubstr("read-only")));
  EXPECT_EQ(store_->SaveGallery(MakeGallery("h", 8, 1, 3)).code(), absl::StatusCode::kUnavailable);
  EXPECT_EQ(store_->RemoveSamples("g", {g.samples[0].id}, absl::Now(), 0).code(),
            absl::StatusCode::kUnavailable);
  EXPECT_EQ(store_->DeleteGallery("g").code(), absl::StatusCode::kUnavailable);
}

}  // namespace
}  // namespace shapeid
