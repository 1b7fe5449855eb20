#ifndef SHAPEID_CORE_IO_ZIP_ARCHIVE_H_
#define SHAPEID_CORE_IO_ZIP_ARCHIVE_H_

// Internal to core/io: reading members of a zip archive held in memory, as the .npz reader
// needs. Every error message starts with the archive's `name`, then ": byte offset N: ".

#include <cstdint>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"

namespace shapeid {

// True when `contents` starts with a zip local file header (PK\3\4) or, for an empty archive,
// an end-of-central-directory record (PK\5\6).
bool IsZip(absl::string_view contents);

// One entry of the central directory, with its ZIP64 values already filled in.
struct ZipMember {
  std::string name;           // as stored: raw bytes, not necessarily UTF-8
  uint64_t record = 0;        // byte offset of its central directory entry
  uint32_t flags = 0;         // general purpose bit flags (bit 0: encrypted)
  uint32_t method = 0;        // compression method: 0 stored, 8 deflate
  uint32_t crc = 0;           // CRC-32 of the uncompressed data
  uint64_t compressed = 0;    // size of the data in the archive
  uint64_t uncompressed = 0;  // size once inflated
  uint64_t local_header = 0;  // byte offset of its local file header
};

// Clauses that end the messages about an archive as a whole, telling the user what the file
// should be (each after "; "); empty clauses are left out.
struct ZipHints {
  absl::string_view not_a_zip;  // e.g. "a .npz file is a zip of .npy arrays"
  absl::string_view empty;      // e.g. "a .npz file holds .npy arrays"
};

// The members of `archive`, in central directory order, found through the end-of-central-
// directory record (searched in the last 64 KiB, past any comment) and, when present, the
// ZIP64 locator and record. Only the central directory is read: member data is checked by
// ReadZipMember.
// Errors:
//  - InvalidArgument: no end-of-central-directory record, a ZIP64 locator or record out of
//    bounds or with a wrong signature, a central directory past the end of the archive or
//    holding fewer entries than announced, an entry with a wrong signature or whose name, extra
//    field and comment overrun the directory, a 0xFFFFFFFF size or offset without its ZIP64
//    extra field (or one too short), an archive without members;
//  - Unimplemented: split (multi-disk) archives.
absl::StatusOr<std::vector<ZipMember>> ListZipMembers(absl::string_view archive,
                                                      absl::string_view name,
                                                      const ZipHints& hints = {});

// The uncompressed bytes of `member`, one of ListZipMembers(archive, ...): a view into
// `archive` for a stored member, else the member inflated into *buffer (which the view then
// refers to). The local file header must name the member; the data must match its CRC-32.
// Deflate errors start with ZipMemberLabel(name, member) rather than `name`.
// Errors:
//  - InvalidArgument: a local header out of bounds, with a wrong signature or another name;
//    data past the end of the archive; a stored member whose two sizes differ; a deflated
//    member claiming more than deflate can reach (1032:1, refused before allocating);
//    corrupt, short or long deflate data; a CRC-32 mismatch;
//  - Unimplemented: encrypted members, compression methods other than stored (0) and
//    deflate (8), named in the message.
absl::StatusOr<absl::string_view> ReadZipMember(absl::string_view archive, const ZipMember& member,
                                                absl::string_view name, std::string* buffer);

// "<name>:<member name>" (C-escaped), the name that messages about a member's contents start
// with.
std::string ZipMemberLabel(absl::string_view name, const ZipMember& member);

}  // namespace shapeid

#endif  // SHAPEID_CORE_IO_ZIP_ARCHIVE_H_
