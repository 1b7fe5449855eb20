#include "server/cloud_assembler.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <type_traits>
#include <utility>

#include "absl/strings/str_cat.h"
#include "core/status_macros.h"

namespace shapeid {
namespace {

constexpr bool kHostBigEndian = __BYTE_ORDER__ == __ORDER_BIG_ENDIAN__;
constexpr char kAxisNames[3] = {'x', 'y', 'z'};
// A point cut by a chunk's end is held until it is whole: this bounds that buffer (real
// sensors' points are tens of bytes).
constexpr uint32_t kMaxPointStep = 1 << 16;

size_t TypeBytes(PointLayout::Type type) { return type == PointLayout::Type::kFloat64 ? 8 : 4; }

// One coordinate of type T at `p`, byte-swapped when kSwap, rounded to float.
template <typename T, bool kSwap>
inline float Read(const char* p) {
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
  T value;
  std::memcpy(&value, &bits, sizeof(T));
  return static_cast<float>(value);
}

inline float ReadAny(const char* p, PointLayout::Type type, bool swap) {
  if (type == PointLayout::Type::kFloat64) {
    return swap ? Read<double, true>(p) : Read<double, false>(p);
  }
  return swap ? Read<float, true>(p) : Read<float, false>(p);
}

// Decodes `count` points `step` bytes apart into `out`; returns the points written (fewer
// than `count` when non-finite ones are dropped).
template <typename T, bool kSwap>
size_t DecodeSameType(const char* in, size_t count, size_t step, const uint32_t offsets[3],
                      bool drop_nonfinite, float* out) {
  size_t written = 0;
  for (size_t i = 0; i < count; ++i, in += step) {
    const float x = Read<T, kSwap>(in + offsets[0]);
    const float y = Read<T, kSwap>(in + offsets[1]);
    const float z = Read<T, kSwap>(in + offsets[2]);
    out[3 * written] = x;
    out[3 * written + 1] = y;
    out[3 * written + 2] = z;
    written += !drop_nonfinite || (std::isfinite(x) && std::isfinite(y) && std::isfinite(z));
  }
  return written;
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
  if (layout.width != 0 && layout.row_step != 0 &&
      uint64_t{layout.row_step} < uint64_t{layout.width} * layout.point_step) {
    return absl::InvalidArgumentError(absl::StrCat("point layout: row_step ", layout.row_step,
                                                   " is less than width ", layout.width,
                                                   " x point_step ", layout.point_step));
  }
  if ((layout.width == 0) != (layout.row_step == 0)) {
    return absl::InvalidArgumentError(
        absl::StrCat("point layout: width ", layout.width, " and row_step ", layout.row_step,
                     " go together (both 0 for rows without padding)"));
  }
  return absl::OkStatus();
}

absl::Status CloudAssembler::Start(uint64_t expected_points, const WireCloudFormat& format) {
  SHAPEID_RETURN_IF_ERROR(ValidatePointLayout(format.layout));
  if (expected_points > max_points_) {
    return absl::ResourceExhaustedError(absl::StrCat("the cloud announces ", expected_points,
                                                     " points, more than the limit of ",
                                                     max_points_, " (max_points_per_cloud)"));
  }
  started_ = true;
  expected_points_ = expected_points;
  format_ = format;
  sent_ = 0;
  partial_point_.clear();
  row_offset_ = 0;
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
      xyz[old_size + i] = Read<float, true>(bytes.data() + 4 * i);  // the wire is little-endian
    }
  }
}

void CloudAssembler::Decode(const char* bytes, size_t count) {
  const PointLayout& layout = format_.layout;
  std::vector<float>& xyz = cloud_.mutable_xyz();
  const size_t old_size = xyz.size();
  xyz.resize(old_size + 3 * count);
  float* out = xyz.data() + old_size;
  const bool swap = layout.big_endian != kHostBigEndian;
  const uint32_t offsets[3] = {layout.xyz[0].offset, layout.xyz[1].offset, layout.xyz[2].offset};
  const PointLayout::Type type = layout.xyz[0].type;
  size_t written;
  if (layout.xyz[1].type == type && layout.xyz[2].type == type) {
    const bool f64 = type == PointLayout::Type::kFloat64;
    const bool drop = layout.drop_nonfinite;
    const size_t step = layout.point_step;
    written = f64 ? (swap ? DecodeSameType<double, true>(bytes, count, step, offsets, drop, out)
                          : DecodeSameType<double, false>(bytes, count, step, offsets, drop, out))
                  : (swap ? DecodeSameType<float, true>(bytes, count, step, offsets, drop, out)
                          : DecodeSameType<float, false>(bytes, count, step, offsets, drop, out));
  } else {
    written = 0;
    for (size_t i = 0; i < count; ++i, bytes += layout.point_step) {
      for (int a = 0; a < 3; ++a) {
        out[3 * written + a] = ReadAny(bytes + offsets[a], layout.xyz[a].type, swap);
      }
      const float* p = out + 3 * written;
      written += !layout.drop_nonfinite ||
                 (std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2]));
    }
  }
  xyz.resize(old_size + 3 * written);
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
    // of a still-empty cloud (undefined behaviour even for 0 bytes).
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
  if (expected_points_ != 0 && sent_ != expected_points_) {
    return absl::InvalidArgumentError(
        absl::StrCat("the header announced ", expected_points_, " points but ", sent_, " arrived"));
  }
  return std::move(cloud_);
}

}  // namespace shapeid
