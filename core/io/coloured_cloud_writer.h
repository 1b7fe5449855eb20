#ifndef SHAPEID_CORE_IO_COLOURED_CLOUD_WRITER_H_
#define SHAPEID_CORE_IO_COLOURED_CLOUD_WRITER_H_

// Clouds with a colour per point, to look at (a scene's objects coloured by label) in Open3D,
// MeshLab, CloudCompare or PCL's viewer.

#include <array>
#include <cstdint>
#include <string>

#include "absl/status/status.h"
#include "absl/strings/string_view.h"
#include "absl/types/span.h"
#include "core/point_cloud.h"

namespace shapeid {

enum class ColouredCloudFormat {
  // Binary little-endian PLY: one vertex element, float x y z, uchar red green blue.
  kPly,
  // PCD v0.7, DATA binary, PCL's PointXYZRGB layout: FIELDS x y z rgb, TYPE F F F U, the
  // colour packed as 0x00RRGGBB; WIDTH n, HEIGHT 1.
  kPcd,
};

using Rgb = std::array<uint8_t, 3>;  // red, green, blue

// The bytes of a file holding `cloud` with colours[i] for point i (colours.size() must be
// cloud.size()). `comment` (one line, no newline) goes in the header. Little-endian hosts.
std::string EncodeColouredCloud(const PointCloud& cloud, absl::Span<const Rgb> colours,
                                ColouredCloudFormat format, absl::string_view comment);

// The format a path's extension names: ".ply" or ".pcd"; InvalidArgument otherwise.
absl::Status ColouredCloudFormatOf(const std::string& path, ColouredCloudFormat* format);

}  // namespace shapeid

#endif  // SHAPEID_CORE_IO_COLOURED_CLOUD_WRITER_H_
