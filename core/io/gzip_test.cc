#include "core/io/gzip.h"

#include <zlib.h>

#include <string>

#include "core/io/io_testing.h"
#include "core/io/point_cloud_reader.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;

// `text` compressed by zlib as gzip (window bits 16 + 15) or raw deflate (-15).
std::string Compress(const std::string& text, int window_bits) {
  z_stream z{};
  EXPECT_EQ(deflateInit2(&z, 6, Z_DEFLATED, window_bits, 8, Z_DEFAULT_STRATEGY), Z_OK);
  std::string out(deflateBound(&z, text.size()) + 32, '\0');
  z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(text.data()));
  z.avail_in = static_cast<uInt>(text.size());
  z.next_out = reinterpret_cast<Bytef*>(out.data());
  z.avail_out = static_cast<uInt>(out.size());
  EXPECT_EQ(deflate(&z, Z_FINISH), Z_STREAM_END);
  out.resize(z.total_out);
  deflateEnd(&z);
  return out;
}

std::string Gzip(const std::string& text) { return Compress(text, 16 + MAX_WBITS); }

std::string ManyPoints(int n) {
  std::string text;
  for (int i = 0; i < n; ++i) text += std::to_string(i) + " " + std::to_string(2 * i) + " 1\n";
  return text;
}

TEST(GzipTest, RoundTripsLargeAndConcatenatedMembers) {
  const std::string a = ManyPoints(50000);
  const std::string b = "7 8 9\n";
  absl::StatusOr<std::string> one = Gunzip(Gzip(a), "a.gz", size_t{1} << 30);
  ASSERT_TRUE(one.ok()) << one.status();
  EXPECT_EQ(*one, a);
  absl::StatusOr<std::string> two = Gunzip(Gzip(a) + Gzip(b), "ab.gz", size_t{1} << 30);
  ASSERT_TRUE(two.ok()) << two.status();
  EXPECT_EQ(*two, a + b);
}

TEST(GzipTest, TruncatedCorruptAndBombAreRefusedNamingTheFile) {
  const std::string gz = Gzip(ManyPoints(2000));
  const absl::StatusOr<std::string> cut = Gunzip(gz.substr(0, gz.size() / 2), "c.gz", 1 << 30);
  ASSERT_FALSE(cut.ok());
  EXPECT_EQ(cut.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(std::string(cut.status().message()), HasSubstr("c.gz: byte offset "));
  EXPECT_THAT(std::string(cut.status().message()), HasSubstr("gzip data ends early"));
  std::string corrupt = gz;
  corrupt[gz.size() / 2] ^= 0x55;
  corrupt[gz.size() / 2 + 1] ^= 0x55;
  const absl::StatusOr<std::string> bad = Gunzip(corrupt, "d.gz", 1 << 30);
  ASSERT_FALSE(bad.ok());
  EXPECT_THAT(std::string(bad.status().message()), HasSubstr("d.gz"));
  const absl::StatusOr<std::string> bomb = Gunzip(Gzip(std::string(1 << 20, 'a')), "b.gz", 4096);
  ASSERT_FALSE(bomb.ok());
  EXPECT_THAT(std::string(bomb.status().message()), HasSubstr("more than 4096 bytes"));
}

TEST(GzipTest, ADamagedSecondMemberIsAnErrorAndZeroPaddingIsNot) {
  const std::string a = ManyPoints(100);
  const std::string b = ManyPoints(50);
  std::string damaged = Gzip(a) + Gzip(b);
  damaged[Gzip(a).size()] = 'X';  // the second member's magic
  const absl::StatusOr<std::string> refused = Gunzip(damaged, "m.gz", 1 << 30);
  ASSERT_FALSE(refused.ok());
  EXPECT_THAT(std::string(refused.status().message()),
              HasSubstr(absl::StrCat("m.gz: byte offset ", Gzip(a).size(),
                                     ": data after the gzip stream")));
  const absl::StatusOr<std::string> padded =
      Gunzip(Gzip(a) + std::string(512, '\0'), "p.gz", 1 << 30);
  ASSERT_TRUE(padded.ok()) << padded.status();
  EXPECT_EQ(*padded, a);
}

TEST(GzipTest, RawDeflateMustMatchItsStatedSize) {
  const std::string text = ManyPoints(100);
  const std::string raw = Compress(text, -MAX_WBITS);
  absl::StatusOr<std::string> ok = InflateRaw(raw, text.size(), "m.npy");
  ASSERT_TRUE(ok.ok()) << ok.status();
  EXPECT_EQ(*ok, text);
  EXPECT_FALSE(InflateRaw(raw, text.size() - 1, "m.npy").ok());
  EXPECT_FALSE(InflateRaw(raw, text.size() + 1, "m.npy").ok());
  EXPECT_FALSE(InflateRaw(raw.substr(0, raw.size() - 4), text.size(), "m.npy").ok());
  // A stated size far above the data costs nothing up front: memory follows the output.
  const absl::StatusOr<std::string> claimed = InflateRaw(raw, size_t{1} << 40, "m.npy");
  ASSERT_FALSE(claimed.ok());
  EXPECT_THAT(std::string(claimed.status().message()), HasSubstr("not its stated size"));
}

TEST(GzipTest, EveryFormatReadsGzippedByNameOrByContents) {
  const std::string text = "1 2 3\n4 5 6\n";
  const std::string plain = WriteTempFile("p.xyz", text);
  const std::string by_name = WriteTempFile("p.xyz.gz", Gzip(text));
  const std::string renamed = WriteTempFile("q.xyz", Gzip(text));
  const absl::StatusOr<ReadResult> a = ReadPointCloud(plain, Raw());
  ASSERT_TRUE(a.ok()) << a.status();
  for (const std::string& path : {by_name, renamed}) {
    const absl::StatusOr<ReadResult> b = ReadPointCloud(path, Raw());
    ASSERT_TRUE(b.ok()) << b.status();
    ASSERT_EQ(b->cloud.size(), 2u);
    EXPECT_EQ(b->cloud.point(1), a->cloud.point(1));
  }
  // Corrupt data names the file as the readers do.
  const std::string cut = WriteTempFile("cut.pcd.gz", Gzip(text).substr(0, 12));
  ExpectError(ReadPointCloud(cut, Raw()), absl::StatusCode::kInvalidArgument, cut, "gzip");
}

}  // namespace
}  // namespace shapeid
