#include "core/io/zip_archive.h"

#include <zlib.h>

#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"
#include "core/io/zip_testing.h"
#include "core/status_macros.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using ::absl::StatusCode;
using ::testing::HasSubstr;
using ::testing::StartsWith;

template <typename T>
void Put(std::string* s, size_t at, T value) {
  std::memcpy(&(*s)[at], &value, sizeof value);
}

// 152 bytes that deflate compresses a little.
std::string Payload() {
  std::string out;
  for (int i = 0; i < 152; ++i) out.push_back(static_cast<char>(i % 19 == 0 ? i : 'a' + i % 7));
  return out;
}

uint32_t Crc(absl::string_view data) {
  return static_cast<uint32_t>(
      crc32_z(0, reinterpret_cast<const Bytef*>(data.data()), data.size()));
}

// Lists `archive`'s members and reads the first.
absl::StatusOr<std::string> ReadFirst(absl::string_view archive, absl::string_view name) {
  SHAPEID_ASSIGN_OR_RETURN(const std::vector<ZipMember> members, ListZipMembers(archive, name));
  std::string buffer;
  SHAPEID_ASSIGN_OR_RETURN(const absl::string_view bytes,
                           ReadZipMember(archive, members[0], name, &buffer));
  return std::string(bytes);
}

// Asserts the code, that the message starts with `name` and that it holds `where`.
void ExpectStatus(const absl::Status& status, StatusCode code, const std::string& name,
                  const std::string& where) {
  ASSERT_FALSE(status.ok());
  EXPECT_EQ(status.code(), code) << status;
  EXPECT_THAT(std::string(status.message()), StartsWith(name));
  EXPECT_THAT(std::string(status.message()), HasSubstr(where));
}

TEST(ZipArchiveTest, IsZip) {
  EXPECT_TRUE(IsZip(Zip({{"a", "x"}})));
  EXPECT_TRUE(IsZip(Zip({})));  // an empty archive is its end record
  EXPECT_FALSE(IsZip(""));
  EXPECT_FALSE(IsZip("PK"));
  EXPECT_FALSE(IsZip("PK\x01\x02"));
  EXPECT_FALSE(IsZip("\x93NUMPY"));
}

TEST(ZipArchiveTest, StoredDeflatedAndZip64) {
  const std::string data = Payload();
  for (uint16_t method : {0, 8}) {
    for (bool zip64 : {false, true}) {
      SCOPED_TRACE(absl::StrCat("method ", method, " zip64 ", zip64));
      const std::string zip =
          Zip({{"points.npy", data, method, zip64}}, zip64, zip64 ? "a comment" : "");
      const absl::StatusOr<std::vector<ZipMember>> members = ListZipMembers(zip, "z.zip");
      ASSERT_TRUE(members.ok()) << members.status();
      ASSERT_EQ(members->size(), 1u);
      const ZipMember& m = (*members)[0];
      EXPECT_EQ(m.name, "points.npy");
      EXPECT_EQ(m.record, DirectoryOffset(zip));
      EXPECT_EQ(m.flags, 0u);
      EXPECT_EQ(m.method, method);
      EXPECT_EQ(m.crc, Crc(data));
      EXPECT_EQ(m.compressed, method == 8 ? RawDeflate(data).size() : data.size());
      EXPECT_EQ(m.uncompressed, data.size());
      EXPECT_EQ(m.local_header, 0u);
      std::string buffer;
      const absl::StatusOr<absl::string_view> bytes = ReadZipMember(zip, m, "z.zip", &buffer);
      ASSERT_TRUE(bytes.ok()) << bytes.status();
      EXPECT_EQ(*bytes, data);
      if (method == 0) {  // a view into the archive, no copy
        EXPECT_EQ(bytes->data(), zip.data() + 30 + 10 + (zip64 ? 20 : 0));
        EXPECT_TRUE(buffer.empty());
      } else {
        EXPECT_EQ(bytes->data(), buffer.data());
      }
    }
  }
}

