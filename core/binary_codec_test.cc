#include "core/binary_codec.h"

#include <string>

#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;

std::string File(uint32_t version, uint32_t payload) {
  ByteWriter out;
  out.Header("SHPDTEST", version);
  out.U32(payload);
  return std::move(out).Finish();
}

std::string ErrorOf(const std::string& bytes) {
  ByteReader reader;
  const absl::Status status = OpenVersionedFile(bytes, "SHPDTEST", 3, "test file", reader);
  EXPECT_EQ(status.code(), absl::StatusCode::kDataLoss) << status;
  return std::string(status.message());
}

TEST(BinaryCodecTest, AVersionedFileOpensAfterItsHeader) {
  const std::string file = File(3, 42);  // the reader reads it in place
  ByteReader reader;
  ASSERT_TRUE(OpenVersionedFile(file, "SHPDTEST", 3, "test file", reader).ok());
  uint32_t payload = 0;
  ASSERT_TRUE(reader.U32(payload));
  EXPECT_EQ(payload, 42u);
  EXPECT_EQ(reader.left(), 0u);
}

TEST(BinaryCodecTest, AVersionedFileRefusesEachDefectByName) {
  EXPECT_EQ(ErrorOf(""), "not a shapeid test file: no magic");
  EXPECT_EQ(ErrorOf("SHPDTES"), "not a shapeid test file: no magic");
  EXPECT_EQ(ErrorOf("SHPDMLP\0" + File(3, 1).substr(8)), "not a shapeid test file: no magic");
  std::string damaged = File(3, 1);
  damaged[13] ^= 1;
  EXPECT_THAT(ErrorOf(damaged), HasSubstr("checksum mismatch"));
  EXPECT_THAT(ErrorOf(File(3, 1).substr(0, 15)), HasSubstr("checksum mismatch"));
  EXPECT_EQ(ErrorOf(File(4, 1)), "not a shapeid test file: format version 4, this build reads 3");
}

}  // namespace
}  // namespace shapeid
