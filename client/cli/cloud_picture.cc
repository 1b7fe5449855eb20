#include "client/cli/cloud_picture.h"

#include <zlib.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "absl/strings/escaping.h"
#include "absl/strings/str_cat.h"

namespace shapeid {
namespace {

constexpr std::array<std::array<uint8_t, 3>, kPictureColors> MakePalette() {
  std::array<std::array<uint8_t, 3>, kPictureColors> p{};
  p[kPictureBackground] = {255, 255, 255};
  p[kPictureFrame] = {209, 213, 219};
  constexpr int kNear[3] = {17, 45, 110};
  constexpr int kFar[3] = {165, 196, 236};
  for (int s = 0; s < kPictureShades; ++s) {
    for (int c = 0; c < 3; ++c) {
      p[kPictureNearest + s][c] =
          static_cast<uint8_t>(kNear[c] + (kFar[c] - kNear[c]) * s / (kPictureShades - 1));
    }
  }
  return p;
}

// One view's axes: screen right, screen up and towards the viewer, as (axis, sign) pairs.
struct ViewAxes {
  int right, right_sign, up, up_sign, depth, depth_sign;
};
constexpr ViewAxes kViews[3] = {
    {0, 1, 1, 1, 2, 1},   // front: x right, y up, +z nearest
    {2, -1, 1, 1, 0, 1},  // side: -z right, y up, +x nearest
    {0, 1, 2, -1, 1, 1},  // top: x right, -z up, +y nearest
};

void AppendBigEndian(std::string& out, uint32_t value) {
  for (int shift = 24; shift >= 0; shift -= 8) out += static_cast<char>((value >> shift) & 0xFF);
}

// A PNG chunk: length, type, data, CRC-32 of type and data.
void AppendChunk(std::string& out, absl::string_view type, absl::string_view data) {
  AppendBigEndian(out, static_cast<uint32_t>(data.size()));
  const size_t start = out.size();
  absl::StrAppend(&out, type, data);
  const auto* bytes = reinterpret_cast<const Bytef*>(out.data() + start);
  AppendBigEndian(out,
                  static_cast<uint32_t>(crc32(0, bytes, static_cast<uInt>(out.size() - start))));
}

// RenderCloudViews, with the points' own colors when `colors` is not empty.
CloudPicture RenderViews(const PointCloud& cloud, absl::Span<const uint8_t> colors,
                         const CloudPictureOptions& options) {
  const int view = std::max(8, options.view_pixels);
  const int gap = std::max(0, options.gap_pixels);
  const int splat = std::clamp(options.point_pixels, 1, view / 4);
  CloudPicture picture;
  picture.width = 3 * view + 2 * gap;
  picture.height = view;
  picture.pixels.assign(static_cast<size_t>(picture.width) * picture.height, kPictureBackground);
  const auto set = [&](int x, int y, uint8_t index) {
    picture.pixels[static_cast<size_t>(y) * picture.width + x] = index;
  };
  for (int v = 0; v < 3; ++v) {
    const int left = v * (view + gap);
    for (int i = 0; i < view; ++i) {
      set(left + i, 0, kPictureFrame);
      set(left + i, view - 1, kPictureFrame);
      set(left, i, kPictureFrame);
      set(left + view - 1, i, kPictureFrame);
    }
  }

  double lo[3], hi[3];
  for (int a = 0; a < 3; ++a) {
    lo[a] = std::numeric_limits<double>::infinity();
    hi[a] = -std::numeric_limits<double>::infinity();
  }
  const float* xyz = cloud.data();
  const auto finite = [&](size_t i) {
    return std::isfinite(xyz[3 * i]) && std::isfinite(xyz[3 * i + 1]) &&
           std::isfinite(xyz[3 * i + 2]);
  };
  for (size_t i = 0; i < cloud.size(); ++i) {
    if (!finite(i)) continue;
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], static_cast<double>(xyz[3 * i + a]));
      hi[a] = std::max(hi[a], static_cast<double>(xyz[3 * i + a]));
    }
  }
  if (!(lo[0] <= hi[0])) return picture;  // no finite point

  double extent = 0;
  double center[3];
  for (int a = 0; a < 3; ++a) {
    extent = std::max(extent, hi[a] - lo[a]);
    center[a] = 0.5 * (lo[a] + hi[a]);
  }
  // Inside the frame, a one-pixel margin, and room for the splat at the far edge.
  const int inner = view - 4 - splat;
  const double scale = extent > 0 ? inner / extent : 0.0;
  std::vector<float> depth(static_cast<size_t>(view) * view);
  for (int v = 0; v < 3; ++v) {
    const ViewAxes& axes = kViews[v];
    const int left = v * (view + gap);
    std::fill(depth.begin(), depth.end(), -std::numeric_limits<float>::infinity());
    const double depth_span = hi[axes.depth] - lo[axes.depth];
    for (size_t i = 0; i < cloud.size(); ++i) {
      if (!finite(i)) continue;
      const double r = axes.right_sign * (xyz[3 * i + axes.right] - center[axes.right]);
      const double u = axes.up_sign * (xyz[3 * i + axes.up] - center[axes.up]);
      const double d = axes.depth_sign * (xyz[3 * i + axes.depth] - center[axes.depth]);
      // Top-left corner of the splat; r = u = 0 is the view's center.
      const int x0 = 2 + static_cast<int>(std::floor(0.5 * inner + r * scale));
      const int y0 = 2 + static_cast<int>(std::floor(0.5 * inner - u * scale));
      // 0 nearest, 1 farthest.
      const double far = depth_span > 0 ? std::clamp(0.5 - d / depth_span, 0.0, 1.0) : 0.0;
      const uint8_t shade =
          colors.empty()
              ? static_cast<uint8_t>(kPictureNearest + std::lround(far * (kPictureShades - 1)))
              : colors[i];
      for (int dy = 0; dy < splat; ++dy) {
        for (int dx = 0; dx < splat; ++dx) {
          const int x = std::clamp(x0 + dx, 1, view - 2);
          const int y = std::clamp(y0 + dy, 1, view - 2);
          float& nearest = depth[static_cast<size_t>(y) * view + x];
          if (d > nearest) {
            nearest = static_cast<float>(d);
            set(left + x, y, shade);
          }
        }
      }
    }
  }
  return picture;
}

}  // namespace

