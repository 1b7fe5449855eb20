// The gallery file: chunks come back as written, the target only ever holds a complete file,
// and a foreign, truncated or damaged file is refused with a message that says which.

#include "client/gallery_file.h"

#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using ::testing::StartsWith;

std::vector<v1::GalleryExportChunk> SomeChunks(int runs = 3) {
  std::vector<v1::GalleryExportChunk> chunks(1);
  chunks[0].mutable_header()->set_name("parts");
  chunks[0].mutable_header()->set_dimension(4);
  for (int r = 0; r < runs; ++r) {
    v1::ExportedSamples* s = chunks.emplace_back().mutable_samples();
    for (int i = 0; i < 100; ++i) {
      s->add_sample_ids(static_cast<uint64_t>(1000 * r + i + 1));
      s->add_labels(absl::StrCat("label-", i % 7));
      for (int j = 0; j < 4; ++j) s->add_features(0.25f * static_cast<float>(i * j) - 3.0f);
    }
  }
  chunks.emplace_back().mutable_trailer()->set_sample_count(static_cast<uint64_t>(100 * runs));
  return chunks;
}

std::string Slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

class GalleryFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::path(::testing::TempDir()) /
           absl::StrCat("gallery_file_", ::getpid(), "_",
                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string Path(const std::string& name) const { return (dir_ / name).string(); }

  absl::Status WriteAll(const std::string& path, const std::vector<v1::GalleryExportChunk>& chunks,
                        uint64_t* bytes = nullptr) {
    auto writer = GalleryFileWriter::Open(path);
    if (!writer.ok()) return writer.status();
    for (const auto& chunk : chunks) {
      if (absl::Status s = (*writer)->Write(chunk); !s.ok()) return s;
    }
    if (bytes != nullptr) *bytes = (*writer)->bytes_written();
    return (*writer)->Commit();
  }

  // Every chunk of `path`, or the first error.
  absl::StatusOr<std::vector<v1::GalleryExportChunk>> ReadAll(const std::string& path) {
    auto reader = GalleryFileReader::Open(path);
    if (!reader.ok()) return reader.status();
    std::vector<v1::GalleryExportChunk> chunks;
    v1::GalleryExportChunk chunk;
    while (true) {
      absl::StatusOr<bool> more = (*reader)->Next(&chunk);
      if (!more.ok()) return more.status();
      if (!*more) break;
      chunks.push_back(chunk);
    }
    return chunks;
  }

  // Names in the directory (temporary files included).
  std::vector<std::string> Entries() const {
    std::vector<std::string> names;
    for (const auto& entry : fs::directory_iterator(dir_)) {
      names.push_back(entry.path().filename().string());
    }
    return names;
  }

  fs::path dir_;
};

TEST_F(GalleryFileTest, ChunksComeBackAsWritten) {
  const auto chunks = SomeChunks();
  uint64_t bytes = 0;
  ASSERT_TRUE(WriteAll(Path("g.shapeid"), chunks, &bytes).ok());
  const std::string contents = Slurp(Path("g.shapeid"));
  EXPECT_THAT(contents, StartsWith("SHAPEIDG"));
  EXPECT_EQ(contents.size(), bytes);
  auto back = ReadAll(Path("g.shapeid"));
  ASSERT_TRUE(back.ok()) << back.status();
  ASSERT_EQ(back->size(), chunks.size());
  for (size_t i = 0; i < chunks.size(); ++i) {
    EXPECT_EQ((*back)[i].SerializeAsString(), chunks[i].SerializeAsString()) << i;
  }
  EXPECT_THAT(Entries(), ::testing::ElementsAre("g.shapeid"));  // no temporary file left
}

TEST_F(GalleryFileTest, TheTargetOnlyEverHoldsACompleteFile) {
  ASSERT_TRUE(WriteAll(Path("g.shapeid"), SomeChunks(1)).ok());
  const std::string before = Slurp(Path("g.shapeid"));
  {
    auto writer = GalleryFileWriter::Open(Path("g.shapeid"));
    ASSERT_TRUE(writer.ok());
    for (const auto& chunk : SomeChunks(5)) ASSERT_TRUE((*writer)->Write(chunk).ok());
    // While it is being written, the old file is intact and the new one lives elsewhere.
    EXPECT_EQ(Slurp(Path("g.shapeid")), before);
    EXPECT_EQ(Entries().size(), 2u);
  }  // abandoned without Commit: an export that failed half-way
  EXPECT_EQ(Slurp(Path("g.shapeid")), before);
  EXPECT_THAT(Entries(), ::testing::ElementsAre("g.shapeid"));

  ASSERT_TRUE(WriteAll(Path("g.shapeid"), SomeChunks(5)).ok());
  EXPECT_GT(Slurp(Path("g.shapeid")).size(), before.size());
  EXPECT_THAT(Entries(), ::testing::ElementsAre("g.shapeid"));
}

