#include "core/io/gzip.h"

#include <zlib.h>

#include <algorithm>

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

// Output is produced this much at a time and appended, so memory grows with the data that
// really arrives, never with a size a header claims.
constexpr size_t kOutChunk = size_t{1} << 20;
// zlib counts input in uInt: at most this many bytes per call.
constexpr size_t kInChunk = size_t{1} << 30;

// Inflates one stream (a gzip member or a raw deflate stream) from the start of `in`,
// appending to `out`; `consumed` gets the compressed bytes it used. `base` is the stream's
// offset in the file, for messages. Stops, setting `*over` and returning OK, when `out` would
// pass `max_out` bytes.
absl::Status InflateStream(int window_bits, absl::string_view in, uint64_t base,
                           absl::string_view name, absl::string_view kind, size_t max_out,
                           std::string* out, size_t* consumed, bool* over) {
  *over = false;
  Inflater inflater(window_bits);
  if (!inflater.ok()) {
    return absl::ResourceExhaustedError(absl::StrCat(name, ": zlib cannot start inflating"));
  }
  z_stream& z = inflater.stream();
  z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(in.data()));
  size_t fed = std::min(in.size(), kInChunk);
  z.avail_in = static_cast<uInt>(fed);
  std::string buffer;
  buffer.resize(kOutChunk);
  int rc = Z_OK;
  while (rc != Z_STREAM_END) {
    if (z.avail_in == 0 && fed < in.size()) {
      const size_t more = std::min(in.size() - fed, kInChunk);
      z.avail_in = static_cast<uInt>(more);
      fed += more;
    }
    z.next_out = reinterpret_cast<Bytef*>(buffer.data());
    z.avail_out = static_cast<uInt>(buffer.size());
    rc = inflate(&z, Z_NO_FLUSH);
    const size_t produced = buffer.size() - z.avail_out;
    if (produced > max_out - std::min(max_out, out->size())) {
      *over = true;
      return absl::OkStatus();
    }
    out->append(buffer.data(), produced);
    const uint64_t where = base + z.total_in;
    if (rc == Z_MEM_ERROR) {
      return absl::ResourceExhaustedError(absl::StrCat(name, ": zlib ran out of memory"));
    }
    if (rc == Z_BUF_ERROR && produced == 0 && z.avail_in == 0 && fed == in.size()) {
      return absl::InvalidArgumentError(absl::StrCat(name, ": byte offset ", where, ": ", kind,
                                                     " ends early (the file is truncated)"));
    }
    if (rc != Z_OK && rc != Z_STREAM_END && rc != Z_BUF_ERROR) {
      return absl::InvalidArgumentError(absl::StrCat(name, ": byte offset ", where, ": corrupt ",
                                                     kind, z.msg != nullptr ? ": " : "",
                                                     z.msg != nullptr ? z.msg : ""));
    }
  }
  *consumed = z.total_in;
  return absl::OkStatus();
}

}  // namespace

bool IsGzip(absl::string_view contents) {
  // The magic, then compression method 8 (deflate), the only one gzip defines.
  return contents.size() >= 3 && static_cast<unsigned char>(contents[0]) == 0x1f &&
         static_cast<unsigned char>(contents[1]) == 0x8b &&
         static_cast<unsigned char>(contents[2]) == 0x08;
}

absl::StatusOr<std::string> Gunzip(absl::string_view contents, absl::string_view name,
                                   size_t max_bytes) {
  std::string out;
  size_t offset = 0;
  while (offset < contents.size()) {
    size_t consumed = 0;
    bool over = false;
    const absl::Status member = InflateStream(16 + MAX_WBITS, contents.substr(offset), offset, name,
                                              "gzip data", max_bytes, &out, &consumed, &over);
    if (!member.ok()) return member;
    if (over) {
      return absl::InvalidArgumentError(
          absl::StrCat(name, ": gzip data decompresses to more than ", max_bytes, " bytes"));
    }
    offset += consumed;
    if (offset == contents.size() || IsGzip(contents.substr(offset))) continue;
    // After the last member only zero padding is allowed (tape blocks, some tools' output);
    // anything else is a damaged next member, and reading on would drop the rest unsaid.
    const absl::string_view tail = contents.substr(offset);
    if (tail.find_first_not_of('\0') != absl::string_view::npos) {
      return absl::InvalidArgumentError(absl::StrCat(
          name, ": byte offset ", offset,
          ": data after the gzip stream is neither another gzip member nor zero padding"));
    }
    break;
  }
  return out;
}

absl::StatusOr<std::string> InflateRaw(absl::string_view contents, size_t size,
                                       absl::string_view name) {
  std::string out;
  out.reserve(std::min(size, size_t{64} << 20));
  size_t consumed = 0;
  bool over = false;
  const absl::Status status =
      InflateStream(-MAX_WBITS, contents, 0, name, "deflated data", size, &out, &consumed, &over);
  if (!status.ok()) return status;
  if (over) {
    return absl::InvalidArgumentError(
        absl::StrCat(name, ": deflated data is longer than its stated size of ", size, " bytes"));
  }
  if (out.size() != size) {
    return absl::InvalidArgumentError(absl::StrCat(name, ": deflated data is ", out.size(),
                                                   " bytes, not its stated size of ", size));
  }
  return out;
}

}  // namespace shapeid