const std::array<std::array<uint8_t, 3>, kPictureColors> kCloudPalette = MakePalette();

CloudPicture RenderCloudViews(const PointCloud& cloud, const CloudPictureOptions& options) {
  return RenderViews(cloud, {}, options);
}

CloudPicture RenderColoredCloudViews(const PointCloud& cloud, absl::Span<const uint8_t> colors,
                                     const CloudPictureOptions& options) {
  return RenderViews(cloud, colors, options);
}

std::string EncodePng(const CloudPicture& picture) { return EncodePng(picture, kCloudPalette); }

std::string EncodePng(const CloudPicture& picture,
                      absl::Span<const std::array<uint8_t, 3>> palette) {
  std::string png("\x89PNG\r\n\x1a\n", 8);
  std::string header;
  AppendBigEndian(header, static_cast<uint32_t>(picture.width));
  AppendBigEndian(header, static_cast<uint32_t>(picture.height));
  header += std::string("\x08\x03\x00\x00\x00", 5);  // 8 bits, indexed, deflate, filter 0, -
  AppendChunk(png, "IHDR", header);
  std::string colors;
  for (const auto& rgb : palette) colors.append(reinterpret_cast<const char*>(rgb.data()), 3);
  AppendChunk(png, "PLTE", colors);

  // Every row starts with its filter type, 0 (none): runs of background compress well as
  // they are.
  std::string rows;
  rows.reserve(static_cast<size_t>(picture.width + 1) * picture.height);
  for (int y = 0; y < picture.height; ++y) {
    rows += '\0';
    rows.append(reinterpret_cast<const char*>(picture.pixels.data()) +
                    static_cast<size_t>(y) * picture.width,
                static_cast<size_t>(picture.width));
  }
  uLongf size = compressBound(static_cast<uLong>(rows.size()));
  std::string compressed(size, '\0');
  if (compress2(reinterpret_cast<Bytef*>(compressed.data()), &size,
                reinterpret_cast<const Bytef*>(rows.data()), static_cast<uLong>(rows.size()),
                Z_BEST_COMPRESSION) != Z_OK) {
    return "";
  }
  compressed.resize(size);
  AppendChunk(png, "IDAT", compressed);
  AppendChunk(png, "IEND", "");
  return png;
}

std::string PngDataUri(absl::string_view png) {
  return absl::StrCat("data:image/png;base64,", absl::Base64Escape(png));
}

}  // namespace shapeid
