#ifndef SHAPEID_FUZZ_READER_FUZZER_H_
#define SHAPEID_FUZZ_READER_FUZZER_H_

#include <cmath>
#include <cstddef>
#include <cstdint>

#include "absl/status/status.h"
#include "absl/strings/match.h"
#include "absl/strings/string_view.h"
#include "core/io/point_cloud_reader.h"
#include "fuzz/fuzz_oracle.h"

namespace shapeid::fuzz {

// Parses `data` as `format` twice, with the defaults and with every option turned the other
// way (mesh sampling on, small, so an iteration stays fast), and checks what the readers
// promise in core/io/point_cloud_reader.h beyond "no crash, no undefined behavior":
//  - an error is InvalidArgument or Unimplemented and its message starts with the file name;
//  - a cloud read with drop_non_finite has only finite points, and counts what it dropped;
//  - the recentering offset is finite.
// A header announcing 10^12 points must fail, not allocate: libFuzzer's -malloc_limit_mb
// catches a reader that trusts it.
inline void FuzzReader(CloudFormat format, const uint8_t* data, size_t size) {
  const absl::string_view contents(reinterpret_cast<const char*>(data), size);
  ReadOptions options[2];
  options[1].drop_non_finite = true;
  options[1].recenter = false;
  options[1].sample_points = 64;
  options[1].sample_seed = size;
  options[0].sample_points = 0;  // meshes: the vertices
  for (const ReadOptions& o : options) {
    absl::StatusOr<ReadResult> read = ParsePointCloud(contents, format, "fuzz-input", o);
    if (!read.ok()) {
      const absl::StatusCode code = read.status().code();
      if (code != absl::StatusCode::kInvalidArgument && code != absl::StatusCode::kUnimplemented) {
        Fail("error code is neither InvalidArgument nor Unimplemented", read.status());
      }
      if (!absl::StartsWith(read.status().message(), "fuzz-input")) {
        Fail("error message does not start with the file name", read.status());
      }
      continue;
    }
    if (!read->offset.allFinite()) Fail("non-finite offset", absl::OkStatus());
    if (!o.drop_non_finite && read->dropped_non_finite != 0) {
      Fail("points dropped without drop_non_finite", absl::OkStatus());
    }
    if (o.drop_non_finite) {
      const float* xyz = read->cloud.data();
      for (size_t i = 0; i < 3 * read->cloud.size(); ++i) {
        if (!std::isfinite(xyz[i])) Fail("non-finite point kept", absl::OkStatus());
      }
    }
  }
}

}  // namespace shapeid::fuzz

#endif  // SHAPEID_FUZZ_READER_FUZZER_H_