TEST(ZipArchiveTest, EveryMemberInDirectoryOrder) {
  const std::string binary_name("b\xff\x01.bin", 7);
  const std::string zip =
      Zip({{"first.txt", "one"}, {binary_name, Payload(), 8}, {"empty", ""}, {"z", "zz", 0, true}});
  const absl::StatusOr<std::vector<ZipMember>> members = ListZipMembers(zip, "m.zip");
  ASSERT_TRUE(members.ok()) << members.status();
  ASSERT_EQ(members->size(), 4u);
  const char* const want[] = {"one", nullptr, "", "zz"};
  for (size_t i = 0; i < 4; ++i) {
    SCOPED_TRACE(i);
    std::string buffer;
    const absl::StatusOr<absl::string_view> bytes =
        ReadZipMember(zip, (*members)[i], "m.zip", &buffer);
    ASSERT_TRUE(bytes.ok()) << bytes.status();
    EXPECT_EQ(*bytes, want[i] == nullptr ? Payload() : std::string(want[i]));
  }
  EXPECT_EQ((*members)[0].name, "first.txt");
  EXPECT_EQ((*members)[1].name, binary_name);
  EXPECT_EQ((*members)[1].local_header, 30u + 9u + 3u);
  EXPECT_EQ((*members)[1].record, DirectoryOffset(zip) + 46 + 9);
  EXPECT_EQ(ZipMemberLabel("m.zip", (*members)[1]), "m.zip:b\\xff\\x01.bin");
}

TEST(ZipArchiveTest, NotAZipArchiveAndEmptyArchive) {
  ExpectStatus(ListZipMembers("", "n.zip").status(), StatusCode::kInvalidArgument, "n.zip",
               "n.zip: byte offset 0: not a zip archive: no end-of-central-directory record "
               "(PK\\5\\6) in its last 0 bytes");
  EXPECT_THAT(std::string(ListZipMembers("", "n.zip").status().message()),
              testing::EndsWith("0 bytes"));  // no hint given, none appended
  // Only the last 22 + 65535 bytes may hold the end record.
  ExpectStatus(ListZipMembers(std::string(70000, 'x'), "n.zip").status(),
               StatusCode::kInvalidArgument, "n.zip",
               "byte offset 4443: not a zip archive: no end-of-central-directory record "
               "(PK\\5\\6) in its last 65557 bytes");
  ExpectStatus(ListZipMembers(Zip({}), "n.zip").status(), StatusCode::kInvalidArgument, "n.zip",
               "byte offset 10: the archive is empty");
  const ZipHints hints{"a .x file is a zip", "a .x file holds arrays"};
  const absl::Status not_zip = ListZipMembers("PK", "n.x", hints).status();
  EXPECT_THAT(std::string(not_zip.message()),
              testing::EndsWith("in its last 2 bytes; a .x file is a zip"));
  const absl::Status empty = ListZipMembers(Zip({}), "n.x", hints).status();
  EXPECT_EQ(empty.message(), "n.x: byte offset 10: the archive is empty; a .x file holds arrays");
  // An end record whose comment would run past the end is not the end record.
  std::string cut = Zip({{"a", "x"}}, false, "a comment");
  cut.pop_back();
  ExpectStatus(ListZipMembers(cut, "c.zip").status(), StatusCode::kInvalidArgument, "c.zip",
               "not a zip archive");
}

