#include "server/wire/cloud_assembler.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <type_traits>
#include <utility>

#include "absl/strings/str_cat.h"
#include "core/status_macros.h"

namespace shapeid {
namespace {

constexpr bool kHostBigEndian = __BYTE_ORDER__ == __ORDER_BIG_ENDIAN__;
constexpr char kAxisNames[3] = {'x', 'y', 'z'};

// The bits of one coordinate of type T at `p`, byte-swapped when kSwap.
template <typename T, bool kSwap>
inline auto ReadBits(const char* p) {
  using Bits = std::conditional_t<sizeof(T) == 4, uint32_t, uint64_t>;
  Bits bits;
  std::memcpy(&bits, p, sizeof(T));
  if constexpr (kSwap) {
    if constexpr (sizeof(T) == 4) {
      bits = __builtin_bswap32(bits);
    } else {
      bits = __builtin_bswap64(bits);
    }
  }
  return bits;
}

template <typename T, typename Bits>
inline T FromBits(Bits bits) {
  T value;
  std::memcpy(&value, &bits, sizeof(T));
  return value;
}

template <typename T, bool kSwap>
inline T ReadRaw(const char* p) {
  return FromBits<T>(ReadBits<T, kSwap>(p));
}

// True when float32 loses the finite `value` that rounded to `rounded`: beyond its range, or
// not 0 and below its smallest normal (float32 data declared FLOAT64 reads like this).
inline bool LostInFloat32(double value, float rounded) {
  const bool overflow = !std::isfinite(rounded);
  const bool underflow = (value != 0) & (std::abs(rounded) < std::numeric_limits<float>::min());
  return std::isfinite(value) & (overflow | underflow);
}

// A cheap superset of LostInFloat32 on a float64's bits: finite, not 0, and of a magnitude
// below float32's smallest normal or above its largest (one that rounds into range included).
inline bool MaybeLostInFloat32(uint64_t bits) {
  constexpr uint64_t kMagnitude = 0x7FFF'FFFF'FFFF'FFFF;
  constexpr uint64_t kFloatMin = 0x3810'0000'0000'0000;  // 2^-126 as a float64
  constexpr uint64_t kFloatMax = 0x47EF'FFFF'E000'0000;  // (2 - 2^-23) 2^127 as a float64
  constexpr uint64_t kInfinity = 0x7FF0'0000'0000'0000;
  const uint64_t magnitude = bits & kMagnitude;
  return (magnitude - 1 < kFloatMin - 1) | ((magnitude > kFloatMax) & (magnitude < kInfinity));
}

// One coordinate of `type` at `p`, rounded to float; `*lost` is set when float32 loses it.
inline float ReadAny(const char* p, PointLayout::Type type, bool swap, bool* lost) {
  if (type == PointLayout::Type::kFloat64) {
    const double value = swap ? ReadRaw<double, true>(p) : ReadRaw<double, false>(p);
    const float rounded = static_cast<float>(value);
    *lost |= LostInFloat32(value, rounded);
    return rounded;
  }
  return swap ? ReadRaw<float, true>(p) : ReadRaw<float, false>(p);
}

// Decodes `count` points `step` bytes apart into `out`; returns the points written (fewer
// than `count` when non-finite ones are dropped). `*lost`: whether float32 may have lost a
// FLOAT64 coordinate (MaybeLostInFloat32: the caller checks those points exactly).
template <typename T, bool kSwap>
size_t DecodeSameType(const char* in, size_t count, size_t step, const uint32_t offsets[3],
                      bool drop_nonfinite, float* out, bool* lost) {
  size_t written = 0;
  bool maybe_lost = false;
  for (size_t i = 0; i < count; ++i, in += step) {
    const auto bx = ReadBits<T, kSwap>(in + offsets[0]);
    const auto by = ReadBits<T, kSwap>(in + offsets[1]);
    const auto bz = ReadBits<T, kSwap>(in + offsets[2]);
    if constexpr (std::is_same_v<T, double>) {
      // Branch-free; clang refuses `|` between bools.
      maybe_lost |= MaybeLostInFloat32(bx);
      maybe_lost |= MaybeLostInFloat32(by);
      maybe_lost |= MaybeLostInFloat32(bz);
    }
    const float x = static_cast<float>(FromBits<T>(bx));
    const float y = static_cast<float>(FromBits<T>(by));
    const float z = static_cast<float>(FromBits<T>(bz));
    out[3 * written] = x;
    out[3 * written + 1] = y;
    out[3 * written + 2] = z;
    written += !drop_nonfinite || (std::isfinite(x) && std::isfinite(y) && std::isfinite(z));
  }
  *lost = maybe_lost;
  return written;
}

}  // namespace

absl::Status CloudAssembler::Start(uint64_t expected_points, const WireCloudFormat& format) {
  SHAPEID_RETURN_IF_ERROR(ValidatePointLayout(format.layout));
  if (expected_points > max_points_) {
    return absl::ResourceExhaustedError(absl::StrCat("the cloud announces ", expected_points,
                                                     " points, more than the limit of ",
                                                     max_points_, " (max_points_per_cloud)"));
  }
  if (format.layout.width != 0 && expected_points % format.layout.width != 0) {
    return absl::InvalidArgumentError(
        absl::StrCat("the cloud announces ", expected_points, " points, not whole rows of width ",
                     format.layout.width, " (an organized cloud is height x width points)"));
  }
  started_ = true;
  expected_points_ = expected_points;
  format_ = format;
  sent_ = 0;
  partial_point_.clear();
  row_offset_ = 0;
  survey_ = !format.layout.is_packed_float32();
  if (survey_) layout_survey_.Reset(format.layout);
  lost_coordinate_.reset();
  cloud_ = PointCloud();
  memory_.Release();
  return Reserve(expected_points);
}

absl::Status CloudAssembler::Reserve(size_t points) {
  std::vector<float>& xyz = cloud_.mutable_xyz();
  if (3 * points <= xyz.capacity()) return absl::OkStatus();
  if (budget_ != nullptr) {
    const size_t more = (3 * points - xyz.capacity()) * sizeof(float);
    if (memory_.bytes() == 0) {
      absl::StatusOr<MemoryBudget::Grant> grant =
          budget_->Reserve(caller_, more, "the cloud in transit");
      if (!grant.ok()) return grant.status();
      memory_ = *std::move(grant);
    } else if (absl::Status grown = memory_.Grow(more); !grown.ok()) {
      return grown;
    }
  }
  xyz.reserve(3 * points);
  return absl::OkStatus();
}

absl::Status CloudAssembler::Admit(size_t count) {
  if (sent_ + count > max_points_) {
    return absl::ResourceExhaustedError(absl::StrCat("the cloud has more than the limit of ",
                                                     max_points_, " points (", sent_ + count,
                                                     " received so far; max_points_per_cloud)"));
  }
  sent_ += count;
  points_received_ += count;
  const size_t points = cloud_.size() + count;
  if (3 * points > cloud_.mutable_xyz().capacity()) {
    // Grows geometrically, as the vector would, but with the memory held first.
    const size_t capacity = cloud_.mutable_xyz().capacity() / 3;
    SHAPEID_RETURN_IF_ERROR(
        Reserve(std::min(max_points_, std::max({points, 2 * capacity, size_t{4096}}))));
  }
  return absl::OkStatus();
}

void CloudAssembler::CopyPacked(absl::string_view bytes) {
  std::vector<float>& xyz = cloud_.mutable_xyz();
  const size_t old_size = xyz.size();
  xyz.resize(old_size + bytes.size() / 4);
  if constexpr (!kHostBigEndian) {
    std::memcpy(xyz.data() + old_size, bytes.data(), bytes.size());
  } else {
    for (size_t i = 0; i < bytes.size() / 4; ++i) {
      xyz[old_size + i] = ReadRaw<float, true>(bytes.data() + 4 * i);  // the wire is little-endian
    }
  }
}

void CloudAssembler::Decode(const char* bytes, size_t count) {
  const PointLayout& layout = format_.layout;
  if (survey_ && !layout_survey_.full()) layout_survey_.Add(bytes, count);
  std::vector<float>& xyz = cloud_.mutable_xyz();
  const size_t old_size = xyz.size();
  xyz.resize(old_size + 3 * count);
  float* out = xyz.data() + old_size;
  const bool swap = layout.big_endian != kHostBigEndian;
  const uint32_t offsets[3] = {layout.xyz[0].offset, layout.xyz[1].offset, layout.xyz[2].offset};
  const PointLayout::Type type = layout.xyz[0].type;
  size_t written;
  bool lost = false;
  if (layout.xyz[1].type == type && layout.xyz[2].type == type) {
    const bool f64 = type == PointLayout::Type::kFloat64;
    const bool drop = layout.drop_nonfinite;
    const size_t step = layout.point_step;
    const char* in = bytes;
    written =
        f64 ? (swap ? DecodeSameType<double, true>(in, count, step, offsets, drop, out, &lost)
                    : DecodeSameType<double, false>(in, count, step, offsets, drop, out, &lost))
            : (swap ? DecodeSameType<float, true>(in, count, step, offsets, drop, out, &lost)
                    : DecodeSameType<float, false>(in, count, step, offsets, drop, out, &lost));
  } else {
    written = 0;
    const char* in = bytes;
    for (size_t i = 0; i < count; ++i, in += layout.point_step) {
      for (int a = 0; a < 3; ++a) {
        out[3 * written + a] = ReadAny(in + offsets[a], layout.xyz[a].type, swap, &lost);
      }
      const float* p = out + 3 * written;
      written += !layout.drop_nonfinite ||
                 (std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2]));
    }
  }
  xyz.resize(old_size + 3 * written);
  if (lost && !lost_coordinate_.has_value()) FindLostCoordinate(bytes, count);
}

