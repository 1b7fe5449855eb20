#include "core/io/stl_reader.h"

#include <cstdint>
#include <cstring>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "core/io/cloud_accumulator.h"
#include "core/io/mesh_sampler.h"
#include "core/io/text_lines.h"
#include "core/status_macros.h"

namespace shapeid {
namespace {

constexpr size_t kHeaderBytes = 84;  // 80 bytes of header, then the uint32 triangle count
constexpr size_t kRecordBytes = 50;  // normal, 3 vertices (float32 x 12), uint16 attribute

uint32_t LoadLittle32(const char* p) {
  const auto* b = reinterpret_cast<const unsigned char*>(p);
  return static_cast<uint32_t>(b[0]) | static_cast<uint32_t>(b[1]) << 8 |
         static_cast<uint32_t>(b[2]) << 16 | static_cast<uint32_t>(b[3]) << 24;
}

double LoadFloat(const char* p) {
  const uint32_t bits = LoadLittle32(p);
  float f;
  std::memcpy(&f, &bits, sizeof f);
  return f;
}

absl::StatusOr<ReadResult> ParseBinary(absl::string_view contents, absl::string_view name,
                                       uint32_t count, const ReadOptions& options) {
  const bool sample = options.sample_points > 0;
  if (!sample) {  // the vertices, three per record
    const auto at = [](size_t v) {
      return kHeaderBytes + v / 3 * kRecordBytes + 12 + 12 * (v % 3);
    };
    return ReadPointsTwice(
        size_t{3} * count,
        [&](size_t v, double* p) {
          const char* xyz = contents.data() + at(v);
          for (int a = 0; a < 3; ++a) p[a] = LoadFloat(xyz + 4 * a);
        },
        at, name, "byte offset", options);
  }
  CloudAccumulator cloud(name, "byte offset");
  TriangleMesh mesh;
  if (!sample) cloud.Reserve(size_t{3} * count);  // the size was checked against the count
  std::vector<uint64_t> triangle(3);
  for (uint64_t t = 0; t < count; ++t) {
    const size_t record = kHeaderBytes + static_cast<size_t>(t) * kRecordBytes;
    for (size_t v = 0; v < 3; ++v) {
      const size_t at = record + 12 + 12 * v;
      const char* p = contents.data() + at;
      const double x = LoadFloat(p), y = LoadFloat(p + 4), z = LoadFloat(p + 8);
      if (sample) {
        triangle[v] = mesh.vertex_count();
        mesh.AddVertex(x, y, z);
      } else {
        cloud.Add(x, y, z, at);
      }
    }
    if (sample) mesh.AddPolygon(triangle, record);
  }
  if (sample) {
    SHAPEID_RETURN_IF_ERROR(
        mesh.Sample(options.sample_points, options.sample_seed, name, "byte offset", &cloud));
  }
  return std::move(cloud).Finish(options);
}

// The ascii file as tokens, with the line of the last one.
class Tokens {
 public:
  explicit Tokens(absl::string_view text) : lines_(text), words_(absl::string_view()) {}

  bool Next(absl::string_view* token) {
    while (!words_.Next(token)) {
      absl::string_view line;
      if (!lines_.Next(&line)) return false;
      words_ = Tokenizer(line);
      line_ = lines_.line_number();
    }
    return true;
  }
  // Drops the rest of the current line (a solid's name).
  void SkipLine() { words_ = Tokenizer(absl::string_view()); }
  uint64_t line() const { return line_; }

 private:
  LineReader lines_;
  Tokenizer words_;
  uint64_t line_ = 1;
};

class AsciiParser {
 public:
  AsciiParser(absl::string_view contents, absl::string_view name, const ReadOptions& options)
      : tokens_(contents), name_(name), options_(options), cloud_(name, "line") {}

  absl::StatusOr<ReadResult> Parse() && {
    absl::string_view token;
    tokens_.Next(&token);
    if (!absl::EqualsIgnoreCase(token, "solid")) {
      return Error(absl::StrCat("an ascii STL file starts with \"solid [name]\"; found ",
                                QuoteForMessage(token)));
    }
    while (true) {
      tokens_.SkipLine();  // the solid's name
      SHAPEID_RETURN_IF_ERROR(ReadSolid());
      if (!tokens_.Next(&token)) break;
      if (!absl::EqualsIgnoreCase(token, "solid")) {
        return Error(
            absl::StrCat("expected \"solid\" or the end of the file after endsolid, found ",
                         QuoteForMessage(token)));
      }
    }
    if (sample()) {
      SHAPEID_RETURN_IF_ERROR(
          mesh_.Sample(options_.sample_points, options_.sample_seed, name_, "line", &cloud_));
    }
    return std::move(cloud_).Finish(options_);
  }

 private:
  bool sample() const { return options_.sample_points > 0; }

  absl::Status Error(absl::string_view message) const {
    return absl::InvalidArgumentError(
        absl::StrCat(name_, ": line ", tokens_.line(), ": ", message));
  }

  absl::Status Expect(const char* keyword) {
    absl::string_view token;
    if (!tokens_.Next(&token)) {
      return Error(absl::StrCat("the file ends where \"", keyword, "\" was expected"));
    }
    if (!absl::EqualsIgnoreCase(token, keyword)) {
      return Error(absl::StrCat("expected \"", keyword, "\", found ", QuoteForMessage(token)));
    }
    return absl::OkStatus();
  }

  absl::Status Numbers(const char* what, double v[3]) {
    for (int a = 0; a < 3; ++a) {
      absl::string_view token;
      if (!tokens_.Next(&token)) {
        return Error(absl::StrCat("the file ends inside a ", what, " (x y z)"));
      }
      if (!ParseDouble(token, &v[a])) {
        return Error(absl::StrCat(what, " ", std::string(1, "xyz"[a]), " value ",
                                  QuoteForMessage(token), " is not a number"));
      }
    }
    return absl::OkStatus();
  }