TEST(ZipArchiveTest, DirectoryErrors) {
  const std::string zip = Zip({{"points.npy", Payload()}});
  const size_t cd = DirectoryOffset(zip);
  const size_t end = zip.size() - 22;
  std::string z = zip;
  Put<uint32_t>(&z, end + 16, static_cast<uint32_t>(end - 10));
  ExpectStatus(
      ListZipMembers(z, "d.npz").status(), StatusCode::kInvalidArgument, "d.npz",
      absl::StrCat("byte offset ", end + 12, ": the central directory (56 bytes at offset ",
                   end - 10, ") runs past the end of the archive (", zip.size(), " bytes)"));
  z = zip;
  Put<uint32_t>(&z, end + 12, 50);
  ExpectStatus(ListZipMembers(z, "d.npz").status(), StatusCode::kInvalidArgument, "d.npz",
               absl::StrCat("byte offset ", cd + 28,
                            ": central directory entry 0's name, extra field and comment run "
                            "past the end of the central directory"));
  z = zip;
  Put<uint16_t>(&z, end + 10, 2);
  ExpectStatus(ListZipMembers(z, "d.npz").status(), StatusCode::kInvalidArgument, "d.npz",
               absl::StrCat("byte offset ", cd + 56,
                            ": the central directory ends after 1 of its 2 entries"));
  z = zip;
  z[cd + 2] = 'X';
  ExpectStatus(ListZipMembers(z, "d.npz").status(), StatusCode::kInvalidArgument, "d.npz",
               absl::StrCat("byte offset ", cd,
                            ": expected a central directory entry (PK\\1\\2), found \"PKX\\x02\""));
  z = zip;
  Put<uint16_t>(&z, end + 4, 1);
  ExpectStatus(ListZipMembers(z, "d.npz").status(), StatusCode::kUnimplemented, "d.npz",
               absl::StrCat("byte offset ", end + 4,
                            ": split (multi-disk) zip archives are not read; join them first"));
  z = zip;
  Put<uint16_t>(&z, end + 6, 1);
  ExpectStatus(ListZipMembers(z, "d.npz").status(), StatusCode::kUnimplemented, "d.npz",
               "split (multi-disk) zip archives are not read");
  // A ZIP64 size without its extra field.
  z = zip;
  Put<uint32_t>(&z, cd + 24, 0xffffffffu);
  ExpectStatus(ListZipMembers(z, "d.npz").status(), StatusCode::kInvalidArgument, "d.npz",
               absl::StrCat("byte offset ", cd + 56,
                            ": member \"points.npy\": sizes or offset of 0xFFFFFFFF but no "
                            "ZIP64 extra field"));
}

TEST(ZipArchiveTest, Zip64Errors) {
  const std::string zip = Zip({{"points.npy", Payload(), 0, true}}, true);
  const size_t cd = DirectoryOffset(zip);
  const size_t locator = zip.size() - 22 - 20;
  const size_t record = locator - 56;
  std::string z = zip;
  Put<uint64_t>(&z, locator + 8, zip.size());
  ExpectStatus(ListZipMembers(z, "z.npz").status(), StatusCode::kInvalidArgument, "z.npz",
               absl::StrCat("byte offset ", locator + 8, ": the ZIP64 locator points to offset ",
                            zip.size(), ", past the end of the archive (", zip.size(), " bytes)"));
  z = zip;
  z[record] = 'X';
  ExpectStatus(ListZipMembers(z, "z.npz").status(), StatusCode::kInvalidArgument, "z.npz",
               absl::StrCat("byte offset ", record,
                            ": expected the ZIP64 end-of-central-directory record (PK\\6\\6), "
                            "found \"XK\\x06\\x06\""));
  z = zip;
  Put<uint32_t>(&z, locator + 16, 3);
  ExpectStatus(
      ListZipMembers(z, "z.npz").status(), StatusCode::kUnimplemented, "z.npz",
      absl::StrCat("byte offset ", locator + 16, ": split (multi-disk) zip archives are not read"));
  // The ZIP64 record's disk numbers are the ones that count.
  z = zip;
  Put<uint32_t>(&z, record + 16, 1);
  ExpectStatus(ListZipMembers(z, "z.npz").status(), StatusCode::kUnimplemented, "z.npz",
               "split (multi-disk) zip archives are not read");
  // The ZIP64 record's count, size and offset are the ones read.
  z = zip;
  Put<uint64_t>(&z, record + 32, 0);
  ExpectStatus(ListZipMembers(z, "z.npz").status(), StatusCode::kInvalidArgument, "z.npz",
               absl::StrCat("byte offset ", record + 32, ": the archive is empty"));
  z = zip;
  Put<uint64_t>(&z, record + 48, uint64_t{1} << 40);
  ExpectStatus(ListZipMembers(z, "z.npz").status(), StatusCode::kInvalidArgument, "z.npz",
               absl::StrCat("byte offset ", record + 40,
                            ": the central directory (84 bytes at "
                            "offset 1099511627776) runs past"));
  // The CD's ZIP64 field holds three sizes; claim it holds two.
  z = zip;
  Put<uint16_t>(&z, cd + 46 + 10 + 2, 16);
  ExpectStatus(ListZipMembers(z, "z.npz").status(), StatusCode::kInvalidArgument, "z.npz",
               absl::StrCat("byte offset ", cd + 56,
                            ": member \"points.npy\": its ZIP64 extra field has 16 bytes, too few "
                            "for its 3 64-bit sizes"));
}

