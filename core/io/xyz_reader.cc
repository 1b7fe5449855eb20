#include "core/io/xyz_reader.h"

#include <string>
#include <utility>

#include "absl/status/status.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "core/io/cloud_accumulator.h"
#include "core/io/text_lines.h"

namespace shapeid {

absl::StatusOr<ReadResult> ParseXyz(absl::string_view contents, absl::string_view name,
                                    TextDialect dialect, const ReadOptions& options) {
  CloudAccumulator cloud(name, "line");
  // A guess that avoids most regrowth: real files have about 25 to 40 bytes per line.
  cloud.Reserve(contents.size() / 24 + 1);
  char separator = ',';
  bool first = true;
  LineReader lines(contents);
  absl::string_view line;
  while (lines.Next(&line)) {
    const absl::string_view content = StripComment(line);
    if (content.empty()) continue;
    const uint64_t ln = lines.line_number();
    if (first && dialect == TextDialect::kCsv && content.find(';') != absl::string_view::npos) {
      separator = ';';
    }
    Tokenizer tokens(content, separator);
    absl::string_view token[3];
    double v[3] = {0, 0, 0};
    bool numeric[3] = {false, false, false};
    int found = 0;
    int numbers = 0;
    for (; found < 3 && tokens.Next(&token[found]); ++found) {
      numeric[found] = ParseDouble(token[found], &v[found]);
      numbers += numeric[found];
    }
    if (first) {
      first = false;
      if (numbers == 0) continue;  // a header line
    }
    uint64_t count;
    if (dialect == TextDialect::kPts && found == 1 && absl::SimpleAtoi(token[0], &count)) {
      continue;  // a scan's point count
    }
    if (found < 3) {
      return absl::InvalidArgumentError(absl::StrCat(name, ": line ", ln,
                                                     ": expected x y z, found ", found,
                                                     found == 1 ? " value" : " values"));
    }
    for (int a = 0; a < 3; ++a) {
      if (!numeric[a]) {
        return absl::InvalidArgumentError(
            absl::StrCat(name, ": line ", ln, ": ", std::string(1, "xyz"[a]), " value ",
                         QuoteForMessage(token[a]), " is not a number",
                         numbers == 0 ? " (a header is allowed only as the first line)" : ""));
      }
    }
    cloud.Add(v[0], v[1], v[2], ln);
  }
  return std::move(cloud).Finish(options);
}

}  // namespace shapeid
