#ifndef SHAPEID_SERVER_CLOUD_ASSEMBLER_H_
#define SHAPEID_SERVER_CLOUD_ASSEMBLER_H_

#include <cstddef>
#include <cstdint>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "core/point_cloud.h"

namespace shapeid {

// Builds one point cloud from the PointChunk messages of a stream: packed little-endian
// float32 xyz, 12 bytes per point, any number of chunks of any size. gRPC-free, so the
// service and its tests share it. Not thread-safe (one per stream).
class CloudAssembler {
 public:
  explicit CloudAssembler(size_t max_points) : max_points_(max_points) {}

  // Starts a new cloud. `expected_points` (0: unknown) is checked by Finish and reserves
  // memory; over the limit it is ResourceExhausted at once, before any point arrives.
  absl::Status Start(uint64_t expected_points);

  // Appends one chunk. InvalidArgument if its size is not a multiple of 12 bytes;
  // ResourceExhausted (with the numbers) once the cloud passes the limit.
  absl::Status Append(absl::string_view xyz_bytes);

  // The cloud received since Start; InvalidArgument if it has fewer points than announced.
  // Finiteness and the other section-0 checks are the descriptor's (core/point_cloud.h).
  absl::StatusOr<PointCloud> Finish();

  bool started() const { return started_; }
  size_t points() const { return cloud_.size(); }
  size_t max_points() const { return max_points_; }

 private:
  size_t max_points_;
  bool started_ = false;
  uint64_t expected_points_ = 0;
  PointCloud cloud_;
};

}  // namespace shapeid

#endif  // SHAPEID_SERVER_CLOUD_ASSEMBLER_H_