TEST(ZipArchiveTest, EncryptedAndOtherMethods) {
  const std::string zip = Zip({{"points.npy", Payload()}});
  const size_t cd = DirectoryOffset(zip);
  std::string z = zip;
  Put<uint16_t>(&z, cd + 8, 1);
  ExpectStatus(
      ReadFirst(z, "e.npz").status(), StatusCode::kUnimplemented, "e.npz",
      absl::StrCat("byte offset ", cd + 8,
                   ": member \"points.npy\" is encrypted; encrypted archives are not read"));
  struct Method {
    uint16_t number;
    const char* text;
  };
  for (const Method& m :
       {Method{9, "9 (deflate64)"}, Method{12, "12 (bzip2)"}, Method{14, "14 (LZMA)"},
        Method{93, "93 (zstd)"}, Method{95, "95 (xz)"}, Method{1, "1;"}, Method{99, "99;"}}) {
    SCOPED_TRACE(m.number);
    z = zip;
    Put<uint16_t>(&z, cd + 10, m.number);
    ExpectStatus(
        ReadFirst(z, "e.npz").status(), StatusCode::kUnimplemented, "e.npz",
        absl::StrCat("byte offset ", cd + 10, ": member \"points.npy\" is compressed with method ",
                     m.text, m.text[std::strlen(m.text) - 1] == ';' ? "" : ";",
                     " stored (0) and deflate (8), as numpy writes, are read"));
  }
}

TEST(ZipArchiveTest, MemberHeaderAndSizeErrors) {
  const std::string zip = Zip({{"points.npy", Payload()}});
  const size_t cd = DirectoryOffset(zip);
  std::string z = zip;
  Put<uint32_t>(&z, cd + 42, static_cast<uint32_t>(zip.size()));
  ExpectStatus(
      ReadFirst(z, "e.npz").status(), StatusCode::kInvalidArgument, "e.npz",
      absl::StrCat("byte offset ", cd + 42, ": member \"points.npy\": its local header offset ",
                   zip.size(), " is past the end of the archive (", zip.size(), " bytes)"));
  z = zip;
  z[1] = 'Q';
  ExpectStatus(ReadFirst(z, "e.npz").status(), StatusCode::kInvalidArgument, "e.npz",
               "byte offset 0: member \"points.npy\": expected a local file header (PK\\3\\4), "
               "found \"PQ\\x03\\x04\"");
  z = zip;
  z[30] = 'P';
  ExpectStatus(ReadFirst(z, "e.npz").status(), StatusCode::kInvalidArgument, "e.npz",
               "byte offset 30: member \"points.npy\": its local header names it \"Points.npy\"");
  z = zip;
  Put<uint16_t>(&z, 28, 60000);
  ExpectStatus(ReadFirst(z, "e.npz").status(), StatusCode::kInvalidArgument, "e.npz",
               "byte offset 26: member \"points.npy\": its local header runs past the end of the "
               "archive");
  z = zip;
  Put<uint32_t>(&z, cd + 20, 100000);
  Put<uint32_t>(&z, cd + 24, 100000);
  ExpectStatus(ReadFirst(z, "e.npz").status(), StatusCode::kInvalidArgument, "e.npz",
               absl::StrCat("byte offset ", cd + 20,
                            ": member \"points.npy\": its 100000 bytes at offset 40 run past the "
                            "end of the archive (",
                            zip.size(), " bytes)"));
  z = zip;
  Put<uint32_t>(&z, cd + 24, 100);
  ExpectStatus(ReadFirst(z, "e.npz").status(), StatusCode::kInvalidArgument, "e.npz",
               absl::StrCat("byte offset ", cd + 20,
                            ": member \"points.npy\" is stored, yet its sizes differ (152 bytes "
                            "stored, 100 bytes uncompressed)"));
  z = zip;
  z[cd + 16] ^= 1;
  const uint32_t crc = Crc(Payload());
  ExpectStatus(ReadFirst(z, "e.npz").status(), StatusCode::kInvalidArgument, "e.npz",
               absl::StrCat("byte offset ", cd + 16,
                            ": member \"points.npy\": its data's CRC-32 "
                            "is 0x",
                            absl::Hex(crc, absl::kZeroPad8), ", the archive records 0x",
                            absl::Hex(crc ^ 1, absl::kZeroPad8), " (the archive is corrupt)"));
  z = zip;
  z[100] ^= 1;  // in the member's data
  ExpectStatus(ReadFirst(z, "e.npz").status(), StatusCode::kInvalidArgument, "e.npz",
               "the archive is corrupt");
}

