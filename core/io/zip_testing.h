#ifndef SHAPEID_CORE_IO_ZIP_TESTING_H_
#define SHAPEID_CORE_IO_ZIP_TESTING_H_

// Test-only: zip archives built by hand, byte by byte, so that tests know every offset.

#include <zlib.h>

#include <cstdint>
#include <string>
#include <vector>

#include "absl/strings/string_view.h"
#include "core/io/io_testing.h"
#include "gtest/gtest.h"

namespace shapeid {

// `data` as a raw deflate stream (no header), as zip archives store it.
inline std::string RawDeflate(absl::string_view data) {
  z_stream z{};
  EXPECT_EQ(deflateInit2(&z, 9, Z_DEFLATED, -15, 8, Z_DEFAULT_STRATEGY), Z_OK);
  std::string out(deflateBound(&z, data.size()), '\0');
  z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(data.data()));
  z.avail_in = static_cast<uInt>(data.size());
  z.next_out = reinterpret_cast<Bytef*>(&out[0]);
  z.avail_out = static_cast<uInt>(out.size());
  EXPECT_EQ(deflate(&z, Z_FINISH), Z_STREAM_END);
  out.resize(z.total_out);
  deflateEnd(&z);
  return out;
}

struct TestZipMember {
  std::string name;
  std::string data;
  uint16_t method = 0;  // 0 stored, 8 deflate
  bool zip64 = false;   // sizes and offset in ZIP64 extra fields, as numpy's force_zip64
};

// A zip archive of `members`: each local header (30 bytes, the name, for zip64 a 20-byte extra
// field) and data in order, then the central directory (46 bytes, the name, for zip64 a
// 28-byte extra field per entry); with zip64_end the ZIP64 end record (56 bytes) and locator
// (20 bytes); then the 22-byte end record and `comment`.
inline std::string Zip(const std::vector<TestZipMember>& members, bool zip64_end = false,
                       absl::string_view comment = "") {
  constexpr uint32_t kMax32 = 0xffffffffu;
  std::string out, directory;
  for (const TestZipMember& m : members) {
    const std::string stored = m.method == 8 ? RawDeflate(m.data) : m.data;
    const uint32_t crc = static_cast<uint32_t>(
        crc32(0, reinterpret_cast<const Bytef*>(m.data.data()), static_cast<uInt>(m.data.size())));
    const uint64_t local = out.size();
    const auto u16 = [](std::string* s, uint64_t v) { AppendBytes(s, static_cast<uint16_t>(v)); };
    const auto u32 = [](std::string* s, uint64_t v) { AppendBytes(s, static_cast<uint32_t>(v)); };
    u32(&out, 0x04034b50);
    u16(&out, m.zip64 ? 45 : 20);
    u16(&out, 0);  // flags
    u16(&out, m.method);
    u32(&out, 0);  // time and date
    u32(&out, crc);
    u32(&out, m.zip64 ? kMax32 : stored.size());
    u32(&out, m.zip64 ? kMax32 : m.data.size());
    u16(&out, m.name.size());
    u16(&out, m.zip64 ? 20 : 0);
    out += m.name;
    if (m.zip64) {
      u16(&out, 1);
      u16(&out, 16);
      AppendBytes<uint64_t>(&out, m.data.size());
      AppendBytes<uint64_t>(&out, stored.size());
    }
    out += stored;

    u32(&directory, 0x02014b50);
    u16(&directory, m.zip64 ? 45 : 20);  // made by
    u16(&directory, m.zip64 ? 45 : 20);  // needed
    u16(&directory, 0);
    u16(&directory, m.method);
    u32(&directory, 0);
    u32(&directory, crc);
    u32(&directory, m.zip64 ? kMax32 : stored.size());
    u32(&directory, m.zip64 ? kMax32 : m.data.size());
    u16(&directory, m.name.size());
    u16(&directory, m.zip64 ? 28 : 0);
    u16(&directory, 0);  // comment
    u16(&directory, 0);  // disk
    u16(&directory, 0);  // internal attributes
    u32(&directory, 0);  // external attributes
    u32(&directory, m.zip64 ? kMax32 : local);
    directory += m.name;
    if (m.zip64) {
      u16(&directory, 1);
      u16(&directory, 24);
      AppendBytes<uint64_t>(&directory, m.data.size());
      AppendBytes<uint64_t>(&directory, stored.size());
      AppendBytes<uint64_t>(&directory, local);
    }
  }
  const uint64_t directory_offset = out.size();
  out += directory;
  if (zip64_end) {
    const uint64_t record = out.size();
    AppendBytes<uint32_t>(&out, 0x06064b50);
    AppendBytes<uint64_t>(&out, 44);
    AppendBytes<uint16_t>(&out, 45);
    AppendBytes<uint16_t>(&out, 45);
    AppendBytes<uint32_t>(&out, 0);
    AppendBytes<uint32_t>(&out, 0);
    AppendBytes<uint64_t>(&out, members.size());
    AppendBytes<uint64_t>(&out, members.size());
    AppendBytes<uint64_t>(&out, directory.size());
    AppendBytes<uint64_t>(&out, directory_offset);
    AppendBytes<uint32_t>(&out, 0x07064b50);
    AppendBytes<uint32_t>(&out, 0);
    AppendBytes<uint64_t>(&out, record);
    AppendBytes<uint32_t>(&out, 1);
  }
  AppendBytes<uint32_t>(&out, 0x06054b50);
  AppendBytes<uint16_t>(&out, 0);
  AppendBytes<uint16_t>(&out, 0);
  AppendBytes<uint16_t>(&out, zip64_end ? 0xffff : members.size());
  AppendBytes<uint16_t>(&out, zip64_end ? 0xffff : members.size());
  AppendBytes<uint32_t>(&out, zip64_end ? kMax32 : directory.size());
  AppendBytes<uint32_t>(&out, zip64_end ? kMax32 : directory_offset);
  AppendBytes<uint16_t>(&out, comment.size());
  out += std::string(comment);
  return out;
}

// Where the first central directory entry starts.
inline size_t DirectoryOffset(const std::string& zip) { return zip.find("PK\x01\x02"); }

}  // namespace shapeid

#endif  // SHAPEID_CORE_IO_ZIP_TESTING_H_
