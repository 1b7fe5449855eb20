#include "core/io/gzip.h"

#include <zlib.h>

#include <algorithm>
#include <limits>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"

namespace shapeid {
namespace {

// zlib's stream, ended on every path out.
class Inflater {
 public:
  // window_bits: 16 + 15 for gzip, -15 for raw deflate.
  explicit Inflater(int window_bits) { ok_ = inflateInit2(&stream_, window_bits) == Z_OK; }
  ~Inflater() {
    if (ok_) inflateEnd(&stream_);
  }
  Inflater(const Inflater&) = delete;
  Inflater& operator=(const Inflater&) = delete;

  bool ok() const { return ok_; }
  z_stream& stream() { return stream_; }

 private:
  z_stream stream_{};
  bool ok_ = false;
};

// zlib counts in uInt: feed and drain at most this many bytes per call.
constexpr size_t kChunk = size_t{1} << 30;

absl::Status Corrupt(absl::string_view name, absl::string_view what, const z_stream& stream) {
  return absl::InvalidArgumentError(absl::StrCat(name, ": ", what, " at compressed byte offset ",
                                                 stream.total_in, stream.msg != nullptr ? ": " : "",
                                                 stream.msg != nullptr ? stream.msg : ""));
}

}  // namespace

bool IsGzip(absl::string_view contents) {
  return contents.size() >= 2 && static_cast<unsigned char>(contents[0]) == 0x1f &&
         static_cast<unsigned char>(contents[1]) == 0x8b;
}

absl::StatusOr<std::string> Gunzip(absl::string_view contents, absl::string_view name,
                                   size_t max_bytes) {
  std::string out;
  // A guess at the size (gzip's trailer holds it modulo 2^32): grows as needed.
  out.resize(std::min(max_bytes, std::max<size_t>(contents.size() * 4, 4096)));
  size_t used = 0;
  size_t consumed = 0;
  while (consumed < contents.size()) {
    Inflater inflater(16 + MAX_WBITS);
    if (!inflater.ok()) return absl::ResourceExhaustedError("zlib: cannot start inflating");
    z_stream& z = inflater.stream();
    const absl::string_view member = contents.substr(consumed);
    z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(member.data()));
    size_t fed = std::min(member.size(), kChunk);
    z.avail_in = static_cast<uInt>(fed);
    int rc = Z_OK;
    while (rc != Z_STREAM_END) {
      if (used == out.size()) {
        if (out.size() >= max_bytes) {
          return absl::InvalidArgumentError(
              absl::StrCat(name, ": decompresses to more than ", max_bytes, " bytes"));
        }
        out.resize(std::min(max_bytes, out.size() * 2));
      }
      z.next_out = reinterpret_cast<Bytef*>(&out[used]);
      const size_t room = std::min(out.size() - used, kChunk);
      z.avail_out = static_cast<uInt>(room);
      if (z.avail_in == 0 && fed < member.size()) {
        const size_t more = std::min(member.size() - fed, kChunk);
        z.avail_in = static_cast<uInt>(more);
        fed += more;
      }
      rc = inflate(&z, Z_NO_FLUSH);
      used += room - z.avail_out;
      if (rc == Z_BUF_ERROR && z.avail_in == 0 && fed == member.size()) {
        return Corrupt(name, "gzip data ends early", z);
      }
      if (rc != Z_OK && rc != Z_STREAM_END && rc != Z_BUF_ERROR) {
        return Corrupt(name, "corrupt gzip data", z);
      }
    }
    consumed += z.total_in;
    // Padding after the last member (some tools write zeros) ends the stream, as for gunzip.
    if (consumed < contents.size() && !IsGzip(contents.substr(consumed))) break;
  }
  out.resize(used);
  return out;
}

absl::StatusOr<std::string> InflateRaw(absl::string_view contents, size_t size,
                                       absl::string_view name) {
  Inflater inflater(-MAX_WBITS);
  if (!inflater.ok()) return absl::ResourceExhaustedError("zlib: cannot start inflating");
  z_stream& z = inflater.stream();
  std::string out(size, '\0');
  z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(contents.data()));
  size_t fed = std::min(contents.size(), kChunk);
  z.avail_in = static_cast<uInt>(fed);
  size_t used = 0;
  int rc = Z_OK;
  while (rc != Z_STREAM_END) {
    if (z.avail_in == 0 && fed < contents.size()) {
      const size_t more = std::min(contents.size() - fed, kChunk);
      z.avail_in = static_cast<uInt>(more);
      fed += more;
    }
    // One spare byte of room shows a stream longer than promised.
    char spare;
    const bool spare_room = used == size;
    z.next_out = reinterpret_cast<Bytef*>(spare_room ? &spare : &out[used]);
    const size_t room = spare_room ? 1 : std::min(size - used, kChunk);
    z.avail_out = static_cast<uInt>(room);
    rc = inflate(&z, Z_NO_FLUSH);
    const size_t produced = room - z.avail_out;
    if (spare_room && produced > 0) {
      return absl::InvalidArgumentError(
          absl::StrCat(name, ": deflated data is longer than its stated size of ", size, " bytes"));
    }
    used += produced;
    if (rc == Z_BUF_ERROR && z.avail_in == 0 && fed == contents.size()) {
      return Corrupt(name, "deflated data ends early", z);
    }
    if (rc != Z_OK && rc != Z_STREAM_END && rc != Z_BUF_ERROR) {
      return Corrupt(name, "corrupt deflated data", z);
    }
  }
  if (used != size) {
    return absl::InvalidArgumentError(
        absl::StrCat(name, ": deflated data is ", used, " bytes, not its stated size of ", size));
  }
  return out;
}

}  // namespace shapeid
