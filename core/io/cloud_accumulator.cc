#include "core/io/cloud_accumulator.h"

#include <sys/mman.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <utility>

#include "absl/strings/str_cat.h"

namespace shapeid {

std::vector<float> NewCloudBuffer(size_t floats) {
  std::vector<float> out;
  out.reserve(floats);
#ifdef MADV_HUGEPAGE
  // Advice only (the kernel may decline, e.g. when transparent huge pages are off); it covers
  // the whole 2 MiB pages inside the buffer.
  constexpr uintptr_t kHuge = uintptr_t{2} << 20;
  const auto begin = reinterpret_cast<uintptr_t>(out.data());
  const uintptr_t first = (begin + kHuge - 1) & ~(kHuge - 1);
  const uintptr_t last = (begin + floats * sizeof(float)) & ~(kHuge - 1);
  if (last > first) madvise(reinterpret_cast<void*>(first), last - first, MADV_HUGEPAGE);
#endif
  out.resize(floats);
  return out;
}

CloudAccumulator::CloudAccumulator(absl::string_view name, absl::string_view where_label)
    : name_(name), where_label_(where_label) {}

void CloudAccumulator::AddToBox(double x, double y, double z, uint64_t where) {
  const double p[3] = {x, y, z};
  if (finite_ == 0) {
    for (int a = 0; a < 3; ++a) {
      min_[a] = max_[a] = p[a];
      min_where_[a] = max_where_[a] = where;
    }
  } else {
    for (int a = 0; a < 3; ++a) {
      if (p[a] < min_[a]) {
        min_[a] = p[a];
        min_where_[a] = where;
      } else if (p[a] > max_[a]) {
        max_[a] = p[a];
        max_where_[a] = where;
      }
    }
  }
  ++finite_;
}

absl::StatusOr<ReadResult> CloudAccumulator::Finish(const ReadOptions& options) && {
  ReadResult result;
  if (options.recenter && finite_ > 0) {
    // Halves first: (min + max) can overflow a double; each half cannot.
    for (int a = 0; a < 3; ++a) result.offset[a] = min_[a] / 2 + max_[a] / 2;
  }
  // Only the extremes can overflow a float, so checking them checks every point.
  constexpr double kFloatMax = std::numeric_limits<float>::max();
  for (int a = 0; a < 3 && finite_ > 0; ++a) {
    const double hi = max_[a] - result.offset[a];
    const double lo = min_[a] - result.offset[a];
    if (hi > kFloatMax || lo < -kFloatMax) {
      const bool blame_hi = hi > kFloatMax;
      return cloud_internal::DoesNotFit(name_, where_label_,
                                        blame_hi ? max_where_[a] : min_where_[a], a,
                                        blame_hi ? max_[a] : min_[a], options);
    }
  }

  const size_t n = size();
  const bool drop = options.drop_non_finite && non_finite_ > 0;
  std::vector<float> out = NewCloudBuffer(3 * (drop ? finite_ : n));
  float* o = out.data();
  const double ox = result.offset.x(), oy = result.offset.y(), oz = result.offset.z();
  for (size_t i = 0; i < n; ++i) {
    const double* p = &xyz_[3 * i];
    if (drop && !(std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2]))) continue;
    o[0] = static_cast<float>(p[0] - ox);
    o[1] = static_cast<float>(p[1] - oy);
    o[2] = static_cast<float>(p[2] - oz);
    o += 3;
  }
  cloud_internal::Box box;
  box.non_finite = non_finite_;
  box.first_non_finite = first_non_finite_;
  cloud_internal::SetCounts(box, first_non_finite_where_, where_label_, drop, &result);
  result.cloud = PointCloud(std::move(out));
  return result;
}

namespace cloud_internal {

absl::Status DoesNotFit(absl::string_view name, absl::string_view where_label, uint64_t where,
                        int axis, double value, const ReadOptions& options) {
  return absl::InvalidArgumentError(
      absl::StrCat(name, ": ", where_label, " ", where, ": ", absl::string_view(&"xyz"[axis], 1),
                   " = ", value, " does not fit in a float",
                   options.recenter ? " even after recentering" : " (recentering is off)"));
}

void SetCounts(const Box& box, uint64_t first_where, absl::string_view where_label, bool dropped,
               ReadResult* result) {
  result->dropped_non_finite = dropped ? box.non_finite : 0;
  result->non_finite_points = box.non_finite;
  if (box.non_finite > 0) {
    result->first_non_finite = box.first_non_finite;
    result->first_non_finite_location = absl::StrCat(where_label, " ", first_where);
  }
}

}  // namespace cloud_internal