TEST(ZipArchiveTest, DeflateErrors) {
  const std::string zip = Zip({{"points.npy", Payload(), 8}});
  const size_t cd = DirectoryOffset(zip);
  uint32_t compressed;
  std::memcpy(&compressed, &zip[cd + 20], 4);
  std::string z = zip;
  // More than 1032:1 is impossible for deflate: refused before allocating.
  Put<uint32_t>(&z, cd + 24, compressed * 1032 + 1033);
  ExpectStatus(ReadFirst(z, "f.npz").status(), StatusCode::kInvalidArgument, "f.npz",
               absl::StrCat("byte offset ", cd + 24, ": member \"points.npy\" claims ",
                            compressed * 1032 + 1033, " bytes from ", compressed,
                            " deflated bytes, more than deflate can reach (1032:1)"));
  z = zip;
  Put<uint32_t>(&z, cd + 24, compressed * 1032 + 1032);  // possible, so inflated, then too short
  ExpectStatus(ReadFirst(z, "f.npz").status(), StatusCode::kInvalidArgument, "f.npz:points.npy",
               "f.npz:points.npy: deflated data is 152 bytes, not its stated size");
  z = zip;
  Put<uint32_t>(&z, cd + 24, 151);
  ExpectStatus(ReadFirst(z, "f.npz").status(), StatusCode::kInvalidArgument, "f.npz:points.npy",
               "f.npz:points.npy: deflated data is longer than its stated size of 151 bytes");
  z = zip;
  z[40] = '\xff';  // the first deflate block header: an invalid block type
  ExpectStatus(ReadFirst(z, "f.npz").status(), StatusCode::kInvalidArgument, "f.npz:points.npy",
               "corrupt deflated data");
}

// Truncated and corrupted archives: every error names the archive, and every member read
// has its recorded size and CRC-32. ASan checks the bounds.
TEST(ZipArchiveTest, RandomCorruptionsNameTheArchive) {
  const char replacements[] = "\x00\x01\x02\x03\x04\x05\x06\x07\x08\xff\xfePK";
  uint64_t state = 7;
  const auto check = [](const std::string& archive) {
    const absl::StatusOr<std::vector<ZipMember>> members = ListZipMembers(archive, "bad.zip");
    if (!members.ok()) {
      EXPECT_THAT(std::string(members.status().message()), StartsWith("bad.zip: "));
      return;
    }
    for (const ZipMember& m : *members) {
      std::string buffer;
      const absl::StatusOr<absl::string_view> bytes = ReadZipMember(archive, m, "bad.zip", &buffer);
      if (!bytes.ok()) {
        EXPECT_THAT(std::string(bytes.status().message()), StartsWith("bad.zip"));
        continue;
      }
      EXPECT_EQ(bytes->size(), m.uncompressed);
      EXPECT_EQ(Crc(*bytes), m.crc);
    }
  };
  for (const std::string& zip : {Zip({{"points.npy", Payload(), 8}, {"b.npy", Payload()}}),
                                 Zip({{"arr_0.npy", Payload(), 0, true}}, true)}) {
    for (size_t n = 0; n < zip.size(); ++n) check(zip.substr(0, n));
    for (int trial = 0; trial < 2000; ++trial) {
      std::string corrupt = zip;
      for (int e = 0; e < 3; ++e) {
        state = state * 6364136223846793005ull + 1442695040888963407ull;
        corrupt[(state >> 33) % corrupt.size()] =
            replacements[(state >> 17) % (sizeof replacements - 1)];
      }
      check(corrupt);
    }
  }
}

}  // namespace
}  // namespace shapeid
