#include "server/storage/sqlite_gallery_store.h"

#include <fcntl.h>
#include <sys/mount.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "core/gallery/gallery_registry.h"
#include "core/gallery/gallery_store_testing.h"
#include "core/views/augment.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "server/storage/file_util.h"
#include "server/storage/testing/fault_vfs.h"

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

// Bytes of a file; -1 if it does not exist.
long FileSize(const std::string& path) {
  struct stat st;
  return stat(path.c_str(), &st) == 0 ? static_cast<long>(st.st_size) : -1;
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
  // A format-1 file: today's schema without the augment column, user_version 1 (and no
  // provenance, which format 1 cannot hold).
  const std::string dir = ScratchDir("data");
  StoredGallery g = MakeGallery("old", 6, 4, 8);
  for (StoredSample& sample : g.samples) sample.provenance = {};
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
  for (StoredSample& sample : more.samples) {
    sample.id += 1000;
    sample.provenance = {};
  }
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

// Gallery files an earlier shapeid wrote (server/testdata/README.md) load with every field
// as written, and take changes, whose gallery-row checksum covers the metadata.
TEST(SqliteGalleryStoreTest, FilesAnEarlierReleaseWroteLoadAndTakeChanges) {
  const std::string dir = ScratchDir("data");
  std::filesystem::create_directories(dir + "/galleries");
  for (const char* name : {"old-plain.gallery", "old-augmented.gallery"}) {
    std::filesystem::copy_file(absl::StrCat(SHAPEID_SOURCE_DIR, "/server/testdata/", name),
                               absl::StrCat(dir, "/galleries/", name));
  }
  StoredGallery plain, augmented;
  {
    auto store = OpenStore(dir);
    auto loaded = store->LoadAll();
    ASSERT_TRUE(loaded.ok()) << loaded.status();
    ASSERT_EQ(loaded->size(), 2u);
    augmented = (*loaded)[0];  // sorted by name
    plain = (*loaded)[1];
    for (const StoredGallery* g : {&plain, &augmented}) {
      EXPECT_EQ(g->options.descriptor_spec, "rphsd:refs=cross7,bins=10,variant=reduced");
      EXPECT_EQ(g->dimension, 6);
      EXPECT_EQ(g->descriptor_version, 1u);
      EXPECT_EQ(g->software_version, "0.1.0");
      EXPECT_EQ(g->version, 0u);  // not kept by this store
      EXPECT_EQ(g->incarnation, 0u);
    }
    EXPECT_EQ(plain.name, "old-plain");
    EXPECT_EQ(plain.options.knn.k, 1);
    EXPECT_EQ(plain.options.knn.weighting, VoteWeighting::kUniform);
    EXPECT_EQ(plain.options.knn.scaling, FeatureScaling::kNone);
    EXPECT_EQ(plain.options.reject_distance, 0.0);
    EXPECT_FALSE(plain.options.augment.enabled());
    EXPECT_EQ(absl::ToUnixNanos(plain.created), 1795814593051200696);
    EXPECT_EQ(absl::ToUnixNanos(plain.updated), 1795814595303907810);
    std::vector<uint64_t> ids;
    std::vector<std::string> labels;
    for (const StoredSample& sample : plain.samples) {
      ids.push_back(sample.id);
      labels.push_back(sample.label);
      EXPECT_EQ(sample.features.size(), 6u);
    }
    EXPECT_THAT(ids, ElementsAre(628998521628552669u, 3294616212707828169u, 2572415798631930683u,
                                 425726189010600143u, 1957968127058381579u, 2813021720837754697u));
    EXPECT_THAT(labels, ElementsAre("box", "box", "sphere", "sphere", "rod", "rod"));

    EXPECT_EQ(augmented.name, "old-augmented");
    EXPECT_EQ(augmented.options.knn.k, 3);
    EXPECT_EQ(augmented.options.knn.weighting, VoteWeighting::kDistance);
    EXPECT_EQ(augmented.options.knn.scaling, FeatureScaling::kZScore);
    EXPECT_EQ(augmented.options.reject_distance, 0.75);
    EXPECT_EQ(AugmentOptionsToString(augmented.options.augment),
              "views=2,noise=0.01,points=300-500,pose=fixed,seed=1");
    EXPECT_EQ(absl::ToUnixNanos(augmented.created), 1795814593221890089);
    EXPECT_EQ(absl::ToUnixNanos(augmented.updated), 1795814601502715857);
    ids.clear();
    for (const StoredSample& sample : augmented.samples) {
      ids.push_back(sample.id);
      EXPECT_EQ(sample.features.size(), 18u);  // 3 views
    }
    EXPECT_THAT(ids, ElementsAre(2738972862237451795u, 386655976738752047u, 74914986951301631u,
                                 3672237284517391487u));

    StoredSample extra = plain.samples[0];
    extra.id = 7;
    plain.updated += absl::Seconds(1);
    ASSERT_TRUE(store->AppendSamples("old-plain", {extra}, plain.updated, 1).ok());
    plain.samples.push_back(extra);
    augmented.updated += absl::Seconds(2);
    ASSERT_TRUE(
        store->RemoveSamples("old-augmented", {augmented.samples[1].id}, augmented.updated, 1)
            .ok());
    augmented.samples.erase(augmented.samples.begin() + 1);
  }
  auto store = OpenStore(dir);
  auto loaded = store->LoadAll();
  ASSERT_TRUE(loaded.ok()) << loaded.status();
  ASSERT_EQ(loaded->size(), 2u);
  ExpectSameStoredGallery((*loaded)[0], augmented);
  ExpectSameStoredGallery((*loaded)[1], plain);
}

// The user_version of a gallery file, read without the store.
int64_t FileFormat(const std::string& path) {
  auto db = SqliteDb::Open(path, SqliteDb::Mode::kReadWrite);
  EXPECT_TRUE(db.ok()) << db.status();
  if (!db.ok()) return -1;
  auto format = (*db)->QueryInt("PRAGMA user_version");
  EXPECT_TRUE(format.ok()) << format.status();
  return format.ok() ? *format : -1;
}

// An earlier release's file keeps its format while samples without provenance arrive, and
// gains the provenance column (format 3) with the first sample that has some; everything in
// it reads back.
TEST(SqliteGalleryStoreTest, EarlierFilesGainTheProvenanceColumnOnlyWhenNeeded) {
  const std::string dir = ScratchDir("data");
  const std::string path = dir + "/galleries/old-plain.gallery";
  std::filesystem::create_directories(dir + "/galleries");
  std::filesystem::copy_file(absl::StrCat(SHAPEID_SOURCE_DIR, "/server/testdata/old-plain.gallery"),
                             path);
  ASSERT_EQ(FileFormat(path), 2);
  StoredGallery g;
  {
    auto store = OpenStore(dir);
    auto loaded = store->LoadAll();
    ASSERT_TRUE(loaded.ok()) << loaded.status();
    g = (*loaded)[0];
    StoredSample plain = g.samples[0];
    plain.id = 7;
    g.updated += absl::Seconds(1);
    ASSERT_TRUE(store->AppendSamples(g.name, {plain}, g.updated, 1).ok());
    g.samples.push_back(plain);
  }
  EXPECT_EQ(FileFormat(path), 2);
  {
    auto store = OpenStore(dir);
    ASSERT_TRUE(store->LoadAll().ok());
    StoredSample traced = g.samples[0];
    traced.id = 8;
    traced.provenance = {"lab/box_0008.pcd", {{"camera", "d435"}, {"note", ""}}};
    g.updated += absl::Seconds(1);
    ASSERT_TRUE(store->AppendSamples(g.name, {traced}, g.updated, 2).ok());
    g.samples.push_back(traced);
    // The same open store goes on writing into the upgraded file.
    StoredSample second = traced;
    second.id = 9;
    second.provenance.source = "lab/box_0009.pcd";
    g.updated += absl::Seconds(1);
    ASSERT_TRUE(store->AppendSamples(g.name, {second}, g.updated, 3).ok());
    g.samples.push_back(second);
  }
  EXPECT_EQ(FileFormat(path), 3);
  auto store = OpenStore(dir);
  auto loaded = store->LoadAll();
  ASSERT_TRUE(loaded.ok()) << loaded.status();
  ExpectSameStoredGallery((*loaded)[0], g);
  EXPECT_EQ((*loaded)[0].samples.back().provenance.source, "lab/box_0009.pcd");
}

TEST(SqliteGalleryStoreTest, DamagedProvenanceIsDamage) {
  const std::string dir = ScratchDir("data");
  {
    auto store = OpenStore(dir);
    ASSERT_TRUE(store->LoadAll().ok());
    ASSERT_TRUE(store->SaveGallery(MakeGallery("g", 4, 6, 1)).ok());
  }
  {
    auto db = SqliteDb::Open(dir + "/galleries/g.gallery", SqliteDb::Mode::kReadWrite);
    ASSERT_TRUE(db.ok());
    // One byte of the first sample's source changed: its CRC no longer matches.
    ASSERT_TRUE((*db)
                    ->Exec("UPDATE samples SET provenance = "
                           "substr(provenance, 1, 6) || X'41' || substr(provenance, 8) "
                           "WHERE seq = 1")
                    .ok());
  }
  auto store = OpenStore(dir);
  auto loaded = store->LoadAll();
  EXPECT_EQ(loaded.status().code(), absl::StatusCode::kDataLoss);
  EXPECT_THAT(loaded.status().message(),
              AllOf(HasSubstr("is damaged"), HasSubstr("sample id 1 (row 1)"),
                    HasSubstr("sample provenance: checksum mismatch")));
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

// Records what Load hands over; fails with `fail` at sample `fail_at` (counted from 1 over the
// whole load) when that is set.
class RecordingLoader final : public GalleryLoader {
 public:
  absl::Status Begin(const GalleryMetadata& gallery) override {
    events.push_back(absl::StrCat("begin ", gallery.name));
    return absl::OkStatus();
  }
  absl::Status Add(StoredSample& sample) override {
    if (++added == fail_at) return fail;
    addresses[events.back()].insert(&sample);
    ++samples_since_begin[events.back()];
    return absl::OkStatus();
  }
  absl::Status End() override {
    events.push_back("end");
    return absl::OkStatus();
  }
  absl::Status Head(absl::string_view bytes) override {
    events.push_back(absl::StrCat("head ", bytes));
    return absl::OkStatus();
  }

  std::vector<std::string> events;
  std::map<std::string, int> samples_since_begin;
  std::map<std::string, std::set<const StoredSample*>> addresses;  // by gallery
  int added = 0;
  int fail_at = 0;
  absl::Status fail;
};

TEST(SqliteGalleryStoreTest, LoadHandsOverASampleAtATimeAndDropsAGalleryDamagedPartway) {
  StoredGallery bad;
  const std::string dir = StoreWithTwoGalleries(&bad);
  const std::string path = dir + "/galleries/bad.gallery";
  const float* f = bad.samples[17].features.data();
  const long at = Find(path, std::string(reinterpret_cast<const char*>(f), 16 * sizeof(float)));
  ASSERT_GE(at, 0);
  Overwrite(path, at, std::string(4, '\x7f'));
  auto store = OpenStore(dir, /*set_aside=*/true);
  RecordingLoader loader;
  ASSERT_TRUE(store->Load(loader).ok());
  // "bad" is begun and handed its first 17 samples, then set aside, never ended.
  EXPECT_THAT(loader.events, ElementsAre("begin bad", "begin good", "end"));
  EXPECT_EQ(loader.samples_since_begin["begin bad"], 17);
  EXPECT_EQ(loader.samples_since_begin["begin good"], 30);
  // One sample per gallery, refilled for every row (each gallery's may lie elsewhere: under
  // AddressSanitizer a function's locals move between calls).
  EXPECT_EQ(loader.addresses["begin bad"].size(), 1u);
  EXPECT_EQ(loader.addresses["begin good"].size(), 1u);
  ASSERT_EQ(store->set_aside().size(), 1u);
  EXPECT_EQ(store->set_aside()[0].name, "bad");
}

TEST(SqliteGalleryStoreTest, AKeptHeadComesBackAfterItsGalleryAndGoesWithIt) {
  const std::string dir = ScratchDir("data");
  {
    auto store = OpenStore(dir);
    ASSERT_TRUE(store->LoadAll().ok());
    ASSERT_TRUE(store->SaveGallery(MakeGallery("a", 4, 2, 1)).ok());
    ASSERT_TRUE(store->SaveGallery(MakeGallery("b", 4, 2, 2)).ok());
    ASSERT_TRUE(store->SaveHead("a", "first").ok());
    ASSERT_TRUE(store->SaveHead("a", "second").ok());  // replaces the first
    EXPECT_EQ(store->SaveHead("none", "x").code(), absl::StatusCode::kInternal);
  }
  // What a crash while writing a head leaves behind: removed at the next start.
  std::ofstream(dir + "/galleries/b.head.tmp") << "partial";
  {
    auto store = OpenStore(dir);
    RecordingLoader loader;
    ASSERT_TRUE(store->Load(loader).ok());
    EXPECT_THAT(loader.events, ElementsAre("begin a", "end", "head second", "begin b", "end"));
    EXPECT_FALSE(FileExists(dir + "/galleries/b.head.tmp"));
    ASSERT_TRUE(store->DeleteGallery("a").ok());
    EXPECT_FALSE(FileExists(store->HeadPath("a")));
  }
  auto store = OpenStore(dir);
  RecordingLoader loader;
  ASSERT_TRUE(store->Load(loader).ok());
  EXPECT_THAT(loader.events, ElementsAre("begin b", "end"));
}

TEST(SqliteGalleryStoreTest, ALoadersErrorEndsTheLoadAsItIsAndSetsNothingAside) {
  StoredGallery bad;
  const std::string dir = StoreWithTwoGalleries(&bad);
  for (const absl::Status& fail :
       {absl::InvalidArgumentError("restoring: a bad label"), absl::DataLossError("id 0")}) {
    auto store = OpenStore(dir, /*set_aside=*/true);
    RecordingLoader loader;
    loader.fail_at = 40;  // in "good"
    loader.fail = fail;
    EXPECT_EQ(store->Load(loader), fail);
    EXPECT_THAT(store->set_aside(), IsEmpty());
    EXPECT_TRUE(FileExists(dir + "/galleries/bad.gallery"));
    EXPECT_TRUE(FileExists(dir + "/galleries/good.gallery"));
  }
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

// Fills the file system holding `dir` to the last byte.
void FillUp(const std::string& dir) {
  const int fd = open((dir + "/filler").c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  ASSERT_GE(fd, 0);
  const std::string block(4096, 'x');
  while (write(fd, block.data(), block.size()) > 0) {
  }
  while (write(fd, "x", 1) > 0) {
  }
  close(fd);
}

// A real full disk (where the test may mount): the healthy gallery loads read-only, its
// writes fail ResourceExhausted, and freeing space heals it without a restart.
TEST_F(MountedStoreTest, RestartOnAFullDiskServesReadOnlyUntilSpaceIsFreed) {
  store_ = OpenStore(dir_, /*set_aside=*/true);
  ASSERT_TRUE(store_->LoadAll().ok());
  StoredGallery g = MakeGallery("g", 81, 50, 1);
  ASSERT_TRUE(store_->SaveGallery(g).ok());
  store_.reset();
  FillUp(dir_);
  store_ = OpenStore(dir_, /*set_aside=*/true);
  auto loaded = store_->LoadAll();
  ASSERT_TRUE(loaded.ok()) << loaded.status();
  ASSERT_EQ(loaded->size(), 1u);
  ExpectSameStoredGallery((*loaded)[0], g);
  EXPECT_FALSE(FileExists(dir_ + "/damaged"));
  const auto read_only = store_->read_only_galleries();
  ASSERT_EQ(read_only.size(), 1u);
  EXPECT_EQ(read_only[0].reason.code(), absl::StatusCode::kResourceExhausted)
      << read_only[0].reason;
  StoredGallery more = MakeGallery("g", 81, 2, 2);
  for (StoredSample& s : more.samples) s.id += 1000;
  const absl::Status append = store_->AppendSamples("g", more.samples, g.updated, 0);
  EXPECT_EQ(append.code(), absl::StatusCode::kResourceExhausted) << append;

  ASSERT_TRUE(RemoveFileIfExists(dir_ + "/filler").ok());
  ASSERT_TRUE(store_->AppendSamples("g", more.samples, g.updated, 0).ok());
  EXPECT_THAT(store_->read_only_galleries(), IsEmpty());
  store_.reset();
  store_ = OpenStore(dir_);
  loaded = store_->LoadAll();
  ASSERT_TRUE(loaded.ok()) << loaded.status();
  g.samples.insert(g.samples.end(), more.samples.begin(), more.samples.end());
  ExpectSameStoredGallery((*loaded)[0], g);
}

// A real read-only volume holding changes still in a -wal (a server that lost power, then
// the volume was mounted read-only): they are served, not lost.
TEST_F(MountedStoreTest, ReadOnlyVolumeServesChangesStillInTheWal) {
  const std::string live = ScratchDir("live");
  StoredGallery g = MakeGallery("g", 8, 5, 1);
  {
    auto store = OpenStore(live);
    ASSERT_TRUE(store->LoadAll().ok());
    ASSERT_TRUE(store->SaveGallery(g).ok());
    StoredGallery more = MakeGallery("g", 8, 2, 2);
    for (StoredSample& s : more.samples) s.id += 1000;
    g.updated += absl::Seconds(1);
    ASSERT_TRUE(store->AppendSamples("g", more.samples, g.updated, 0).ok());
    g.samples.insert(g.samples.end(), more.samples.begin(), more.samples.end());
    ASSERT_TRUE(MakeDirectories(dir_ + "/galleries").ok());
    ASSERT_EQ(std::system(absl::StrCat("cp ", live, "/galleries/g.gallery ", live,
                                       "/galleries/g.gallery-wal ", dir_, "/galleries/")
                              .c_str()),
              0);
  }
  ASSERT_GT(FileSize(dir_ + "/galleries/g.gallery-wal"), 0);
  ASSERT_EQ(mount(nullptr, dir_.c_str(), nullptr, MS_REMOUNT | MS_RDONLY, nullptr), 0)
      << std::strerror(errno);
  store_ = OpenStore(dir_);
  ASSERT_TRUE(store_->read_only());
  auto loaded = store_->LoadAll();
  ASSERT_TRUE(loaded.ok()) << loaded.status();
  ASSERT_EQ(loaded->size(), 1u);
  ExpectSameStoredGallery((*loaded)[0], g);
}

// ---------------------------------------------------------------------------------------
// Disk faults at start-up are not damage. Injected through a SQLite VFS
// (testing/fault_vfs.h), since CI runs as root (file modes do not stop it) and cannot mount.

class DiskFaultTest : public ::testing::Test {
 protected:
  // A store on `dir` whose gallery files go through the faulty VFS.
  std::shared_ptr<SqliteGalleryStore> OpenFaulty(const std::string& dir, bool set_aside = true) {
    SqliteGalleryStoreOptions options;
    options.data_dir = dir;
    options.set_aside_damaged = set_aside;
    options.testing_vfs = vfs_.name();
    auto store = SqliteGalleryStore::Open(options);
    EXPECT_TRUE(store.ok()) << store.status();
    return store.ok() ? std::shared_ptr<SqliteGalleryStore>(*std::move(store)) : nullptr;
  }

  // A data directory holding `galleries`, written on a healthy disk and closed.
  std::string Written(absl::string_view what, const std::vector<StoredGallery>& galleries) {
    const std::string dir = ScratchDir(what);
    auto store = OpenStore(dir);
    EXPECT_TRUE(store->LoadAll().ok());
    for (const StoredGallery& g : galleries) EXPECT_TRUE(store->SaveGallery(g).ok());
    return dir;
  }

  // The sample nearest to `features` in gallery `name` once a registry has loaded `store`,
  // as the server loads it.
  static uint64_t Nearest(const std::shared_ptr<SqliteGalleryStore>& store, const std::string& name,
                          const std::vector<float>& features) {
    GalleryRegistry registry({}, store);
    const absl::Status load = registry.LoadFromStore();
    EXPECT_TRUE(load.ok()) << load;
    auto gallery = registry.Get(name);
    EXPECT_TRUE(gallery.ok()) << gallery.status();
    if (!gallery.ok()) return 0;
    auto answer = (*gallery)->Snapshot()->ClassifyFeatures(features);
    EXPECT_TRUE(answer.ok()) << answer.status();
    return answer.ok() && !answer->knn.neighbors.empty() ? answer->knn.neighbors[0].id : 0;
  }

  FaultVfs vfs_{"shapeid_fault"};  // declared first: outlives every store of the test
};

// MakeGallery without the extreme bit patterns of its first sample, which a gallery refuses
// to serve.
StoredGallery Servable(std::string name, int samples, uint32_t seed) {
  StoredGallery g = MakeGallery(std::move(name), 81, samples, seed);
  std::fill(g.samples[0].features.begin(), g.samples[0].features.end(), 0.5f);
  return g;
}

TEST_F(DiskFaultTest, RestartOnAFullDiskServesHealthyGalleriesReadOnlyAndMovesNothing) {
  const StoredGallery a = Servable("a", 20, 1);
  const StoredGallery b = Servable("b", 5, 2);
  // A full disk refuses new files (no free inode or directory block), or only new blocks:
  // SQLite then creates the -shm but cannot size it.
  for (const bool files_too : {true, false}) {
    SCOPED_TRACE(files_too ? "no new files" : "no new blocks");
    const std::string dir = Written(files_too ? "files" : "blocks", {a, b});
    FaultVfs::Faults full = FaultVfs::DiskFull();
    full.fail_create = files_too;
    vfs_.Set(full);
    const int before = vfs_.injected();
    auto store = OpenFaulty(dir, /*set_aside=*/true);
    auto loaded = store->LoadAll();
    ASSERT_TRUE(loaded.ok()) << loaded.status();
    EXPECT_GT(vfs_.injected(), before);
    ASSERT_EQ(loaded->size(), 2u);
    ExpectSameStoredGallery((*loaded)[0], a);
    ExpectSameStoredGallery((*loaded)[1], b);
    EXPECT_THAT(store->set_aside(), IsEmpty());
    EXPECT_FALSE(FileExists(dir + "/damaged"));
    const auto read_only = store->read_only_galleries();
    ASSERT_EQ(read_only.size(), 2u);
    EXPECT_EQ(read_only[0].name, "a");
    EXPECT_EQ(read_only[0].reason.code(), absl::StatusCode::kResourceExhausted)
        << read_only[0].reason;
    EXPECT_THAT(read_only[0].reason.message(), HasSubstr("full"));
    EXPECT_EQ(read_only[1].name, "b");
    store.reset();
    // And the server's path: the registry loads it and it classifies.
    EXPECT_EQ(Nearest(OpenFaulty(dir), "a", a.samples[7].features), a.samples[7].id);
  }
}

TEST_F(DiskFaultTest, IoErrorsOpeningAGalleryAreNotDamage) {
  const StoredGallery a = MakeGallery("a", 8, 6, 1);
  const StoredGallery b = MakeGallery("b", 8, 6, 2);
  const std::string dir = Written("data", {a, b});
  {
    // SQLite cannot set up its shared memory for 'a': reading it needs none.
    FaultVfs::Faults shm;
    shm.shm_error = SQLITE_IOERR_SHMOPEN;
    shm.error = EIO;
    shm.path_contains = "/a.gallery";
    vfs_.Set(shm);
    auto store = OpenFaulty(dir, /*set_aside=*/true);
    auto loaded = store->LoadAll();
    ASSERT_TRUE(loaded.ok()) << loaded.status();
    ASSERT_EQ(loaded->size(), 2u);
    ExpectSameStoredGallery((*loaded)[0], a);
    const auto read_only = store->read_only_galleries();
    ASSERT_EQ(read_only.size(), 1u);
    EXPECT_EQ(read_only[0].name, "a");
    EXPECT_EQ(read_only[0].reason.code(), absl::StatusCode::kUnavailable) << read_only[0].reason;
    EXPECT_THAT(read_only[0].reason.message(), HasSubstr("Input/output error"));
    EXPECT_THAT(store->set_aside(), IsEmpty());
  }
  // Not even readable (a bad sector under the file): start-up fails saying it is the disk,
  // and moves nothing, although set_aside_damaged is on.
  FaultVfs::Faults unreadable;
  unreadable.read_error = SQLITE_IOERR_READ;
  unreadable.error = EIO;
  unreadable.path_contains = "/a.gallery";
  vfs_.Set(unreadable);
  auto store = OpenFaulty(dir, /*set_aside=*/true);
  auto loaded = store->LoadAll();
  EXPECT_EQ(loaded.status().code(), absl::StatusCode::kUnavailable) << loaded.status();
  EXPECT_THAT(loaded.status().message(),
              AllOf(HasSubstr("cannot load gallery 'a'"), HasSubstr(dir + "/galleries/a.gallery"),
                    HasSubstr("not damage"), HasSubstr("nothing was moved"),
                    HasSubstr("Input/output error")));
  EXPECT_TRUE(FileExists(dir + "/galleries/a.gallery"));
  EXPECT_FALSE(FileExists(dir + "/damaged"));
}

TEST_F(DiskFaultTest, ProvenDamageIsStillSetAsideOnAHealthyOrAFullDisk) {
  const StoredGallery bad = MakeGallery("bad", 16, 30, 3);
  for (const bool full : {false, true}) {
    SCOPED_TRACE(full ? "full disk" : "healthy disk");
    const std::string dir =
        Written(full ? "full" : "healthy", {MakeGallery("good", 16, 4, 4), bad});
    // A flipped bit in a label: SQLite's structure is intact, the row's CRC-32 is not.
    const std::string path = dir + "/galleries/bad.gallery";
    const long at = Find(path, bad.samples[11].label);
    ASSERT_GE(at, 0);
    Overwrite(path, at, "C");
    vfs_.Set(full ? FaultVfs::DiskFull() : FaultVfs::Faults{});
    auto store = OpenFaulty(dir, /*set_aside=*/true);
    auto loaded = store->LoadAll();
    ASSERT_TRUE(loaded.ok()) << loaded.status();
    ASSERT_EQ(loaded->size(), 1u);
    EXPECT_EQ((*loaded)[0].name, "good");
    const auto aside = store->set_aside();
    ASSERT_EQ(aside.size(), 1u);
    EXPECT_EQ(aside[0].name, "bad");
    EXPECT_THAT(aside[0].reason, HasSubstr("checksum mismatch"));
    EXPECT_TRUE(FileExists(aside[0].moved_to));
    EXPECT_FALSE(FileExists(path));
  }
}

TEST_F(DiskFaultTest, ACommitStillInTheWalIsServedAfterARestartOnAFullDisk) {
  StoredGallery g = MakeGallery("g", 8, 10, 1);
  const std::string dir = ScratchDir("live");
  const std::string crashed = ScratchDir("crashed");
  {
    auto store = OpenStore(dir);
    ASSERT_TRUE(store->LoadAll().ok());
    ASSERT_TRUE(store->SaveGallery(g).ok());  // checkpointed into the main file
    StoredGallery more = MakeGallery("g", 8, 3, 2);
    for (StoredSample& s : more.samples) s.id += 1000;
    g.updated += absl::Seconds(1);
    ASSERT_TRUE(store->AppendSamples("g", more.samples, g.updated, 0).ok());  // in the -wal
    g.samples.insert(g.samples.end(), more.samples.begin(), more.samples.end());
    g.updated += absl::Seconds(1);
    ASSERT_TRUE(store->RemoveSamples("g", {g.samples[2].id}, g.updated, 0).ok());
    g.samples.erase(g.samples.begin() + 2);
    // What a power cut leaves: the main file and the -wal as they are now (the -shm is
    // rebuilt from the -wal, so it is not kept).
    ASSERT_TRUE(MakeDirectories(crashed + "/galleries").ok());
    for (const char* file : {"g.gallery", "g.gallery-wal"}) {
      ASSERT_EQ(
          std::system(
              absl::StrCat("cp ", dir, "/galleries/", file, " ", crashed, "/galleries/").c_str()),
          0);
    }
  }
  const std::string wal = crashed + "/galleries/g.gallery-wal";
  const long wal_size = FileSize(wal);
  ASSERT_GT(wal_size, 0);
  vfs_.Set(FaultVfs::DiskFull());
  auto store = OpenFaulty(crashed, /*set_aside=*/true);
  auto loaded = store->LoadAll();
  ASSERT_TRUE(loaded.ok()) << loaded.status();
  ASSERT_EQ(loaded->size(), 1u);
  ExpectSameStoredGallery((*loaded)[0], g);
  ASSERT_EQ(store->read_only_galleries().size(), 1u);
  // Read without touching anything: no -shm, the -wal as it was.
  EXPECT_EQ(FileSize(crashed + "/galleries/g.gallery-shm"), -1);
  EXPECT_EQ(FileSize(wal), wal_size);

  // Space freed: the next write reopens the gallery and goes through, without a restart.
  vfs_.Set({});
  StoredGallery later = MakeGallery("g", 8, 1, 3);
  later.samples[0].id = 5000;
  g.updated += absl::Seconds(1);
  ASSERT_TRUE(store->AppendSamples("g", later.samples, g.updated, 0).ok());
  g.samples.push_back(later.samples[0]);
  EXPECT_THAT(store->read_only_galleries(), IsEmpty());
  store.reset();
  auto reopened = OpenStore(crashed);
  auto again = reopened->LoadAll();
  ASSERT_TRUE(again.ok()) << again.status();
  ExpectSameStoredGallery((*again)[0], g);
}

TEST_F(DiskFaultTest, WritesToAReadOnlyGalleryFailNamingItAndWhy) {
  StoredGallery a = MakeGallery("a", 8, 6, 1);
  const StoredGallery b = MakeGallery("b", 8, 6, 2);
  const std::string dir = Written("data", {a, b});
  StoredGallery more = MakeGallery("a", 8, 2, 5);
  for (StoredSample& s : more.samples) s.id += 1000;
  {
    FaultVfs::Faults full = FaultVfs::DiskFull();
    full.path_contains = "/a.gallery";  // as if only a's volume were full
    vfs_.Set(full);
    auto store = OpenFaulty(dir);
    ASSERT_TRUE(store->LoadAll().ok());
    const absl::Status append = store->AppendSamples("a", more.samples, absl::Now(), 0);
    EXPECT_EQ(append.code(), absl::StatusCode::kResourceExhausted) << append;
    EXPECT_THAT(append.message(), AllOf(HasSubstr("cannot store 2 samples in gallery 'a'"),
                                        HasSubstr("served read-only"), HasSubstr("disk is full")));
    const absl::Status remove = store->RemoveSamples("a", {a.samples[0].id}, absl::Now(), 0);
    EXPECT_EQ(remove.code(), absl::StatusCode::kResourceExhausted) << remove;
    EXPECT_THAT(remove.message(), HasSubstr("gallery 'a'"));
    // The other gallery goes on as usual.
    StoredGallery for_b = MakeGallery("b", 8, 1, 6);
    for_b.samples[0].id = 7000;
    EXPECT_TRUE(store->AppendSamples("b", for_b.samples, absl::Now(), 0).ok());
  }
  {
    FaultVfs::Faults read_only = FaultVfs::ReadOnlyVolume();
    read_only.path_contains = "/a.gallery";
    vfs_.Set(read_only);
    auto store = OpenFaulty(dir);
    ASSERT_TRUE(store->LoadAll().ok());
    ASSERT_EQ(store->read_only_galleries().size(), 1u);
    EXPECT_EQ(store->read_only_galleries()[0].reason.code(), absl::StatusCode::kUnavailable);
    const absl::Status append = store->AppendSamples("a", more.samples, absl::Now(), 0);
    EXPECT_EQ(append.code(), absl::StatusCode::kUnavailable) << append;
    EXPECT_THAT(append.message(), AllOf(HasSubstr("gallery 'a'"), HasSubstr("served read-only"),
                                        HasSubstr("Read-only file system")));
  }
  // Deleting writes nothing into the file, so it works (and frees the space).
  vfs_.Set(FaultVfs::DiskFull());
  auto store = OpenFaulty(dir);
  ASSERT_TRUE(store->LoadAll().ok());
  EXPECT_TRUE(store->DeleteGallery("a").ok());
  EXPECT_FALSE(FileExists(dir + "/galleries/a.gallery"));
  ASSERT_EQ(store->read_only_galleries().size(), 1u);
  EXPECT_EQ(store->read_only_galleries()[0].name, "b");
}

TEST_F(DiskFaultTest, OurOwnFileOperationsFailingAtStartUp) {
  StoredGallery bad = MakeGallery("bad", 8, 6, 1);
  const std::string dir = Written("data", {MakeGallery("good", 8, 6, 2), bad});
  // Leftovers of a crash that cannot be removed (here: a directory where a file was) are
  // skipped; the galleries are still served.
  ASSERT_TRUE(MakeDirectories(dir + "/galleries/.old.deleted/x").ok());
  ASSERT_TRUE(RemoveFileIfExists(dir + "/galleries/bad.gallery").ok());
  {
    auto store = OpenFaulty(dir);
    auto loaded = store->LoadAll();
    ASSERT_TRUE(loaded.ok()) << loaded.status();
    EXPECT_EQ(loaded->size(), 1u);
  }
  // A damaged gallery that cannot be moved aside (damaged/ cannot be created): start-up
  // fails saying both, and the file stays where it was.
  std::ofstream(dir + "/galleries/bad.gallery") << "not a database";
  std::ofstream(dir + "/damaged") << "a file where the directory should be";
  auto store = OpenFaulty(dir, /*set_aside=*/true);
  auto loaded = store->LoadAll();
  EXPECT_EQ(loaded.status().code(), absl::StatusCode::kUnavailable) << loaded.status();
  EXPECT_THAT(loaded.status().message(),
              AllOf(HasSubstr("cannot set gallery 'bad' aside"), HasSubstr("not a database"),
                    HasSubstr("not a directory")));
  EXPECT_TRUE(FileExists(dir + "/galleries/bad.gallery"));
}

}  // namespace
}  // namespace shapeid
