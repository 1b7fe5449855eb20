#ifndef SHAPEID_CORE_IO_CLOUD_ACCUMULATOR_H_
#define SHAPEID_CORE_IO_CLOUD_ACCUMULATOR_H_

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "core/io/read_options.h"

namespace shapeid {

// Internal to core/io: collects the points a reader decodes, in double, together with the
// bounding box of the finite ones and where in the file each extreme came from, then applies
// ReadOptions in Finish. Every reader goes through it, so recentering and dropping behave the
// same for every format.
class CloudAccumulator {
 public:
  // `name` (the file) and `where_label` ("line", "byte offset") only shape error messages.
  CloudAccumulator(absl::string_view name, absl::string_view where_label);

  void Reserve(size_t points) { xyz_.reserve(3 * points); }
  size_t size() const { return xyz_.size() / 3; }

  // `where` locates the point in the file (its line or byte offset), for messages.
  void Add(double x, double y, double z, uint64_t where);

  // Drops non-finite points if asked, shifts by the box centre if asked, converts to float.
  // InvalidArgument, naming the file and the point's location, when a coordinate does not fit
  // in a float after the shift (it would become infinite).
  absl::StatusOr<ReadResult> Finish(const ReadOptions& options) &&;

 private:
  std::string name_;
  std::string where_label_;
  std::vector<double> xyz_;
  size_t finite_ = 0;
  double min_[3] = {0, 0, 0};
  double max_[3] = {0, 0, 0};
  uint64_t min_where_[3] = {0, 0, 0};
  uint64_t max_where_[3] = {0, 0, 0};
};

}  // namespace shapeid

#endif  // SHAPEID_CORE_IO_CLOUD_ACCUMULATOR_H_
