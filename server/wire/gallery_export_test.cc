// The export stream of a gallery and its assembler: a round trip keeps every bit, chunks stay
// under their byte budget, the CRC is the one the proto defines, and every malformed or
// damaged stream fails with the documented code at the first bad chunk.

#include "server/wire/gallery_export.h"

#include <unistd.h>
#include <zlib.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "core/descriptor_registry.h"
#include "core/gallery/gallery.h"
#include "core/gallery/gallery_registry.h"
#include "core/gallery/gallery_store_testing.h"
#include "core/knn/knn_index.h"
#include "gmock/gmock.h"
#include "google/protobuf/io/zero_copy_stream_impl_lite.h"
#include "google/protobuf/util/delimited_message_util.h"
#include "gtest/gtest.h"
#include "server/storage/sqlite_gallery_store.h"

namespace shapeid {
namespace {

using gallery_testing::ExpectSameStoredGallery;

using ::testing::HasSubstr;

// A gallery with awkward values everywhere a copy could lose them: float bit patterns
// (negative zero, subnormals, the largest a gallery holds), ids above 2^63, multi-byte labels,
// nanosecond times, provenance of every shape.
StoredGallery OddGallery(int num_samples, int dimension = 21) {
  StoredGallery g;
  g.name = "odd.gallery-1";
  g.options.descriptor_spec = "rphsd:refs=cross7,bins=100,variant=complete";
  g.options.knn.k = 5;
  g.options.knn.weighting = VoteWeighting::kDistance;
  g.options.knn.scaling = FeatureScaling::kZScore;
  g.options.reject_distance = 0.125;
  g.created = absl::FromUnixNanos(1'700'000'000'123'456'789);
  g.updated = absl::FromUnixNanos(1'700'000'100'987'654'321);
  g.descriptor_version = FindDescriptorKind("rphsd")->version;
  g.software_version = "0.1.0";
  g.dimension = dimension;
  const float odd[] = {-0.0f, std::numeric_limits<float>::denorm_min(),
                       KnnIndex::kMaxFeatureMagnitude, -1e-38f, 0.1f};
  for (int i = 0; i < num_samples; ++i) {
    StoredSample s;
    s.id = i % 2 == 0 ? static_cast<uint64_t>(i + 1) : kFirstAssignedId + static_cast<uint64_t>(i);
    s.label = i % 3 == 0 ? "t\xC3\xAA"
                           "te"
                         : (i % 3 == 1 ? "box" : "a-long-label-for-a-chair");
    for (int j = 0; j < dimension; ++j)
      s.features.push_back(odd[(i + j) % 5] / static_cast<float>(1 + i));
    // Provenance on some: a source alone, metadata alone, both (multi-byte included).
    if (i % 4 == 1) s.provenance.source = absl::StrCat("/data/scans/", i, ".pcd");
    if (i % 4 == 2)
      s.provenance.metadata = {{"camera", "d435"}, {"op\xC3\xA9rateur", "zo\xC3\xAB"}};
    if (i % 4 == 3) s.provenance = {"s3://bucket/x.ply", {{"k", ""}}};
    g.samples.push_back(std::move(s));
  }
  return g;
}

std::vector<v1::GalleryExportChunk> Export(GalleryExporter& exporter) {
  std::vector<v1::GalleryExportChunk> chunks;
  v1::GalleryExportChunk chunk;
  while (exporter.Next(&chunk)) chunks.push_back(chunk);
  EXPECT_TRUE(exporter.done());
  return chunks;
}

absl::StatusOr<StoredGallery> Assemble(const std::vector<v1::GalleryExportChunk>& chunks,
                                       int64_t max_samples = 1'000'000) {
  GalleryImportAssembler assembler(max_samples);
  for (const auto& chunk : chunks) {
    if (absl::Status s = assembler.Add(chunk); !s.ok()) return s;
  }
  return assembler.Finish();
}

TEST(GalleryExportTest, RoundTripKeepsEveryBitAndTheOrder) {
  const StoredGallery original = OddGallery(50);
  GalleryExporter exporter(original, /*chunk_bytes=*/1000);
  const std::vector<v1::GalleryExportChunk> chunks = Export(exporter);
  ASSERT_GE(chunks.size(), 4u);
  EXPECT_TRUE(chunks.front().has_header());
  EXPECT_EQ(chunks.front().header().format_version(), kGalleryExportFormatVersion);
  EXPECT_EQ(chunks.front().header().sample_count(), 50u);
  EXPECT_EQ(chunks.front().header().knn().scaling(), v1::FEATURE_SCALING_ZSCORE);
  EXPECT_TRUE(chunks.back().has_trailer());
  EXPECT_EQ(chunks.back().trailer().sample_count(), 50u);
  const size_t one_sample = chunks[1].samples().ByteSizeLong() /
                            static_cast<size_t>(chunks[1].samples().sample_ids_size());
  for (size_t i = 1; i + 1 < chunks.size(); ++i) {
    ASSERT_TRUE(chunks[i].has_samples()) << i;
    EXPECT_LE(chunks[i].ByteSizeLong(), 1000 + 2 * one_sample) << "chunk " << i;
  }
  absl::StatusOr<StoredGallery> imported = Assemble(chunks);
  ASSERT_TRUE(imported.ok()) << imported.status();
  ExpectSameStoredGallery(original, *imported);
}

TEST(GalleryExportTest, DefaultChunksStayFarBelowTheGrpcLimit) {
  const StoredGallery big = OddGallery(20'000, 81);  // 6.5 MB of features, 0.5 MB provenance
  GalleryExporter exporter(big);
  const std::vector<v1::GalleryExportChunk> chunks = Export(exporter);
  EXPECT_EQ(chunks.size(), 2u + 8u);  // header, 8 runs of ~1 MiB, trailer
  for (const auto& chunk : chunks) EXPECT_LT(chunk.ByteSizeLong(), kExportChunkBytes + 1024);
  absl::StatusOr<StoredGallery> imported = Assemble(chunks);
  ASSERT_TRUE(imported.ok()) << imported.status();
  EXPECT_EQ(imported->samples.size(), 20'000u);
}

TEST(GalleryExportTest, AnEmptyGalleryIsAHeaderAndATrailer) {
  const StoredGallery empty = OddGallery(0);
  GalleryExporter exporter(empty);
  const std::vector<v1::GalleryExportChunk> chunks = Export(exporter);
  ASSERT_EQ(chunks.size(), 2u);
  EXPECT_EQ(chunks[1].trailer().crc32(), 0u);
  absl::StatusOr<StoredGallery> imported = Assemble(chunks);
  ASSERT_TRUE(imported.ok()) << imported.status();
  ExpectSameStoredGallery(empty, *imported);
}

TEST(GalleryExportTest, ASnapshotExportsLikeItsStoredForm) {
  const StoredGallery original = OddGallery(30);
  auto gallery = Gallery::Restore(original, {}, nullptr);
  ASSERT_TRUE(gallery.ok()) << gallery.status();
  ASSERT_EQ((*gallery)->Snapshot()->incompatible(), "");
  GalleryExporter from_snapshot((*gallery)->Snapshot(), 700);
  GalleryExporter from_stored(original, 700);
  const auto a = Export(from_snapshot);
  const auto b = Export(from_stored);
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].SerializeAsString(), b[i].SerializeAsString()) << "chunk " << i;
  }
}

// The chunks of a gallery file (client/gallery_file.h): "SHAPEIDG", then length-delimited
// chunks.
std::vector<v1::GalleryExportChunk> ReadExportFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(bytes.substr(0, 8), "SHAPEIDG") << path;
  google::protobuf::io::ArrayInputStream stream(bytes.data() + 8,
                                                static_cast<int>(bytes.size()) - 8);
  std::vector<v1::GalleryExportChunk> chunks;
  for (;;) {
    v1::GalleryExportChunk chunk;
    bool clean_eof = false;
    if (!google::protobuf::util::ParseDelimitedFromZeroCopyStream(&chunk, &stream, &clean_eof)) {
      EXPECT_TRUE(clean_eof) << path;
      return chunks;
    }
    chunks.push_back(std::move(chunk));
  }
}

