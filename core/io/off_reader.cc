#include "core/io/off_reader.h"

#include <algorithm>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "core/io/cloud_accumulator.h"
#include "core/io/mesh_sampler.h"
#include "core/io/text_lines.h"

namespace shapeid {
namespace {

absl::Status LineError(absl::string_view name, uint64_t line, absl::string_view message) {
  return absl::InvalidArgumentError(absl::StrCat(name, ": line ", line, ": ", message));
}

}  // namespace

absl::StatusOr<ReadResult> ParseOff(absl::string_view contents, absl::string_view name,
                                    const ReadOptions& options) {
  LineReader lines(contents);
  absl::string_view line;
  // The next line that is not blank or a comment, trimmed; false at the end.
  const auto next = [&lines, &line]() {
    while (lines.Next(&line)) {
      line = StripComment(line);
      if (!line.empty()) return true;
    }
    return false;
  };

  if (!next() || line.substr(0, 3) != "OFF") {
    return absl::InvalidArgumentError(
        absl::StrCat(name, ": line ", std::max<uint64_t>(lines.line_number(), 1),
                     ": an OFF file starts with an \"OFF\" line; found ", QuoteForMessage(line)));
  }
  absl::string_view counts_text = line.substr(3);  // ModelNet writes "OFF490 518 0"
  while (!counts_text.empty() && IsBlank(counts_text.front())) counts_text.remove_prefix(1);
  if (counts_text.empty()) {
    if (!next()) {
      return LineError(name, lines.line_number(), "the file ends before the counts line");
    }
    counts_text = line;
  }
  const uint64_t counts_line = lines.line_number();
  uint64_t counts[3] = {0, 0, 0};
  {
    Tokenizer tokens(counts_text);
    absl::string_view token;
    int k = 0;
    for (; tokens.Next(&token); ++k) {
      if (k >= 3 || !absl::SimpleAtoi(token, &counts[k])) {
        return LineError(name, counts_line,
                         absl::StrCat("expected \"vertices faces [edges]\" counts, found ",
                                      QuoteForMessage(counts_text)));
      }
    }
    if (k < 2) {
      return LineError(name, counts_line,
                       absl::StrCat("expected \"vertices faces [edges]\" counts, found ",
                                    QuoteForMessage(counts_text)));
    }
  }
  const uint64_t vertices = counts[0], faces = counts[1];

  // Counts are not trusted for memory: each vertex needs at least "0 0 0\n".
  const size_t reserve = static_cast<size_t>(std::min<uint64_t>(vertices, contents.size() / 6));
  TriangleMesh mesh;
  CloudAccumulator cloud(name, "line");
  const bool sample = options.sample_points > 0;
  if (!sample) cloud.Reserve(reserve);
  for (uint64_t i = 0; i < vertices; ++i) {
    if (!next()) {
      return LineError(name, lines.line_number(),
                       absl::StrCat("the file ends after ", i, " of ", vertices, " vertices"));
    }
    Tokenizer tokens(line);
    absl::string_view token;
    double v[3];
    for (int a = 0; a < 3; ++a) {
      if (!tokens.Next(&token)) {
        return LineError(name, lines.line_number(),
                         absl::StrCat("a vertex needs x y z, found ", a, " values"));
      }
      if (!ParseDouble(token, &v[a])) {
        return LineError(name, lines.line_number(),
                         absl::StrCat(std::string(1, "xyz"[a]), " value ", QuoteForMessage(token),
                                      " is not a number"));
      }
    }
    if (sample) {
      mesh.AddVertex(v[0], v[1], v[2]);
    } else {
      cloud.Add(v[0], v[1], v[2], lines.line_number());
    }
  }

  std::vector<uint64_t> indices;
  for (uint64_t f = 0; f < faces; ++f) {
    if (!next()) {
      return LineError(name, lines.line_number(),
                       absl::StrCat("the file ends after ", f, " of ", faces, " faces"));
    }
    const uint64_t ln = lines.line_number();
    Tokenizer tokens(line);
    absl::string_view token;
    uint64_t n = 0;
    tokens.Next(&token);
    if (!absl::SimpleAtoi(token, &n) || n < 3) {
      return LineError(name, ln,
                       absl::StrCat("a face starts with its vertex count (3 or more), found ",
                                    QuoteForMessage(token)));
    }
    indices.clear();
    for (uint64_t k = 0; k < n; ++k) {
      uint64_t index = 0;
      if (!tokens.Next(&token)) {
        return LineError(name, ln, absl::StrCat("the face lists ", k, " of its ", n, " vertices"));
      }
      if (!absl::SimpleAtoi(token, &index) || index >= vertices) {
        return LineError(name, ln,
                         absl::StrCat("vertex index ", QuoteForMessage(token),
                                      " is not an integer in [0, ", vertices, ")"));
      }
      indices.push_back(index);
    }
    if (sample) mesh.AddPolygon(indices, ln);
  }
  if (next()) {
    return LineError(name, lines.line_number(),
                     absl::StrCat("more data than the ", vertices, " vertices and ", faces,
                                  " faces on line ", counts_line));
  }
  if (sample) {
    absl::Status sampled =
        mesh.Sample(options.sample_points, options.sample_seed, name, "line", &cloud);
    if (!sampled.ok()) return sampled;
  }
  return std::move(cloud).Finish(options);
}

}  // namespace shapeid
