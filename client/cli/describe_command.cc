#include "client/cli/describe_command.h"

#include <cmath>
#include <cstdint>
#include <memory>
#include <utility>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "core/descriptor.h"
#include "core/descriptor_registry.h"
#include "core/io/point_cloud_reader.h"
#include "core/status_macros.h"

namespace shapeid {
namespace {

void AppendFloat(std::string* out, float value) {
  char buffer[32];
  const int n = std::snprintf(buffer, sizeof buffer, "%.9g", static_cast<double>(value));
  out->append(buffer, static_cast<size_t>(n));
}

// The length of the valid UTF-8 sequence at the start of `s`, or 0 (RFC 3629: no overlong
// forms, no surrogates, nothing above U+10FFFF).
size_t Utf8SequenceLength(absl::string_view s) {
  const auto byte = [&](size_t i) { return static_cast<unsigned char>(s[i]); };
  const unsigned char b0 = byte(0);
  size_t len;
  unsigned char lo = 0x80, hi = 0xBF;  // bounds for the second byte
  if (b0 < 0x80) return 1;
  if (b0 >= 0xC2 && b0 <= 0xDF) {
    len = 2;
  } else if (b0 >= 0xE0 && b0 <= 0xEF) {
    len = 3;
    if (b0 == 0xE0) lo = 0xA0;
    if (b0 == 0xED) hi = 0x9F;
  } else if (b0 >= 0xF0 && b0 <= 0xF4) {
    len = 4;
    if (b0 == 0xF0) lo = 0x90;
    if (b0 == 0xF4) hi = 0x8F;
  } else {
    return 0;
  }
  if (s.size() < len) return 0;
  if (byte(1) < lo || byte(1) > hi) return 0;
  for (size_t i = 2; i < len; ++i) {
    if (byte(i) < 0x80 || byte(i) > 0xBF) return 0;
  }
  return len;
}

absl::Status DescribeFile(const Descriptor& descriptor, const std::string& file,
                          const DescribeOptions& options, std::vector<float>* values) {
  ReadOptions read_options;
  read_options.drop_non_finite = options.drop_non_finite;
  SHAPEID_ASSIGN_OR_RETURN(const ReadResult read, ReadPointCloud(file, read_options));
  return descriptor.Compute(read.cloud, values);
}

}  // namespace

std::string JsonString(absl::string_view text) {
  std::string out = "\"";
  out.reserve(text.size() + 2);
  while (!text.empty()) {
    const unsigned char c = static_cast<unsigned char>(text[0]);
    switch (c) {
      case '"':
        out += "\\\"";
        break;
      case '\\':
        out += "\\\\";
        break;
      case '\b':
        out += "\\b";
        break;
      case '\f':
        out += "\\f";
        break;
      case '\n':
        out += "\\n";
        break;
      case '\r':
        out += "\\r";
        break;
      case '\t':
        out += "\\t";
        break;
      default:
        if (c < 0x20) {
          char buffer[8];
          std::snprintf(buffer, sizeof buffer, "\\u%04x", c);
          out += buffer;
        } else {
          const size_t len = Utf8SequenceLength(text);
          if (len == 0) {
            out += "\\ufffd";
            text.remove_prefix(1);
            continue;
          }
          out.append(text.data(), len);
          text.remove_prefix(len);
          continue;
        }
    }
    text.remove_prefix(1);
  }
  out += '"';
  return out;
}

std::string FormatTextLine(absl::string_view file, absl::Span<const float> values) {
  std::string line(file);
  line.reserve(file.size() + 16 * values.size() + 1);
  for (float v : values) {
    line += ' ';
    AppendFloat(&line, v);
  }
  line += '\n';
  return line;
}

std::string FormatJsonLine(absl::string_view file, absl::string_view spec,
                           absl::Span<const float> values) {
  std::string line = absl::StrCat("{\"file\":", JsonString(file), ",\"spec\":", JsonString(spec),
                                  ",\"dimension\":", values.size(), ",\"descriptor\":[");
  for (size_t i = 0; i < values.size(); ++i) {
    if (i > 0) line += ',';
    // Descriptor::Compute never yields a non-finite value; should one slip through, JSON has
    // no spelling for it.
    if (std::isfinite(values[i])) {
      AppendFloat(&line, values[i]);
    } else {
      line += "null";
    }
  }
  line += "]}\n";
  return line;
}

std::string FileErrorLine(absl::string_view file, const absl::Status& status) {
  absl::string_view message = status.message();
  if (absl::StartsWith(message, absl::StrCat(file, ": "))) message.remove_prefix(file.size() + 2);
  return absl::StrCat("shapeid: ", file, ": ", message, "\n");
}

int RunDescribe(const DescribeOptions& options, std::FILE* out, std::FILE* err) {
  if (!options.local) {
    std::fputs(
        "shapeid: describe without --local needs the shapeid server, which arrives with "
        "the gRPC service; pass --local to compute in this process\n",
        err);
    return kExitUsage;
  }
  absl::StatusOr<std::unique_ptr<Descriptor>> descriptor = CreateDescriptor(options.spec);
  if (!descriptor.ok()) {
    std::fputs(absl::StrCat("shapeid: --spec \"", options.spec,
                            "\": ", descriptor.status().message(), "\n")
                   .c_str(),
               err);
    return kExitUsage;
  }
  const std::string canonical_spec = (*descriptor)->spec().ToString();

  bool failed = false;
  std::vector<float> values;
  std::string line;
  for (const std::string& file : options.files) {
    const absl::Status status = DescribeFile(**descriptor, file, options, &values);
    if (!status.ok()) {
      failed = true;
      std::fflush(out);  // keeps the two streams in file order on a terminal
      line = FileErrorLine(file, status);
      std::fwrite(line.data(), 1, line.size(), err);
      continue;
    }
    line = options.format == OutputFormat::kJson ? FormatJsonLine(file, canonical_spec, values)
                                                 : FormatTextLine(file, values);
    std::fwrite(line.data(), 1, line.size(), out);
  }
  if (std::fflush(out) != 0 || std::ferror(out)) {
    std::fputs("shapeid: cannot write the output\n", err);
    return kExitSomeFilesFailed;
  }
  return failed ? kExitSomeFilesFailed : kExitOk;
}

std::string DescribeHelpFooter() {
  return absl::StrCat(
      "Descriptor kinds (--spec KIND or KIND:param=value,...; omitted parameters take the\n"
      "defaults shown):\n",
      DescribeRegistry(),
      "\n"
      "Files: .pcd (PCD v0.7: ascii, binary, binary_compressed), .ply (ascii, binary little or\n"
      "big endian; vertices), .off (a mesh, sampled to 2,048 points, area-weighted, seeded),\n"
      ".xyz / .txt (x y z per line, blank- or comma-separated), .csv (comma or semicolon).\n"
      "Coordinates are recentred on the bounding box before conversion to float; every\n"
      "descriptor is translation invariant.\n"
      "\n"
      "Output: text prints one line per file, the file name and then the values (%.9g, which\n"
      "round-trips float); json prints one JSON object per line:\n"
      "  {\"file\":...,\"spec\":<canonical spec>,\"dimension\":N,\"descriptor\":[...]}\n"
      "\n"
      "Exit status: 0 every file described; 1 some file failed (one line each on stderr, the\n"
      "others are still described); 2 usage error or bad --spec (no file is read).\n"
      "\n"
      "Examples:\n"
      "  shapeid describe --local chair.pcd\n"
      "  shapeid describe --local --spec rphsd:refs=cross7,bins=10 a.pcd b.xyz\n"
      "  shapeid describe --local --spec comsd:grid=50 --format json models/*.pcd > d.jsonl\n"
      "  shapeid describe --local --drop-nonfinite --spec 'rphsd:refs=[0,0,0;1,0,0;0,1,0]' "
      "kinect.pcd\n");
}

}  // namespace shapeid
