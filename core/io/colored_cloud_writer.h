#ifndef SHAPEID_CORE_IO_COLORED_CLOUD_WRITER_H_
#define SHAPEID_CORE_IO_COLORED_CLOUD_WRITER_H_

// Clouds with a color per point, to look at (a scene's objects colored by label) in Open3D,
// MeshLab, CloudCompare or PCL's viewer.

#include <array>
#include <cstdint>
#include <string>

#include "absl/status/status.h"
#include "absl/strings/string_view.h"
#include "absl/types/span.h"
#include "core/point_cloud.h"

namespace shapeid {

enum class ColoredCloudFormat {
  // Binary little-endian PLY: one vertex element, float x y z, uchar red green blue.
  kPly,
  // PCD v0.7, DATA binary, PCL's PointXYZRGB layout: FIELDS x y z rgb, TYPE F F F U, the
  // color packed as 0x00RRGGBB; WIDTH n, HEIGHT 1.
  kPcd,
};

using Rgb = std::array<uint8_t, 3>;  // red, green, blue

// The bytes of a file holding `cloud` with colors[i] for point i (colors.size() must be
// cloud.size()). `comment` (one line, no newline) goes in the header. Little-endian hosts.
std::string EncodeColoredCloud(const PointCloud& cloud, absl::Span<const Rgb> colors,
                               ColoredCloudFormat format, absl::string_view comment);

// The format a path's extension names: ".ply" or ".pcd"; InvalidArgument otherwise.
absl::Status ColoredCloudFormatOf(const std::string& path, ColoredCloudFormat* format);

}  // namespace shapeid

#endif  // SHAPEID_CORE_IO_COLORED_CLOUD_WRITER_H_
