#include "server/cloud_assembler.h"

#include <algorithm>
#include <cstring>
#include <utility>

#include "absl/strings/str_cat.h"
#include "core/status_macros.h"

namespace shapeid {

absl::Status CloudAssembler::Start(uint64_t expected_points) {
  if (expected_points > max_points_) {
    return absl::ResourceExhaustedError(absl::StrCat("the cloud announces ", expected_points,
                                                     " points, more than the limit of ",
                                                     max_points_, " (max_points_per_cloud)"));
  }
  started_ = true;
  expected_points_ = expected_points;
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

absl::Status CloudAssembler::Append(absl::string_view xyz_bytes) {
  if (!started_) {
    return absl::InvalidArgumentError("points arrived before the header that starts a cloud");
  }
  if (xyz_bytes.size() % 12 != 0) {
    return absl::InvalidArgumentError(
        absl::StrCat("a point chunk of ", xyz_bytes.size(),
                     " bytes is not a whole number of points (12 bytes each: float32 x y z)"));
  }
  const size_t added = xyz_bytes.size() / 12;
  // Empty chunks are allowed; returning here also keeps memcpy away from the null data()
  // of a still-empty cloud (undefined behaviour even for 0 bytes; UBSan caught it).
  if (added == 0) return absl::OkStatus();
  if (cloud_.size() + added > max_points_) {
    return absl::ResourceExhaustedError(
        absl::StrCat("the cloud has more than the limit of ", max_points_, " points (",
                     cloud_.size() + added, " received so far; max_points_per_cloud)"));
  }
  std::vector<float>& xyz = cloud_.mutable_xyz();
  const size_t old_size = xyz.size();
  if (xyz.size() + 3 * added > xyz.capacity()) {
    // Grows geometrically, as the vector would, but with the memory held first.
    const size_t points = cloud_.size() + added;
    const size_t capacity = xyz.capacity() / 3;
    SHAPEID_RETURN_IF_ERROR(
        Reserve(std::min(max_points_, std::max({points, 2 * capacity, size_t{4096}}))));
  }
  xyz.resize(old_size + 3 * added);
  static_assert(sizeof(float) == 4);
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
  std::memcpy(xyz.data() + old_size, xyz_bytes.data(), xyz_bytes.size());
#else
  for (size_t i = 0; i < 3 * added; ++i) {  // the wire is little-endian
    const auto* b = reinterpret_cast<const unsigned char*>(xyz_bytes.data()) + 4 * i;
    const uint32_t bits =
        uint32_t{b[0]} | uint32_t{b[1]} << 8 | uint32_t{b[2]} << 16 | uint32_t{b[3]} << 24;
    std::memcpy(&xyz[old_size + i], &bits, 4);
  }
#endif
  return absl::OkStatus();
}

absl::StatusOr<PointCloud> CloudAssembler::Finish() {
  if (!started_) return absl::InvalidArgumentError("no cloud was started");
  started_ = false;
  if (expected_points_ != 0 && cloud_.size() != expected_points_) {
    return absl::InvalidArgumentError(absl::StrCat("the header announced ", expected_points_,
                                                   " points but ", cloud_.size(), " arrived"));
  }
  return std::move(cloud_);
}

}  // namespace shapeid
