#include "core/io/zip_archive.h"

#include <zlib.h>

#include <algorithm>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/escaping.h"
#include "absl/strings/str_cat.h"
#include "core/io/gzip.h"
#include "core/io/text_lines.h"
#include "core/status_macros.h"

namespace shapeid {
namespace {

constexpr uint32_t kEndSignature = 0x06054b50;
constexpr uint32_t kZip64LocatorSignature = 0x07064b50;
constexpr uint32_t kZip64EndSignature = 0x06064b50;
constexpr uint32_t kCentralSignature = 0x02014b50;
constexpr uint32_t kLocalSignature = 0x04034b50;
constexpr uint64_t kEndSize = 22;
constexpr uint64_t kCentralSize = 46;
constexpr uint64_t kLocalSize = 30;
// Deflate emits at most 258 bytes per 2 bits: no stream inflates by more than this.
constexpr uint64_t kMaxDeflateRatio = 1032;

absl::Status Invalid(absl::string_view name, uint64_t offset, absl::string_view what) {
  return absl::InvalidArgumentError(absl::StrCat(name, ": byte offset ", offset, ": ", what));
}

absl::Status Unimplemented(absl::string_view name, uint64_t offset, absl::string_view what) {
  return absl::UnimplementedError(absl::StrCat(name, ": byte offset ", offset, ": ", what));
}

// `what`, then "; " and the hint when there is one.
std::string WithHint(absl::string_view what, absl::string_view hint) {
  return hint.empty() ? std::string(what) : absl::StrCat(what, "; ", hint);
}

// The little-endian unsigned integer of n <= 8 bytes at p.
uint64_t Le(const char* p, int n) {
  uint64_t v = 0;
  for (int i = n - 1; i >= 0; --i) v = (v << 8) | static_cast<unsigned char>(p[i]);
  return v;
}

std::string MemberText(absl::string_view member) {
  return absl::StrCat("member \"", absl::CHexEscape(member), "\"");
}

// Fills the ZIP64 values of `m` (those stored as 0xFFFFFFFF) from its extra field.
absl::Status ReadZip64Extra(absl::string_view extra, uint64_t extra_at, absl::string_view name,
                            ZipMember* m) {
  uint64_t* wanted[3] = {nullptr, nullptr, nullptr};
  int n = 0;
  for (uint64_t* v : {&m->uncompressed, &m->compressed, &m->local_header}) {
    if (*v == 0xffffffffu) wanted[n++] = v;
  }
  if (n == 0) return absl::OkStatus();
  for (size_t i = 0; i + 4 <= extra.size();) {
    const uint64_t id = Le(extra.data() + i, 2);
    const uint64_t size = Le(extra.data() + i + 2, 2);
    if (size > extra.size() - i - 4) break;
    if (id == 1) {
      if (size < 8 * static_cast<uint64_t>(n)) {
        return Invalid(name, extra_at + i,
                       absl::StrCat(MemberText(m->name), ": its ZIP64 extra field has ", size,
                                    " bytes, too few for its ", n, " 64-bit sizes"));
      }
      for (int k = 0; k < n; ++k) *wanted[k] = Le(extra.data() + i + 4 + 8 * k, 8);
      return absl::OkStatus();
    }
    i += 4 + size;
  }
  return Invalid(name, extra_at,
                 absl::StrCat(MemberText(m->name),
                              ": sizes or offset of 0xFFFFFFFF but no ZIP64 extra field"));
}

}  // namespace

bool IsZip(absl::string_view contents) {
  return contents.substr(0, 4) == absl::string_view("PK\x03\x04", 4) ||
         contents.substr(0, 4) == absl::string_view("PK\x05\x06", 4);
}

absl::StatusOr<std::vector<ZipMember>> ListZipMembers(absl::string_view archive,
                                                      absl::string_view name,
                                                      const ZipHints& hints) {
  const uint64_t n = archive.size();
  const char* d = archive.data();
  const uint64_t lowest = n < kEndSize ? 0 : n - kEndSize - std::min<uint64_t>(n - kEndSize, 65535);
  uint64_t end = n;
  for (uint64_t i = n < kEndSize ? 0 : n - kEndSize + 1; i-- > lowest;) {
    if (Le(d + i, 4) == kEndSignature && i + kEndSize + Le(d + i + 20, 2) <= n) {
      end = i;
      break;
    }
  }
  if (end == n) {
    return Invalid(name, lowest,
                   WithHint(absl::StrCat("not a zip archive: no end-of-central-directory record ",
                                         "(PK\\5\\6) in its last ", n - lowest, " bytes"),
                            hints.not_a_zip));
  }
  uint64_t disk = Le(d + end + 4, 2), directory_disk = Le(d + end + 6, 2);
  uint64_t count = Le(d + end + 10, 2);
  uint64_t directory_size = Le(d + end + 12, 4), directory_offset = Le(d + end + 16, 4);
  uint64_t count_at = end + 10, directory_at = end + 12;
  if (end >= 20 && Le(d + end - 20, 4) == kZip64LocatorSignature) {
    const uint64_t locator = end - 20;
    const uint64_t z = Le(d + locator + 8, 8);
    if (Le(d + locator + 16, 4) > 1) {
      return Unimplemented(name, locator + 16,
                           "split (multi-disk) zip archives are not read; join them first");
    }
    if (z > n || n - z < 56) {
      return Invalid(name, locator + 8,
                     absl::StrCat("the ZIP64 locator points to offset ", z,
                                  ", past the end of the archive (", n, " bytes)"));
    }
    if (Le(d + z, 4) != kZip64EndSignature) {
      return Invalid(name, z,
                     absl::StrCat("expected the ZIP64 end-of-central-directory record ",
                                  "(PK\\6\\6), found ", QuoteForMessage(archive.substr(z, 4))));
    }
    disk = Le(d + z + 16, 4);
    directory_disk = Le(d + z + 20, 4);
    count = Le(d + z + 32, 8);
    directory_size = Le(d + z + 40, 8);
    directory_offset = Le(d + z + 48, 8);
    count_at = z + 32;
    directory_at = z + 40;
  }
  if (disk != 0 || directory_disk != 0) {
    return Unimplemented(name, end + 4,
                         "split (multi-disk) zip archives are not read; join them first");
  }
  if (directory_offset > n || directory_size > n - directory_offset) {
    return Invalid(
        name, directory_at,
        absl::StrCat("the central directory (", directory_size, " bytes at offset ",
                     directory_offset, ") runs past the end of the archive (", n, " bytes)"));
  }
  if (count == 0) return Invalid(name, count_at, WithHint("the archive is empty", hints.empty));
  std::vector<ZipMember> members;
  uint64_t pos = directory_offset;
  const uint64_t directory_end = directory_offset + directory_size;
  for (uint64_t i = 0; i < count; ++i) {
    if (directory_end - pos < kCentralSize) {
      return Invalid(
          name, pos,
          absl::StrCat("the central directory ends after ", i, " of its ", count, " entries"));
    }
    if (Le(d + pos, 4) != kCentralSignature) {
      return Invalid(name, pos,
                     absl::StrCat("expected a central directory entry (PK\\1\\2), found ",
                                  QuoteForMessage(archive.substr(pos, 4))));
    }
    ZipMember m;
    m.record = pos;
    m.flags = static_cast<uint32_t>(Le(d + pos + 8, 2));
    m.method = static_cast<uint32_t>(Le(d + pos + 10, 2));
    m.crc = static_cast<uint32_t>(Le(d + pos + 16, 4));
    m.compressed = Le(d + pos + 20, 4);
    m.uncompressed = Le(d + pos + 24, 4);
    m.local_header = Le(d + pos + 42, 4);
    const uint64_t name_length = Le(d + pos + 28, 2);
    const uint64_t extra_length = Le(d + pos + 30, 2);
    const uint64_t comment_length = Le(d + pos + 32, 2);
    const uint64_t record_size = kCentralSize + name_length + extra_length + comment_length;
    if (record_size > directory_end - pos) {
      return Invalid(name, pos + 28,
                     absl::StrCat("central directory entry ", i, "'s name, extra field and ",
                                  "comment run past the end of the central directory"));
    }
    m.name = std::string(archive.substr(pos + kCentralSize, name_length));
    const uint64_t extra_at = pos + kCentralSize + name_length;
    SHAPEID_RETURN_IF_ERROR(
        ReadZip64Extra(archive.substr(extra_at, extra_length), extra_at, name, &m));
    members.push_back(std::move(m));
    pos += record_size;
  }
  return members;
}

absl::StatusOr<absl::string_view> ReadZipMember(absl::string_view archive, const ZipMember& m,
                                                absl::string_view name, std::string* buffer) {
  const uint64_t n = archive.size();
  const std::string member = MemberText(m.name);
  if ((m.flags & 1) != 0) {
    return Unimplemented(name, m.record + 8,
                         absl::StrCat(member, " is encrypted; encrypted archives are not read"));
  }
  if (m.method != 0 && m.method != 8) {
    const char* method = m.method == 9    ? " (deflate64)"
                         : m.method == 12 ? " (bzip2)"
                         : m.method == 14 ? " (LZMA)"
                         : m.method == 93 ? " (zstd)"
                         : m.method == 95 ? " (xz)"
                                          : "";
    return Unimplemented(name, m.record + 10,
                         absl::StrCat(member, " is compressed with method ", m.method, method,
                                      "; stored (0) and deflate (8), as numpy writes, are read"));
  }
  if (m.local_header > n || n - m.local_header < kLocalSize) {
    return Invalid(name, m.record + 42,
                   absl::StrCat(member, ": its local header offset ", m.local_header,
                                " is past the end of the archive (", n, " bytes)"));
  }
  const char* local = archive.data() + m.local_header;
  if (Le(local, 4) != kLocalSignature) {
    return Invalid(name, m.local_header,
                   absl::StrCat(member, ": expected a local file header (PK\\3\\4), found ",
                                QuoteForMessage(archive.substr(m.local_header, 4))));
  }
  const uint64_t name_length = Le(local + 26, 2);
  const uint64_t data_start = m.local_header + kLocalSize + name_length + Le(local + 28, 2);
  if (data_start > n) {
    return Invalid(name, m.local_header + 26,
                   absl::StrCat(member, ": its local header runs past the end of the archive"));
  }
  const absl::string_view local_name = archive.substr(m.local_header + kLocalSize, name_length);
  if (local_name != m.name) {
    return Invalid(
        name, m.local_header + kLocalSize,
        absl::StrCat(member, ": its local header names it ", QuoteForMessage(local_name)));
  }
  if (m.compressed > n - data_start) {
    return Invalid(name, m.record + 20,
                   absl::StrCat(member, ": its ", m.compressed, " bytes at offset ", data_start,
                                " run past the end of the archive (", n, " bytes)"));
  }
  const absl::string_view raw = archive.substr(data_start, m.compressed);
  absl::string_view bytes = raw;
  if (m.method == 0) {
    if (m.uncompressed != m.compressed) {
      return Invalid(name, m.record + 20,
                     absl::StrCat(member, " is stored, yet its sizes differ (", m.compressed,
                                  " bytes stored, ", m.uncompressed, " bytes uncompressed)"));
    }
  } else {
    if (m.uncompressed > m.compressed * kMaxDeflateRatio + kMaxDeflateRatio) {
      return Invalid(name, m.record + 24,
                     absl::StrCat(member, " claims ", m.uncompressed, " bytes from ", m.compressed,
                                  " deflated bytes, more than deflate can reach (1032:1)"));
    }
    SHAPEID_ASSIGN_OR_RETURN(*buffer, InflateRaw(raw, m.uncompressed, ZipMemberLabel(name, m)));
    bytes = *buffer;
  }
  const uint32_t crc =
      static_cast<uint32_t>(crc32_z(0, reinterpret_cast<const Bytef*>(bytes.data()), bytes.size()));
  if (crc != m.crc) {
    return Invalid(name, m.record + 16,
                   absl::StrCat(member, ": its data's CRC-32 is 0x",
                                absl::Hex(crc, absl::kZeroPad8), ", the archive records 0x",
                                absl::Hex(m.crc, absl::kZeroPad8), " (the archive is corrupt)"));
  }
  return bytes;
}

std::string ZipMemberLabel(absl::string_view name, const ZipMember& member) {
  return absl::StrCat(name, ":", absl::CHexEscape(member.name));
}

}  // namespace shapeid