// Two galleries an earlier shapeid stored and exported (server/testdata/README.md): each
// export imports as the stored gallery, and today's exports of it, from the stored form and
// from a restored snapshot, are the earlier export's bytes.
TEST(GalleryExportTest, WhatAnEarlierReleaseStoredExportsAsItExportedThen) {
  const std::string testdata = absl::StrCat(SHAPEID_SOURCE_DIR, "/server/testdata/");
  const std::string dir = absl::StrCat(::testing::TempDir(), "/gallery_export_test_", getpid());
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir + "/galleries");
  for (const char* name : {"old-plain.gallery", "old-augmented.gallery"}) {
    std::filesystem::copy_file(testdata + name, absl::StrCat(dir, "/galleries/", name));
  }
  auto store = SqliteGalleryStore::Open({dir, false});
  ASSERT_TRUE(store.ok()) << store.status();
  auto loaded = (*store)->LoadAll();
  ASSERT_TRUE(loaded.ok()) << loaded.status();
  ASSERT_EQ(loaded->size(), 2u);
  EXPECT_TRUE((*loaded)[0].options.augment.enabled());  // old-augmented
  for (const StoredGallery& stored : *loaded) {
    SCOPED_TRACE(stored.name);
    const std::vector<v1::GalleryExportChunk> old =
        ReadExportFile(absl::StrCat(testdata, stored.name, ".shapeid"));
    ASSERT_EQ(old.size(), 3u);  // header, samples, trailer
    auto imported = Assemble(old);
    ASSERT_TRUE(imported.ok()) << imported.status();
    ExpectSameStoredGallery(*imported, stored);
    auto restored = Gallery::Restore(stored, {}, nullptr);
    ASSERT_TRUE(restored.ok()) << restored.status();
    GalleryExporter from_stored(stored);
    GalleryExporter from_snapshot((*restored)->Snapshot());
    for (const auto& chunks : {Export(from_stored), Export(from_snapshot)}) {
      ASSERT_EQ(chunks.size(), old.size());
      for (size_t i = 0; i < old.size(); ++i) {
        EXPECT_EQ(chunks[i].SerializeAsString(), old[i].SerializeAsString()) << "chunk " << i;
      }
    }
  }
  std::filesystem::remove_all(dir);
}

