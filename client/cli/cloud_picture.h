#ifndef SHAPEID_CLIENT_CLI_CLOUD_PICTURE_H_
#define SHAPEID_CLIENT_CLI_CLOUD_PICTURE_H_

// Small pictures of point clouds for the eval report (eval_report.h): three orthographic
// views side by side, points shaded by depth, encoded here as an indexed-color PNG so that a
// page can embed it as a data: URI without any image library or external file.

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "absl/strings/string_view.h"
#include "absl/types/span.h"
#include "core/point_cloud.h"

namespace shapeid {

// Palette indices of a CloudPicture (kCloudPalette holds their colors).
inline constexpr uint8_t kPictureBackground = 0;  // white
inline constexpr uint8_t kPictureFrame = 1;       // the light grey border of each view
inline constexpr uint8_t kPictureNearest = 2;     // the darkest shade: the nearest points
inline constexpr int kPictureShades = 24;         // kPictureNearest .. kPictureNearest + 23
inline constexpr int kPictureColors = kPictureNearest + kPictureShades;
// The RGB color of each index: white, grey, then navy (near) to pale blue (far).
extern const std::array<std::array<uint8_t, 3>, kPictureColors> kCloudPalette;

struct CloudPictureOptions {
  int view_pixels = 96;  // each view is a square this wide and high, its frame included
  int gap_pixels = 6;    // background between two views
  int point_pixels = 2;  // side of the square each point is drawn as
};

// One palette index per pixel, row-major from the top-left corner.
struct CloudPicture {
  int width = 0;
  int height = 0;
  std::vector<uint8_t> pixels;  // width * height
  uint8_t at(int x, int y) const { return pixels[static_cast<size_t>(y) * width + x]; }
};

// Three views of `cloud`, left to right: front (x right, y up, seen from +z), side (-z right,
// y up, seen from +x) and top (x right, -z up, seen from +y). One scale for all three: the
// largest side of the cloud's bounding box spans the inside of a view, centered on the box's
// center, so proportions and the three views agree. A pixel shows its nearest point, darker
// the nearer (the shade spans the box's depth in that view). Non-finite points are skipped;
// a cloud without a finite point gives the empty frames. Sizes below 8 pixels count as 8.
CloudPicture RenderCloudViews(const PointCloud& cloud, const CloudPictureOptions& options = {});

// As RenderCloudViews, each point drawn in its own palette index, colors[i] for point i (one
// per point of `cloud`), instead of a shade of its depth; nearer points still hide farther
// ones. Indices 0 and 1 are the background and the views' frame.
CloudPicture RenderColoredCloudViews(const PointCloud& cloud, absl::Span<const uint8_t> colors,
                                     const CloudPictureOptions& options = {});

// `picture` as a PNG file: 8-bit indexed color with kCloudPalette, not interlaced, one IDAT
// chunk compressed by zlib. Empty only if zlib runs out of memory.
std::string EncodePng(const CloudPicture& picture);
// The same with `palette` (index -> RGB, at most 256, one for every index the picture uses).
std::string EncodePng(const CloudPicture& picture,
                      absl::Span<const std::array<uint8_t, 3>> palette);

// "data:image/png;base64,..." for an <img src>.
std::string PngDataUri(absl::string_view png);

}  // namespace shapeid

#endif  // SHAPEID_CLIENT_CLI_CLOUD_PICTURE_H_
