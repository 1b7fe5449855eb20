#include "core/gallery/sample_provenance.h"

#include <string>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "core/gallery/gallery_store_testing.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;

SampleProvenance Example() {
  SampleProvenance p;
  p.source = "scans/chair/chair_0001.pcd";
  p.metadata = {{"camera", "realsense-d435"}, {"operator", "Zoë"}, {"session", ""}};
  return p;
}

TEST(SampleProvenanceTest, EncodeDecodeRoundTrips) {
  const SampleProvenance p = Example();
  const std::string bytes = EncodeProvenance(p);
  const absl::StatusOr<SampleProvenance> back = DecodeProvenance(bytes);
  ASSERT_TRUE(back.ok()) << back.status();
  EXPECT_EQ(*back, p);
  // Version byte, then the source's length, little-endian.
  ASSERT_GE(bytes.size(), 5u);
  EXPECT_EQ(bytes[0], '\x01');
  EXPECT_EQ(static_cast<uint8_t>(bytes[1]), p.source.size());
  EXPECT_EQ(bytes.substr(5, p.source.size()), p.source);
}

TEST(SampleProvenanceTest, ProvenanceBytesCountTheText) {
  EXPECT_EQ(ProvenanceBytes({}), 0u);
  // "scans/chair/chair_0001.pcd", then the keys and values.
  EXPECT_EQ(ProvenanceBytes(Example()), 26u + 6 + 14 + 8 + 4 + 7);
  EXPECT_EQ(ProvenanceBytes(gallery_testing::ProvenanceAtLimits(1)),
            kMaxSourceBytes + kMaxMetadataBytes);
}

// A gallery trained holds copies of its samples' provenance; one loaded from a store holds
// what DecodeProvenance made. Both must take the same memory.
TEST(SampleProvenanceTest, DecodingTakesTheMemoryOfACopy) {
  SampleProvenance odd;  // sizes where growth would over-allocate: 20-byte values, 5 pairs
  odd.source = std::string(100, 's');
  for (int i = 0; i < 5; ++i)
    odd.metadata.emplace_back(absl::StrCat("key", i), std::string(20, 'v'));
  for (const SampleProvenance& p : {Example(), odd, gallery_testing::ProvenanceAtLimits(1)}) {
    const absl::StatusOr<SampleProvenance> decoded = DecodeProvenance(EncodeProvenance(p));
    ASSERT_TRUE(decoded.ok()) << decoded.status();
    const SampleProvenance copy = p;
    EXPECT_EQ(ProvenanceMemoryBytes(*decoded), ProvenanceMemoryBytes(copy));
    EXPECT_EQ(decoded->metadata.capacity(), p.metadata.size());
  }
  // At the limits: 8 KiB of text in 130 allocations.
  const size_t at_limits = ProvenanceMemoryBytes(gallery_testing::ProvenanceAtLimits(1));
  EXPECT_GT(at_limits, 14000u);
  EXPECT_LT(at_limits, 16384u);
}

TEST(SampleProvenanceTest, EmptyIsNoBytes) {
  EXPECT_EQ(EncodeProvenance({}), "");
  const absl::StatusOr<SampleProvenance> back = DecodeProvenance("");
  ASSERT_TRUE(back.ok());
  EXPECT_TRUE(back->empty());
  // A source alone, or metadata alone, is not empty.
  SampleProvenance only_metadata;
  only_metadata.metadata = {{"k", "v"}};
  EXPECT_EQ(*DecodeProvenance(EncodeProvenance(only_metadata)), only_metadata);
}

TEST(SampleProvenanceTest, EveryDamageIsDataLoss) {
  const std::string bytes = EncodeProvenance(Example());
  // Every prefix and every single-bit flip is refused, never misread.
  for (size_t n = 1; n < bytes.size(); ++n) {
    const absl::StatusOr<SampleProvenance> cut = DecodeProvenance(bytes.substr(0, n));
    EXPECT_EQ(cut.status().code(), absl::StatusCode::kDataLoss) << n;
  }
  for (size_t i = 0; i < bytes.size(); ++i) {
    for (int bit = 0; bit < 8; ++bit) {
      std::string flipped = bytes;
      flipped[i] = static_cast<char>(flipped[i] ^ (1 << bit));
      EXPECT_EQ(DecodeProvenance(flipped).status().code(), absl::StatusCode::kDataLoss)
          << i << " " << bit;
    }
  }
  EXPECT_THAT(DecodeProvenance(bytes + "x").status().message(), HasSubstr("sample provenance"));
}

TEST(SampleProvenanceTest, ValidateAcceptsTheLimits) {
  SampleProvenance p;
  p.source = std::string(kMaxSourceBytes, 's');
  EXPECT_TRUE(ValidateProvenance(p).ok());
  p.source.clear();
  for (size_t i = 0; i < kMaxMetadataEntries; ++i) {
    p.metadata.emplace_back(absl::StrCat("k", 100 + i),
                            std::string(kMaxMetadataBytes / 64 - 4, 'v'));
  }
  EXPECT_TRUE(ValidateProvenance(p).ok()) << ValidateProvenance(p);
}

TEST(SampleProvenanceTest, ValidateNamesWhatIsWrong) {
  const auto message = [](const SampleProvenance& p) {
    const absl::Status s = ValidateProvenance(p);
    EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument);
    return std::string(s.message());
  };
  SampleProvenance p;
  p.source = std::string(kMaxSourceBytes + 1, 's');
  EXPECT_THAT(message(p), HasSubstr("4097 bytes, more than the limit of 4096"));
  p.source = "bad\xff";
  EXPECT_THAT(message(p), HasSubstr("source \"bad\\xff\" is not valid UTF-8 (at byte 3)"));
  p.source = "ok";
  p.metadata = {{"", "v"}};
  EXPECT_THAT(message(p), HasSubstr("a metadata key is empty"));
  p.metadata = {{"b", "1"}, {"a", "2"}};
  EXPECT_THAT(message(p), HasSubstr("out of order or given twice"));
  p.metadata = {{"k", "\xc0\x80"}};
  EXPECT_THAT(message(p), HasSubstr("metadata value of \"k\""));
  p.metadata.clear();
  for (size_t i = 0; i <= kMaxMetadataEntries; ++i)
    p.metadata.emplace_back(absl::StrCat(100 + i), "");
  EXPECT_THAT(message(p), HasSubstr("65 entries, more than the limit of 64"));
  p.metadata = {{"k", std::string(kMaxMetadataBytes, 'v')}};
  EXPECT_THAT(message(p), HasSubstr("4097 bytes of keys and values"));
}

TEST(SampleProvenanceTest, NormalizeSortsAndRefusesDuplicates) {
  std::vector<std::pair<std::string, std::string>> m = {{"z", "1"}, {"a", "2"}};
  ASSERT_TRUE(NormalizeMetadata(m).ok());
  EXPECT_EQ(m.front().first, "a");
  m.emplace_back("a", "3");
  EXPECT_THAT(NormalizeMetadata(m).message(), HasSubstr("metadata key \"a\" is given twice"));
}

}  // namespace
}  // namespace shapeid