  // The facets of one solid, up to and including its endsolid line.
  absl::Status ReadSolid() {
    absl::string_view token;
    while (true) {
      if (!tokens_.Next(&token)) {
        return Error("the file ends inside a solid, before its \"endsolid\"");
      }
      if (absl::EqualsIgnoreCase(token, "endsolid")) {
        tokens_.SkipLine();
        return absl::OkStatus();
      }
      if (!absl::EqualsIgnoreCase(token, "facet")) {
        return Error(
            absl::StrCat("expected \"facet\" or \"endsolid\", found ", QuoteForMessage(token)));
      }
      const uint64_t facet_line = tokens_.line();
      double v[3];
      SHAPEID_RETURN_IF_ERROR(Expect("normal"));
      SHAPEID_RETURN_IF_ERROR(Numbers("normal", v));
      SHAPEID_RETURN_IF_ERROR(Expect("outer"));
      SHAPEID_RETURN_IF_ERROR(Expect("loop"));
      for (size_t k = 0;; ++k) {
        if (!tokens_.Next(&token)) return Error("the file ends inside a facet's loop");
        if (absl::EqualsIgnoreCase(token, "endloop")) {
          if (k == 3) break;
          return Error(absl::StrCat("the facet on line ", facet_line, " has ", k,
                                    " vertices; STL facets are triangles (3)"));
        }
        if (!absl::EqualsIgnoreCase(token, "vertex")) {
          return Error(
              absl::StrCat("expected \"vertex\" or \"endloop\", found ", QuoteForMessage(token)));
        }
        if (k == 3) {
          return Error(absl::StrCat("the facet on line ", facet_line,
                                    " has a fourth vertex; STL facets are triangles (3)"));
        }
        SHAPEID_RETURN_IF_ERROR(Numbers("vertex", v));
        if (sample()) {
          triangle_[k] = mesh_.vertex_count();
          mesh_.AddVertex(v[0], v[1], v[2]);
        } else {
          cloud_.Add(v[0], v[1], v[2], tokens_.line());
        }
      }
      SHAPEID_RETURN_IF_ERROR(Expect("endfacet"));
      if (sample()) mesh_.AddPolygon(triangle_, facet_line);
    }
  }

  Tokens tokens_;
  absl::string_view name_;
  const ReadOptions& options_;
  CloudAccumulator cloud_;
  TriangleMesh mesh_;
  std::vector<uint64_t> triangle_ = std::vector<uint64_t>(3);
};

}  // namespace

namespace {

// What a binary file of the header's triangle count would weigh; 0 for a file shorter than
// the header.
uint64_t BinarySizeOfCount(absl::string_view contents) {
  if (contents.size() < kHeaderBytes) return 0;
  return kHeaderBytes + uint64_t{kRecordBytes} * LoadLittle32(contents.data() + 80);
}

}  // namespace

bool HasStlSignature(absl::string_view contents) {
  if (contents.size() >= kHeaderBytes && BinarySizeOfCount(contents) == contents.size()) {
    return true;
  }
  return absl::StartsWithIgnoreCase(contents, "solid") &&
         (contents.size() == 5 || IsBlank(contents[5]) || contents[5] == '\n' ||
          contents[5] == '\r');
}

absl::StatusOr<ReadResult> ParseStl(absl::string_view contents, absl::string_view name,
                                    const ReadOptions& options) {
  const uint64_t binary_size = BinarySizeOfCount(contents);
  const uint32_t count = contents.size() >= kHeaderBytes ? LoadLittle32(contents.data() + 80) : 0;
  if (contents.size() >= kHeaderBytes && binary_size == contents.size()) {
    return ParseBinary(contents, name, count, options);
  }
  size_t start = 0;
  while (start < contents.size() && (IsBlank(contents[start]) || contents[start] == '\n')) {
    ++start;
  }
  const bool solid = absl::StartsWithIgnoreCase(contents.substr(start), "solid");
  const bool text = contents.find('\0') == absl::string_view::npos;
  if (solid && text) return AsciiParser(contents, name, options).Parse();
  // Binary files from real exporters break the count rule both ways (as VTK's reader notes):
  // trailing bytes after the records, or a count of 0 or garbage. Read the records the count
  // promises when the file holds them, else every whole record the file holds.
  if (contents.size() >= kHeaderBytes && count > 0 && binary_size <= contents.size()) {
    return ParseBinary(contents.substr(0, binary_size), name, count, options);
  }
  if (contents.size() > kHeaderBytes && (contents.size() - kHeaderBytes) % kRecordBytes == 0) {
    const uint64_t records = (contents.size() - kHeaderBytes) / kRecordBytes;
    return ParseBinary(contents, name, static_cast<uint32_t>(records), options);
  }

  const std::string size = absl::StrCat("the file has ", contents.size(), " bytes");
  if (contents.size() < kHeaderBytes) {
    return absl::InvalidArgumentError(absl::StrCat(
        name, ": byte offset 0: neither ascii STL (which starts with \"solid\") nor binary STL ",
        "(84 bytes or more); ", size));
  }
  return absl::InvalidArgumentError(absl::StrCat(
      name, ": byte offset 80: ",
      solid ? "starts with \"solid\" but holds NUL bytes, so it is not ascii STL; as binary STL, "
            : "neither ascii STL (which starts with \"solid\") nor binary STL: ",
      "its header announces ", count, " triangles, which need 84 + 50 * ", count, " = ",
      binary_size, " bytes, but ", size));
}

}  // namespace shapeid
