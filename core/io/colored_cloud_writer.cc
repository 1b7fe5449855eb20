#include "core/io/colored_cloud_writer.h"

#include <cstring>
#include <filesystem>

#include "absl/strings/str_cat.h"

namespace shapeid {

std::string EncodeColoredCloud(const PointCloud& cloud, absl::Span<const Rgb> colors,
                               ColoredCloudFormat format, absl::string_view comment) {
  const size_t n = cloud.size();
  const bool ply = format == ColoredCloudFormat::kPly;
  std::string out =
      ply ? absl::StrCat("ply\nformat binary_little_endian 1.0\ncomment ", comment,
                         "\nelement vertex ", n,
                         "\nproperty float x\nproperty float y\nproperty float z\nproperty "
                         "uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n")
          : absl::StrCat("# .PCD v0.7 - ", comment,
                         "\nVERSION 0.7\nFIELDS x y z rgb\nSIZE 4 4 4 4\nTYPE F F F U\n"
                         "COUNT 1 1 1 1\nWIDTH ",
                         n, "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS ", n, "\nDATA binary\n");
  const size_t header = out.size();
  const size_t step = ply ? 15 : 16;
  out.resize(header + n * step);
  char* at = out.data() + header;
  for (size_t i = 0; i < n; ++i, at += step) {
    std::memcpy(at, cloud.data() + 3 * i, 12);
    const Rgb& rgb = colors[i];
    if (ply) {
      std::memcpy(at + 12, rgb.data(), 3);
    } else {
      const uint32_t packed = (uint32_t{rgb[0]} << 16) | (uint32_t{rgb[1]} << 8) | rgb[2];
      std::memcpy(at + 12, &packed, 4);
    }
  }
  return out;
}

absl::Status ColoredCloudFormatOf(const std::string& path, ColoredCloudFormat* format) {
  const std::string extension = std::filesystem::path(path).extension().string();
  if (extension == ".ply") {
    *format = ColoredCloudFormat::kPly;
  } else if (extension == ".pcd") {
    *format = ColoredCloudFormat::kPcd;
  } else {
    return absl::InvalidArgumentError(
        absl::StrCat(path, ": a colored cloud is written as .ply or .pcd"));
  }
  return absl::OkStatus();
}

}  // namespace shapeid
