#ifndef SHAPEID_SERVER_WIRE_CLOUD_ASSEMBLER_H_
#define SHAPEID_SERVER_WIRE_CLOUD_ASSEMBLER_H_

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <utility>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "core/point_cloud.h"
#include "core/rigid_transform.h"
#include "server/runtime/memory_budget.h"
#include "server/wire/point_layout.h"

namespace shapeid {

// What a call's clouds are on the wire and how they are moved into the gallery's frame.
struct WireCloudFormat {
  PointLayout layout;
  RigidTransform frame;  // applied to every point as it is decoded
};

// Builds one point cloud from the PointChunk messages of a stream, decoding the call's layout
// into float32 x y z and applying its frame, any number of chunks of any size. gRPC-free, so
// the service and its tests share it. Not thread-safe (one per stream).
//
// With a memory budget, every byte the cloud's storage takes is held from it for `caller`
// until the next Start or the assembler's end (the cloud Finish returns is still in use
// meanwhile), and a cloud that would pass the budget is refused.
class CloudAssembler {
 public:
  explicit CloudAssembler(size_t max_points, MemoryBudget* budget = nullptr,
                          std::string caller = "")
      : max_points_(max_points), budget_(budget), caller_(std::move(caller)) {}

  // Starts a new cloud in `format` (validated here: InvalidArgument naming the field).
  // `expected_points` (0: unknown; points sent, before any are dropped) is checked by Finish
  // and reserves memory; over the limit or the memory budget it is ResourceExhausted at once,
  // before any point arrives; not whole rows of an organized cloud (width), InvalidArgument.
  absl::Status Start(uint64_t expected_points, const WireCloudFormat& format = {});

  // Appends one chunk. In the default layout InvalidArgument if its size is not a multiple of
  // 12 bytes; a declared layout's chunks may end inside a point or a row. ResourceExhausted
  // (with the numbers) once the points sent pass the limit or the cloud passes the budget.
  absl::Status Append(absl::string_view bytes);

  // The cloud received since Start; InvalidArgument if it has fewer points than announced,
  // the stream ended inside a point or inside a row of an organized cloud, a declared layout
  // other than the default looks mis-declared (LayoutSurvey), or a FLOAT64 coordinate is not
  // 0 and outside float32's normal range. Finiteness (unless dropped) and the other section-0
  // checks are the descriptor's (core/point_cloud.h).
  absl::StatusOr<PointCloud> Finish();

  bool started() const { return started_; }
  // Points kept in the current cloud.
  size_t points() const { return cloud_.size(); }
  // Points sent since the assembler was made, over every cloud, dropped ones included: the
  // call's count.
  uint64_t points_received() const { return points_received_; }
  size_t max_points() const { return max_points_; }
  // Bytes held from the budget now.
  size_t held_bytes() const { return memory_.bytes(); }

 private:
  // Makes room for `points` points in all, holding the memory from the budget first.
  absl::Status Reserve(size_t points);
  // Counts `count` more points sent against the limit and makes room for them.
  absl::Status Admit(size_t count);
  // Decodes `count` whole points at `bytes` (the layout's point_step apart) onto the cloud,
  // the last `count` points sent; surveys them and notes the first FLOAT64 coordinate lost in
  // float32.
  void Decode(const char* bytes, size_t count);
  // Notes the first coordinate of the `count` points at `bytes` that float32 loses.
  void FindLostCoordinate(const char* bytes, size_t count);
  // Appends packed float32 bytes as they are.
  void CopyPacked(absl::string_view bytes);

  size_t max_points_;
  MemoryBudget* budget_;
  std::string caller_;
  MemoryBudget::Grant memory_;
  bool started_ = false;
  uint64_t expected_points_ = 0;
  WireCloudFormat format_;
  size_t sent_ = 0;            // points sent in this cloud, dropped ones included
  std::string partial_point_;  // the bytes of a point cut by a chunk's end
  size_t row_offset_ = 0;      // bytes into the current row (padded rows only)
  bool survey_ = false;        // a declared layout other than the default is surveyed
  LayoutSurvey layout_survey_;
  // The first FLOAT64 coordinate that is not 0 and outside float32's normal range.
  struct LostCoordinate {
    uint64_t point = 0;  // counting every point sent
    int axis = 0;
    double value = 0;
  };
  std::optional<LostCoordinate> lost_coordinate_;
  uint64_t points_received_ = 0;
  PointCloud cloud_;
};

}  // namespace shapeid

#endif  // SHAPEID_SERVER_WIRE_CLOUD_ASSEMBLER_H_