TEST_F(GalleryFileTest, OpenErrorsNameThePath) {
  const absl::Status no_dir = WriteAll(Path("missing/g.shapeid"), SomeChunks());
  EXPECT_EQ(no_dir.code(), absl::StatusCode::kNotFound);
  EXPECT_THAT(std::string(no_dir.message()), HasSubstr("missing/g.shapeid"));
  EXPECT_EQ(ReadAll(Path("nothing.shapeid")).status().code(), absl::StatusCode::kNotFound);
  EXPECT_EQ(WriteAll(dir_.string() + "/", SomeChunks()).code(), absl::StatusCode::kInvalidArgument);
}

TEST_F(GalleryFileTest, AForeignFileHasBadMagic) {
  std::ofstream(Path("cloud.pcd")) << "# .PCD v0.7\nVERSION 0.7\n";
  std::ofstream(Path("empty"));
  for (const char* name : {"cloud.pcd", "empty"}) {
    const absl::Status s = ReadAll(Path(name)).status();
    EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument);
    EXPECT_EQ(s.message(),
              absl::StrCat(Path(name), " is not a shapeid gallery export (bad magic)"));
  }
}

TEST_F(GalleryFileTest, TruncationAndDamageAreDataLoss) {
  ASSERT_TRUE(WriteAll(Path("g.shapeid"), SomeChunks()).ok());
  const std::string whole = Slurp(Path("g.shapeid"));

  // Cut anywhere inside a chunk: the reader says truncated, whichever chunk it is.
  for (size_t cut : {size_t{9}, whole.size() / 2, whole.size() - 1}) {
    std::ofstream(Path("cut.shapeid"), std::ios::binary) << whole.substr(0, cut);
    const absl::Status s = ReadAll(Path("cut.shapeid")).status();
    EXPECT_EQ(s.code(), absl::StatusCode::kDataLoss) << cut;
    EXPECT_THAT(std::string(s.message()), HasSubstr("cut.shapeid is truncated")) << cut;
  }

  // A length prefix that claims 2^32 - 1 bytes is refused before anything is allocated.
  std::string huge = "SHAPEIDG";
  huge += "\xff\xff\xff\xff\x0f";
  huge += "garbage";
  std::ofstream(Path("huge.shapeid"), std::ios::binary) << huge;
  absl::Status s = ReadAll(Path("huge.shapeid")).status();
  EXPECT_EQ(s.code(), absl::StatusCode::kDataLoss);
  EXPECT_THAT(std::string(s.message()), HasSubstr("claims 4294967295 bytes"));

  // Bytes that are not a message at all.
  std::string junk = "SHAPEIDG";
  junk += '\x04';
  junk += "\xff\xff\xff\xff";
  std::ofstream(Path("junk.shapeid"), std::ios::binary) << junk;
  s = ReadAll(Path("junk.shapeid")).status();
  EXPECT_EQ(s.code(), absl::StatusCode::kDataLoss);
  EXPECT_THAT(std::string(s.message()), HasSubstr("chunk 0 at byte 8 is not a GalleryExportChunk"));
}

TEST_F(GalleryFileTest, ALargeChunkIsRefusedAtWriteTime) {
  v1::GalleryExportChunk big;
  big.mutable_samples()->mutable_features()->Resize(
      static_cast<int>(kMaxGalleryFileChunkBytes / 4) + 16, 1.0f);
  auto writer = GalleryFileWriter::Open(Path("big.shapeid"));
  ASSERT_TRUE(writer.ok());
  const absl::Status s = (*writer)->Write(big);
  EXPECT_EQ(s.code(), absl::StatusCode::kResourceExhausted);
  EXPECT_EQ((*writer)->Commit(), s);  // the first error sticks
  writer->reset();
  EXPECT_TRUE(Entries().empty());
}

}  // namespace
}  // namespace shapeid
