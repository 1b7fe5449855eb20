#include "server/wire/point_layout.h"

#include <cmath>
#include <cstring>
#include <string>

#include "absl/strings/str_cat.h"

namespace shapeid {
namespace {

constexpr char kAxisNames[3] = {'x', 'y', 'z'};
// A point cut by a chunk's end is held until it is whole: this bounds that buffer (real
// sensors' points are tens of bytes).
constexpr uint32_t kMaxPointStep = 1 << 16;

// A sensor's coordinate is 0 or of a magnitude in [2^-40, 2^40] (a picometre to a billion
// km); bytes read in the wrong order or width land outside about two times in three.
constexpr double kPlausibleMin = 0x1p-40;
constexpr double kPlausibleMax = 0x1p40;
// The survey stops once every exchanged reading has this many coordinates (1,024 points
// without non-finite ones), or after kSurveyMaxPoints points.
constexpr uint64_t kSurveyValues = 3 * 1024;
constexpr uint64_t kSurveyMaxPoints = 1 << 16;

size_t TypeBytes(PointLayout::Type type) { return type == PointLayout::Type::kFloat64 ? 8 : 4; }

PointLayout::Type OtherType(PointLayout::Type type) {
  return type == PointLayout::Type::kFloat64 ? PointLayout::Type::kFloat32
                                             : PointLayout::Type::kFloat64;
}

// The value of `type` at `p` in the given byte order, whatever the host's.
double ReadValue(const char* p, PointLayout::Type type, bool big_endian) {
  const size_t size = TypeBytes(type);
  uint64_t bits = 0;
  for (size_t k = 0; k < size; ++k) {
    bits = (bits << 8) | static_cast<uint8_t>(p[big_endian ? k : size - 1 - k]);
  }
  if (size == 4) {
    const uint32_t bits32 = static_cast<uint32_t>(bits);
    float value;
    std::memcpy(&value, &bits32, 4);
    return value;
  }
  double value;
  std::memcpy(&value, &bits, 8);
  return value;
}

bool Implausible(double v) {
  const double magnitude = std::abs(v);
  return v != 0 && (magnitude < kPlausibleMin || magnitude > kPlausibleMax);
}

}  // namespace

bool PointLayout::is_packed_float32() const {
  const PointLayout packed;
  if (point_step != packed.point_step || big_endian) return false;  // the default is little-endian
  for (int a = 0; a < 3; ++a) {
    if (xyz[a].offset != packed.xyz[a].offset || xyz[a].type != packed.xyz[a].type) return false;
  }
  return width == 0 || row_step == 0 || row_step == uint64_t{width} * point_step;
}

absl::Status ValidatePointLayout(const PointLayout& layout) {
  if (layout.point_step == 0 || layout.point_step > kMaxPointStep) {
    return absl::InvalidArgumentError(absl::StrCat("point layout: point_step ", layout.point_step,
                                                   " is outside [1, ", kMaxPointStep, "] bytes"));
  }
  for (int a = 0; a < 3; ++a) {
    const uint64_t end = uint64_t{layout.xyz[a].offset} + TypeBytes(layout.xyz[a].type);
    if (end > layout.point_step) {
      return absl::InvalidArgumentError(absl::StrCat(
          "point layout: ", std::string(1, kAxisNames[a]), " at offset ", layout.xyz[a].offset,
          " (", TypeBytes(layout.xyz[a].type), " bytes) ends past point_step ", layout.point_step));
    }
    for (int b = 0; b < a; ++b) {
      const uint64_t begin_a = layout.xyz[a].offset, begin_b = layout.xyz[b].offset;
      const uint64_t end_b = begin_b + TypeBytes(layout.xyz[b].type);
      if (begin_a < end_b && begin_b < end) {
        return absl::InvalidArgumentError(absl::StrCat(
            "point layout: ", std::string(1, kAxisNames[b]), " and ", std::string(1, kAxisNames[a]),
            " overlap (offsets ", begin_b, " and ", begin_a, ")"));
      }
    }
  }
  const uint64_t row_points_bytes = uint64_t{layout.width} * layout.point_step;
  if (layout.width != 0 && layout.row_step != 0 && layout.row_step < row_points_bytes) {
    return absl::InvalidArgumentError(absl::StrCat("point layout: row_step ", layout.row_step,
                                                   " is less than width ", layout.width,
                                                   " x point_step ", layout.point_step));
  }
  if ((layout.width == 0) != (layout.row_step == 0)) {
    return absl::InvalidArgumentError(
        absl::StrCat("point layout: width ", layout.width, " and row_step ", layout.row_step,
                     " go together (both 0 for rows without padding)"));
  }
  // Padding with room for a point is what the rows of points point_step too short look like.
  const uint64_t padding = layout.width == 0 ? 0 : layout.row_step - row_points_bytes;
  if (padding >= layout.point_step) {
    return absl::InvalidArgumentError(
        absl::StrCat("point layout: row_step ", layout.row_step, " leaves ", padding,
                     " bytes after width ", layout.width, " x point_step ", layout.point_step,
                     ", room for ", padding / layout.point_step,
                     " more points; rows pad by less than one point (is point_step right?)"));
  }
  return absl::OkStatus();
}

void LayoutSurvey::Reset(const PointLayout& layout) {
  layout_ = layout;
  points_ = 0;
  tallies_ = {};
  tallies_[kSwapped].applies = true;
  // Big-endian, a float64's first half read as a float32 is always plausible (its exponent
  // is the float64's divided by 8): the exchanged width is surveyed in little-endian only.
  tallies_[kOtherWidth].applies = !layout.big_endian;
  for (const PointLayout::Coordinate& c : layout.xyz) {
    if (c.offset + TypeBytes(OtherType(c.type)) > layout.point_step) {
      tallies_[kOtherWidth].applies = false;
    }
  }
}

bool LayoutSurvey::full() const {
  if (points_ >= kSurveyMaxPoints) return true;
  for (const Tally& tally : tallies_) {
    if (tally.applies && tally.values < kSurveyValues) return false;
  }
  return true;
}

void LayoutSurvey::Add(const char* bytes, size_t count) {
  for (size_t i = 0; i < count && !full(); ++i, ++points_, bytes += layout_.point_step) {
    for (const PointLayout::Coordinate& c : layout_.xyz) {
      const double declared = ReadValue(bytes + c.offset, c.type, layout_.big_endian);
      if (!std::isfinite(declared)) continue;
      double exchanged[kReadings];
      exchanged[kSwapped] = ReadValue(bytes + c.offset, c.type, !layout_.big_endian);
      exchanged[kOtherWidth] =
          tallies_[kOtherWidth].applies
              ? ReadValue(bytes + c.offset, OtherType(c.type), layout_.big_endian)
              : NAN;
      for (int r = 0; r < kReadings; ++r) {
        if (!std::isfinite(exchanged[r])) continue;
        Tally& tally = tallies_[r];
        ++tally.values;
        tally.declared_implausible += Implausible(declared);
        tally.implausible += Implausible(exchanged[r]);
      }
    }
  }
}

absl::Status LayoutSurvey::Verdict() const {
  for (int r = 0; r < kReadings; ++r) {
    const Tally& tally = tallies_[r];
    // Mis-declared: over a quarter implausible as declared, under a tenth as exchanged.
    if (!tally.applies || tally.values == 0 || 4 * tally.declared_implausible <= tally.values ||
        10 * tally.implausible >= tally.values) {
      continue;
    }
    const std::string counts =
        absl::StrCat(tally.declared_implausible, " of ", tally.values,
                     " coordinates are implausible (not 0 and outside [2^-40, 2^40]) as declared");
    if (r == kSwapped) {
      return absl::InvalidArgumentError(
          absl::StrCat("point layout: the points look byte-swapped: ", counts, " (is_bigendian ",
                       layout_.big_endian ? "true" : "false", "), ", tally.implausible, " read ",
                       layout_.big_endian ? "little" : "big", "-endian; is is_bigendian right?"));
    }
    bool all_float64 = true, all_float32 = true;
    for (const PointLayout::Coordinate& c : layout_.xyz) {
      all_float64 &= c.type == PointLayout::Type::kFloat64;
      all_float32 &= c.type == PointLayout::Type::kFloat32;
    }
    const char* what = all_float64   ? "FLOAT32 data declared FLOAT64"
                       : all_float32 ? "FLOAT64 data declared FLOAT32"
                                     : "data of the other float widths";
    return absl::InvalidArgumentError(absl::StrCat(
        "point layout: the points look like ", what, ": ", counts, ", ", tally.implausible,
        " read with FLOAT32 and FLOAT64 exchanged at the same offsets; is the "
        "datatype of x, y and z right?"));
  }
  return absl::OkStatus();
}

}  // namespace shapeid