void CloudAssembler::FindLostCoordinate(const char* bytes, size_t count) {
  const PointLayout& layout = format_.layout;
  const bool swap = layout.big_endian != kHostBigEndian;
  for (size_t i = 0; i < count; ++i, bytes += layout.point_step) {
    for (int a = 0; a < 3; ++a) {
      if (layout.xyz[a].type != PointLayout::Type::kFloat64) continue;
      const char* p = bytes + layout.xyz[a].offset;
      const double value = swap ? ReadRaw<double, true>(p) : ReadRaw<double, false>(p);
      if (LostInFloat32(value, static_cast<float>(value))) {
        lost_coordinate_ = LostCoordinate{sent_ - count + i, a, value};
        return;
      }
    }
  }
}

absl::Status CloudAssembler::Append(absl::string_view bytes) {
  if (!started_) {
    return absl::InvalidArgumentError("points arrived before the header that starts a cloud");
  }
  const PointLayout& layout = format_.layout;
  const size_t begin = cloud_.xyz().size();
  if (layout.is_packed_float32() && !layout.drop_nonfinite) {
    if (bytes.size() % 12 != 0) {
      return absl::InvalidArgumentError(
          absl::StrCat("a point chunk of ", bytes.size(),
                       " bytes is not a whole number of points (12 bytes each: float32 x y z)"));
    }
    // Empty chunks are allowed; returning here also keeps memcpy away from the null data()
    // of a still-empty cloud (undefined behavior even for 0 bytes).
    if (bytes.empty()) return absl::OkStatus();
    SHAPEID_RETURN_IF_ERROR(Admit(bytes.size() / 12));
    CopyPacked(bytes);
  } else {
    const size_t step = layout.point_step;
    const size_t row_points_bytes = size_t{layout.width} * step;
    const bool padded = layout.row_step > row_points_bytes;
    while (!bytes.empty()) {
      if (padded && row_offset_ >= row_points_bytes) {  // the padding at a row's end
        const size_t skip = std::min(bytes.size(), layout.row_step - row_offset_);
        bytes.remove_prefix(skip);
        row_offset_ += skip;
        if (row_offset_ == layout.row_step) row_offset_ = 0;
        continue;
      }
      if (!partial_point_.empty() || bytes.size() < step) {  // a point cut by a chunk's end
        const size_t take = std::min(step - partial_point_.size(), bytes.size());
        partial_point_.append(bytes.data(), take);
        bytes.remove_prefix(take);
        if (partial_point_.size() < step) break;
        SHAPEID_RETURN_IF_ERROR(Admit(1));
        Decode(partial_point_.data(), 1);
        partial_point_.clear();
        if (padded) row_offset_ += step;
        continue;
      }
      size_t count = bytes.size() / step;
      if (padded) count = std::min(count, (row_points_bytes - row_offset_) / step);
      SHAPEID_RETURN_IF_ERROR(Admit(count));
      Decode(bytes.data(), count);
      bytes.remove_prefix(count * step);
      if (padded) row_offset_ += count * step;
    }
  }
  if (!format_.frame.is_identity()) {
    std::vector<float>& xyz = cloud_.mutable_xyz();
    ApplyRigidTransform(format_.frame, xyz.data() + begin, (xyz.size() - begin) / 3);
  }
  return absl::OkStatus();
}