namespace {

template <bool kSwapped>
inline float LoadFloat(const char* p) {
  uint32_t bits;
  std::memcpy(&bits, p, sizeof bits);
  if (kSwapped) bits = __builtin_bswap32(bits);
  float f;
  std::memcpy(&f, &bits, sizeof f);
  return f;
}

template <bool kSwapped>
ReadResult ReadColumns(const FloatColumns& c, size_t count, absl::string_view where_label,
                       const ReadOptions& options) {
  const char* const x = c.axis[0];
  const char* const y = c.axis[1];
  const char* const z = c.axis[2];
  const uint64_t sx = c.stride[0], sy = c.stride[1], sz = c.stride[2];
  const auto finite = [](float u, float v, float w) {
    return std::isfinite(u) && std::isfinite(v) && std::isfinite(w);
  };

  // Pass 1: the box of the finite points, as CloudAccumulator::Add compares them (strictly,
  // from the first finite point), and the non-finite ones.
  size_t i = 0;
  size_t non_finite = 0, first_non_finite = 0;
  for (; i < count; ++i) {
    if (finite(LoadFloat<kSwapped>(x + i * sx), LoadFloat<kSwapped>(y + i * sy),
               LoadFloat<kSwapped>(z + i * sz))) {
      break;
    }
    if (non_finite++ == 0) first_non_finite = i;
  }
  float lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
  if (i < count) {
    lo[0] = hi[0] = LoadFloat<kSwapped>(x + i * sx);
    lo[1] = hi[1] = LoadFloat<kSwapped>(y + i * sy);
    lo[2] = hi[2] = LoadFloat<kSwapped>(z + i * sz);
  }
  for (++i; i < count; ++i) {
    const float px = LoadFloat<kSwapped>(x + i * sx);
    const float py = LoadFloat<kSwapped>(y + i * sy);
    const float pz = LoadFloat<kSwapped>(z + i * sz);
    if (!finite(px, py, pz)) {
      if (non_finite++ == 0) first_non_finite = i;
      continue;
    }
    lo[0] = px < lo[0] ? px : lo[0];
    hi[0] = px > hi[0] ? px : hi[0];
    lo[1] = py < lo[1] ? py : lo[1];
    hi[1] = py > hi[1] ? py : hi[1];
    lo[2] = pz < lo[2] ? pz : lo[2];
    hi[2] = pz > hi[2] ? pz : hi[2];
  }

  ReadResult result;
  if (options.recenter && non_finite < count) {
    for (int a = 0; a < 3; ++a) {
      result.offset[a] = static_cast<double>(lo[a]) / 2 + static_cast<double>(hi[a]) / 2;
    }
  }
  // Pass 2: the final cloud. |v - offset| <= (hi - lo) / 2 fits a float, so nothing can fail.
  const bool drop = options.drop_non_finite && non_finite > 0;
  std::vector<float> out = NewCloudBuffer(3 * (drop ? count - non_finite : count));
  float* o = out.data();
  const double ox = result.offset.x(), oy = result.offset.y(), oz = result.offset.z();
  for (size_t j = 0; j < count; ++j) {
    const float px = LoadFloat<kSwapped>(x + j * sx);
    const float py = LoadFloat<kSwapped>(y + j * sy);
    const float pz = LoadFloat<kSwapped>(z + j * sz);
    if (drop && !finite(px, py, pz)) continue;
    o[0] = static_cast<float>(static_cast<double>(px) - ox);
    o[1] = static_cast<float>(static_cast<double>(py) - oy);
    o[2] = static_cast<float>(static_cast<double>(pz) - oz);
    o += 3;
  }
  cloud_internal::Box box;
  box.non_finite = non_finite;
  box.first_non_finite = first_non_finite;
  cloud_internal::SetCounts(box, c.where + first_non_finite * c.where_step, where_label, drop,
                            &result);
  result.cloud = PointCloud(std::move(out));
  return result;
}

}  // namespace

ReadResult ReadFloatColumns(const FloatColumns& columns, size_t count,
                            absl::string_view where_label, const ReadOptions& options) {
  return columns.byte_swapped ? ReadColumns<true>(columns, count, where_label, options)
                              : ReadColumns<false>(columns, count, where_label, options);
}

}  // namespace shapeid