// OddGallery with view augmentation: sample i has 1 + i % 4 views.
StoredGallery AugmentedGallery(int num_samples) {
  StoredGallery g = OddGallery(num_samples);
  g.options.augment.views = 3;
  g.options.augment.seed = 9;
  for (int i = 0; i < num_samples; ++i) {
    std::vector<float>& f = g.samples[static_cast<size_t>(i)].features;
    const std::vector<float> first = f;
    for (int v = 0; v < i % 4; ++v) {
      for (float x : first) f.push_back(x * static_cast<float>(v + 2));
    }
  }
  return g;
}

TEST(GalleryExportTest, AugmentedGalleriesCarryTheirOptionsAndEveryView) {
  const StoredGallery original = AugmentedGallery(40);
  GalleryExporter exporter(original, /*chunk_bytes=*/1500);
  const std::vector<v1::GalleryExportChunk> chunks = Export(exporter);
  ASSERT_GE(chunks.size(), 4u);
  EXPECT_EQ(chunks.front().header().augmentation().views(), 3u);
  for (size_t i = 1; i + 1 < chunks.size(); ++i) {
    EXPECT_EQ(chunks[i].samples().view_counts_size(), chunks[i].samples().sample_ids_size());
  }
  absl::StatusOr<StoredGallery> imported = Assemble(chunks);
  ASSERT_TRUE(imported.ok()) << imported.status();
  ExpectSameStoredGallery(original, *imported);

  // From a live gallery the same bytes come out.
  auto gallery = Gallery::Restore(original, {}, nullptr);
  ASSERT_TRUE(gallery.ok()) << gallery.status();
  GalleryExporter from_snapshot((*gallery)->Snapshot(), 1500);
  const auto live = Export(from_snapshot);
  ASSERT_EQ(live.size(), chunks.size());
  for (size_t i = 0; i < live.size(); ++i) {
    EXPECT_EQ(live[i].SerializeAsString(), chunks[i].SerializeAsString()) << "chunk " << i;
  }

  // Plain galleries do not list view counts, so their exports are unchanged.
  GalleryExporter plain(OddGallery(5));
  for (const auto& chunk : Export(plain)) {
    EXPECT_EQ(chunk.samples().view_counts_size(), 0);
    EXPECT_FALSE(chunk.header().has_augmentation());
  }

  // Damaged view counts are refused by name.
  auto wrong = chunks;
  wrong[1].mutable_samples()->set_view_counts(1, 99);
  absl::StatusOr<StoredGallery> bad = Assemble(wrong);
  EXPECT_EQ(bad.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(std::string(bad.status().message()), HasSubstr("99 views"));
  wrong = chunks;
  wrong[1].mutable_samples()->mutable_view_counts()->RemoveLast();
  bad = Assemble(wrong);
  EXPECT_THAT(std::string(bad.status().message()), HasSubstr("view counts"));
}

TEST(GalleryExportTest, CrcIsZlibsOverIdLabelAndFeaturesLittleEndian) {
  const float features[] = {1.0f, -2.5f};
  std::string bytes("\x01\x02\x03\x04\x05\x06\x07\x08", 8);
  bytes += "ab";
  bytes.append("\x00\x00\x80\x3f\x00\x00\x20\xc0", 8);
  const uLong expected =
      crc32(crc32(0, nullptr, 0), reinterpret_cast<const Bytef*>(bytes.data()), bytes.size());
  EXPECT_EQ(ExportCrc(0, 0x0807060504030201u, "ab", features), expected);
  // Chaining sample by sample is one CRC over the concatenation.
  EXPECT_EQ(ExportCrc(ExportCrc(0, 1, "a", {}), 2, "b", {}),
            crc32(0, reinterpret_cast<const Bytef*>("\1\0\0\0\0\0\0\0a\2\0\0\0\0\0\0\0b"), 18));
}

TEST(GalleryExportTest, ProvenanceIsExportedOnlyWhereARunHasSome) {
  StoredGallery g = OddGallery(8);
  for (size_t i = 0; i < 4; ++i) g.samples[i].provenance = {};
  GalleryExporter exporter(g, /*chunk_bytes=*/1);  // one sample per run
  const auto chunks = Export(exporter);
  ASSERT_EQ(chunks.size(), 10u);
  for (size_t i = 1; i <= 8; ++i) {
    const v1::ExportedSamples& run = chunks[i].samples();
    const StoredSample& sample = g.samples[i - 1];
    if (sample.provenance.empty()) {
      EXPECT_EQ(run.sources_size(), 0) << i;
      EXPECT_EQ(run.metadata_size(), 0) << i;
      continue;
    }
    ASSERT_EQ(run.sources_size(), 1) << i;
    EXPECT_EQ(run.sources(0), sample.provenance.source);
    ASSERT_EQ(run.metadata(0).entries_size(), static_cast<int>(sample.provenance.metadata.size()));
  }
  // The provenance CRC is zlib's over (id, EncodeProvenance but its CRC) of each sample with
  // some.
  uint32_t expected = 0;
  for (const StoredSample& s : g.samples) {
    if (s.provenance.empty()) continue;
    std::string bytes(8, '\0');
    for (int b = 0; b < 8; ++b) bytes[b] = static_cast<char>(s.id >> (8 * b));
    const std::string encoded = EncodeProvenance(s.provenance);
    bytes += encoded.substr(0, encoded.size() - 4);  // its own CRC left out
    expected = static_cast<uint32_t>(
        crc32(expected, reinterpret_cast<const Bytef*>(bytes.data()), bytes.size()));
  }
  EXPECT_EQ(chunks.back().trailer().provenance_crc32(), expected);
  absl::StatusOr<StoredGallery> imported = Assemble(chunks);
  ASSERT_TRUE(imported.ok()) << imported.status();
  ExpectSameStoredGallery(g, *imported);
}

// An export whose checksum is right but which repeats an id (written by hand or by another
// tool) is malformed, not a name clash: INVALID_ARGUMENT rather than the index's
// ALREADY_EXISTS (found by the bad-input corpus, tests/bad_input_test.cc).
TEST(GalleryExportTest, AnIdTwiceIsMalformed) {
  StoredGallery twice = OddGallery(6);
  twice.samples[4].id = twice.samples[2].id;
  GalleryExporter exporter(twice, 300);
  const absl::Status status = Assemble(Export(exporter)).status();
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(
      std::string(status.message()),
      HasSubstr(absl::StrCat("sample id ", twice.samples[2].id, " appears more than once")));
}

// Finite but huge features (+-3e38) would give infinite distances. The assembler rebuilds
// them bit for bit like any value (it judges the stream, not the values); the registry, which
// every import passes, refuses them: INVALID_ARGUMENT naming the sample and the bound, with
// nothing imported. At the bound itself the import succeeds.
TEST(GalleryExportTest, AnImportOfHugeFeaturesIsRefusedNamingTheSample) {
  StoredGallery huge = OddGallery(6);
  huge.samples[4].features[7] = 3e38f;
  huge.samples[5].features[0] = -3e38f;
  GalleryExporter exporter(huge, 300);
  absl::StatusOr<StoredGallery> assembled = Assemble(Export(exporter));
  ASSERT_TRUE(assembled.ok()) << assembled.status();
  ExpectSameStoredGallery(huge, *assembled);

  GalleryRegistry registry;
  const absl::Status refused = registry.Import(*std::move(assembled)).status();
  EXPECT_EQ(refused.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(std::string(refused.message()),
              HasSubstr(absl::StrCat("sample id ", huge.samples[4].id)));
  EXPECT_THAT(std::string(refused.message()), HasSubstr("feature 7 is 3e+38"));
  EXPECT_THAT(std::string(refused.message()), HasSubstr("within +-1e+08"));
  EXPECT_EQ(registry.size(), 0u);

  huge.samples[4].features[7] = KnnIndex::kMaxFeatureMagnitude;
  huge.samples[5].features[0] = -KnnIndex::kMaxFeatureMagnitude;
  EXPECT_TRUE(registry.Import(huge).ok());
}

class AssemblerErrorTest : public ::testing::Test {
 protected:
  void SetUp() override {
    GalleryExporter exporter(OddGallery(12), 300);
    chunks_ = Export(exporter);
    ASSERT_GE(chunks_.size(), 5u);  // header, >= 3 sample runs, trailer
  }
  absl::Status Error(const std::vector<v1::GalleryExportChunk>& chunks, int64_t max = 1000) {
    return Assemble(chunks, max).status();
  }
  std::vector<v1::GalleryExportChunk> chunks_;
};

TEST_F(AssemblerErrorTest, OrderOfChunks) {
  auto samples_first = chunks_;
  samples_first.erase(samples_first.begin());
  absl::Status s = Error(samples_first);
  EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(std::string(s.message()),
              HasSubstr("samples before the header; an export starts with it (chunk 0)"));

  auto two_headers = chunks_;
  two_headers.insert(two_headers.begin() + 2, chunks_[0]);
  s = Error(two_headers);
  EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(std::string(s.message()), HasSubstr("a second header"));

  auto after_trailer = chunks_;
  after_trailer.push_back(chunks_[1]);
  s = Error(after_trailer);
  EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(std::string(s.message()), HasSubstr("after the trailer"));

  EXPECT_EQ(Error({}).code(), absl::StatusCode::kInvalidArgument);
  auto blank = chunks_;
  blank[1].Clear();
  EXPECT_THAT(std::string(Error(blank).message()),
              HasSubstr("no header, samples or trailer (chunk 1)"));
}

TEST_F(AssemblerErrorTest, HeaderChecks) {
  auto version = chunks_;
  version[0].mutable_header()->set_format_version(2);
  absl::Status s = Error(version);
  EXPECT_EQ(s.code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(std::string(s.message()), HasSubstr("export format version 2"));

  auto no_dimension = chunks_;
  no_dimension[0].mutable_header()->set_dimension(0);
  EXPECT_EQ(Error(no_dimension).code(), absl::StatusCode::kInvalidArgument);

  auto bad_enum = chunks_;
  bad_enum[0].mutable_header()->mutable_knn()->set_scaling(static_cast<v1::FeatureScaling>(9));
  s = Error(bad_enum);
  EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(std::string(s.message()), HasSubstr("feature scaling 9"));

  s = Error(chunks_, /*max=*/11);
  EXPECT_EQ(s.code(), absl::StatusCode::kResourceExhausted);
  EXPECT_THAT(std::string(s.message()), HasSubstr("12 samples"));
}

TEST_F(AssemblerErrorTest, SampleCounts) {
  auto labels = chunks_;
  labels[1].mutable_samples()->mutable_labels()->RemoveLast();
  EXPECT_THAT(std::string(Error(labels).message()), HasSubstr("labels (chunk 1)"));

  auto features = chunks_;
  features[2].mutable_samples()->mutable_features()->RemoveLast();
  absl::Status s = Error(features);
  EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(std::string(s.message()), HasSubstr("features, got"));

  auto more = chunks_;
  more.insert(more.begin() + 1, chunks_[1]);
  s = Error(more);
  EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(std::string(s.message()), HasSubstr("more samples than the header announced (12)"));
}

TEST_F(AssemblerErrorTest, DamageAndTruncationAreDataLoss) {
  auto flipped = chunks_;
  float& f = *flipped[2].mutable_samples()->mutable_features()->Mutable(3);
  uint32_t bits;
  std::memcpy(&bits, &f, 4);
  bits ^= 1;  // one bit, still a finite float
  std::memcpy(&f, &bits, 4);
  absl::Status s = Error(flipped);
  EXPECT_EQ(s.code(), absl::StatusCode::kDataLoss);
  EXPECT_THAT(std::string(s.message()), HasSubstr("export damaged: checksum mismatch"));

  auto missing_run = chunks_;
  missing_run.erase(missing_run.begin() + 2);
  s = Error(missing_run);
  EXPECT_EQ(s.code(), absl::StatusCode::kDataLoss);
  EXPECT_THAT(std::string(s.message()), HasSubstr("the header announced 12 samples"));

  auto truncated = chunks_;
  truncated.resize(2);
  const int64_t first_run = chunks_[1].samples().sample_ids_size();
  s = Error(truncated);
  EXPECT_EQ(s.code(), absl::StatusCode::kDataLoss);
  EXPECT_EQ(s.message(),
            absl::StrCat("export truncated: ", first_run, " of 12 samples, no trailer"));
}

TEST_F(AssemblerErrorTest, TheFirstErrorSticksAndFinishRunsOnce) {
  GalleryImportAssembler assembler(1000);
  const absl::Status first = assembler.Add(chunks_[1]);
  ASSERT_FALSE(first.ok());
  EXPECT_EQ(assembler.Add(chunks_[0]), first);
  EXPECT_EQ(assembler.Finish().status(), first);

  GalleryImportAssembler ok(1000);
  for (const auto& chunk : chunks_) ASSERT_TRUE(ok.Add(chunk).ok());
  EXPECT_EQ(ok.num_samples(), 12);
  ASSERT_TRUE(ok.Finish().ok());
  EXPECT_EQ(ok.Finish().status().code(), absl::StatusCode::kFailedPrecondition);
}

TEST_F(AssemblerErrorTest, ProvenanceDamageAndCounts) {
  size_t run = 0;
  for (size_t i = 1; i + 1 < chunks_.size() && run == 0; ++i) {
    if (chunks_[i].samples().sources_size() > 0) run = i;
  }
  ASSERT_GT(run, 0u);
  auto changed = chunks_;
  // The metadata's first value of the run's sample that has some (sample 2: "d435").
  bool flipped = false;
  for (auto& metadata : *changed[run].mutable_samples()->mutable_metadata()) {
    if (metadata.entries_size() > 0 && !flipped) {
      metadata.mutable_entries(0)->set_value("d436");
      flipped = true;
    }
  }
  ASSERT_TRUE(flipped);
  absl::Status s = Error(changed);
  EXPECT_EQ(s.code(), absl::StatusCode::kDataLoss);
  EXPECT_THAT(std::string(s.message()),
              HasSubstr("checksum mismatch over the samples' provenance"));

  auto short_sources = chunks_;
  short_sources[run].mutable_samples()->mutable_sources()->RemoveLast();
  s = Error(short_sources);
  EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(std::string(s.message()), HasSubstr("sources and"));

  // An export without any provenance (an earlier release's) needs no provenance CRC.
  auto stripped = chunks_;
  for (auto& chunk : stripped) {
    if (!chunk.has_samples()) continue;
    chunk.mutable_samples()->clear_sources();
    chunk.mutable_samples()->clear_metadata();
  }
  stripped.back().mutable_trailer()->clear_provenance_crc32();
  EXPECT_TRUE(Error(stripped).ok()) << Error(stripped);
}

}  // namespace
}  // namespace shapeid