absl::StatusOr<PointCloud> CloudAssembler::Finish() {
  if (!started_) return absl::InvalidArgumentError("no cloud was started");
  started_ = false;
  if (!partial_point_.empty()) {
    return absl::InvalidArgumentError(
        absl::StrCat("the points ended inside a point: ", partial_point_.size(), " of its ",
                     format_.layout.point_step, " bytes (point_step) arrived"));
  }
  const PointLayout& layout = format_.layout;
  if (layout.width != 0 && (sent_ % layout.width != 0 || row_offset_ != 0)) {
    // row_offset_ counts the bytes of a padded row; unpadded rows are their points.
    const uint64_t row_bytes =
        row_offset_ != 0 ? row_offset_ : (sent_ % layout.width) * layout.point_step;
    return absl::InvalidArgumentError(
        absl::StrCat("the points ended inside a row: ", row_bytes, " of its ", layout.row_step,
                     " bytes (row_step) arrived; an organized cloud (width ", layout.width,
                     ") is whole rows, padding included"));
  }
  if (expected_points_ != 0 && sent_ != expected_points_) {
    return absl::InvalidArgumentError(
        absl::StrCat("the header announced ", expected_points_, " points but ", sent_, " arrived"));
  }
  if (survey_) SHAPEID_RETURN_IF_ERROR(layout_survey_.Verdict());
  if (lost_coordinate_.has_value()) {
    const LostCoordinate& lost = *lost_coordinate_;
    const std::string where =
        absl::StrCat("point ", lost.point, ": ", std::string(1, kAxisNames[lost.axis]), " = ",
                     lost.value, " (FLOAT64)");
    if (std::abs(lost.value) > std::numeric_limits<float>::max()) {
      return absl::InvalidArgumentError(absl::StrCat(
          where, " does not fit in a float32 (|value| <= ", std::numeric_limits<float>::max(),
          "); subtract an offset first (every descriptor is translation invariant)"));
    }
    return absl::InvalidArgumentError(absl::StrCat(
        where, " is not 0 but below float32's smallest normal (", std::numeric_limits<float>::min(),
        "): float32 data declared FLOAT64 reads like this; is the datatype right?"));
  }
  return std::move(cloud_);
}

}  // namespace shapeid
