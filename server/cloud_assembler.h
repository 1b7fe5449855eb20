#ifndef SHAPEID_SERVER_CLOUD_ASSEMBLER_H_
#define SHAPEID_SERVER_CLOUD_ASSEMBLER_H_

#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "core/point_cloud.h"
#include "server/memory_budget.h"

namespace shapeid {

// Builds one point cloud from the PointChunk messages of a stream: packed little-endian
// float32 xyz, 12 bytes per point, any number of chunks of any size. gRPC-free, so the
// service and its tests share it. Not thread-safe (one per stream).
//
// With a memory budget, every byte the cloud's storage takes is held from it for `caller`
// until the next Start or the assembler's end (the cloud Finish returns is still in use
// meanwhile), and a cloud that would pass the budget is refused.
class CloudAssembler {
 public:
  explicit CloudAssembler(size_t max_points, MemoryBudget* budget = nullptr,
                          std::string caller = "")
      : max_points_(max_points), budget_(budget), caller_(std::move(caller)) {}

  // Starts a new cloud. `expected_points` (0: unknown) is checked by Finish and reserves
  // memory; over the limit or the memory budget it is ResourceExhausted at once, before any
  // point arrives.
  absl::Status Start(uint64_t expected_points);

  // Appends one chunk. InvalidArgument if its size is not a multiple of 12 bytes;
  // ResourceExhausted (with the numbers) once the cloud passes the limit or the budget.
  absl::Status Append(absl::string_view xyz_bytes);

  // The cloud received since Start; InvalidArgument if it has fewer points than announced.
  // Finiteness and the other section-0 checks are the descriptor's (core/point_cloud.h).
  absl::StatusOr<PointCloud> Finish();

  bool started() const { return started_; }
  size_t points() const { return cloud_.size(); }
  size_t max_points() const { return max_points_; }
  // Bytes held from the budget now.
  size_t held_bytes() const { return memory_.bytes(); }

 private:
  // Makes room for `points` points in all, holding the memory from the budget first.
  absl::Status Reserve(size_t points);

  size_t max_points_;
  MemoryBudget* budget_;
  std::string caller_;
  MemoryBudget::Grant memory_;
  bool started_ = false;
  uint64_t expected_points_ = 0;
  PointCloud cloud_;
};

}  // namespace shapeid

#endif  // SHAPEID_SERVER_CLOUD_ASSEMBLER_H_
