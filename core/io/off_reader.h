#ifndef SHAPEID_CORE_IO_OFF_READER_H_
#define SHAPEID_CORE_IO_OFF_READER_H_

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "core/io/read_options.h"

namespace shapeid {

// Parses an OFF mesh (Object File Format, as in ModelNet / Princeton Shape Benchmark) held in
// memory: an "OFF" line, a line "vertices faces [edges]", one vertex per line (x y z, extra
// values such as colors ignored), one face per line ("n i1 ... in", extra values ignored).
// The ModelNet quirk "OFF<vertices> <faces> <edges>" on the first line is accepted. '#'
// starts a comment. The mesh is sampled to ReadOptions::sample_points points, area-weighted
// and seeded with sample_seed (polygons split into fans); sample_points 0 returns the vertices.
// InvalidArgument, naming `name` and the line, for malformed contents: a missing OFF line,
// bad counts, a short or non-numeric vertex, a face with fewer than 3 or out-of-range
// indices, more or fewer lines than the counts promise, nothing to sample.
absl::StatusOr<ReadResult> ParseOff(absl::string_view contents, absl::string_view name,
                                    const ReadOptions& options = {});

}  // namespace shapeid

#endif  // SHAPEID_CORE_IO_OFF_READER_H_
