#ifndef SHAPEID_CORE_IO_XYZ_READER_H_
#define SHAPEID_CORE_IO_XYZ_READER_H_

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "core/io/read_options.h"

namespace shapeid {

enum class TextDialect {
  // .xyz, .txt: values separated by blanks and/or commas.
  kXyz,
  // .csv: as kXyz, except that a file whose first non-comment line contains a ';' is
  // semicolon-separated (blanks too, but not commas), as spreadsheets write CSV where the
  // decimal mark is a comma; "1,5;2" then fails loudly instead of reading as 1 5 2.
  kCsv,
  // .pts (Leica, Open3D, CloudCompare): as kXyz, except that a line holding one integer (the
  // point count written before each scan's points) is skipped.
  kPts,
};

// Parses a text point file held in memory; `name` is the file name that every error message
// starts with. One point per line: x y z are the first three values, further columns are
// ignored (not even parsed). Blank lines and '#' comments (whole or trailing) are skipped.
// The first non-comment line may be a header: if none of its first three values is a number
// it is skipped (e.g. "x,y,z,intensity"). Open3D's .xyzn (x y z nx ny nz) and .xyzrgb
// (x y z r g b) are this format with extra columns. Numbers are parsed locale-independently;
// "nan" and "inf" are numbers (see ReadOptions::drop_non_finite).
// Errors (InvalidArgument) name the line: fewer than three values, a non-numeric coordinate.
absl::StatusOr<ReadResult> ParseXyz(absl::string_view contents, absl::string_view name,
                                    TextDialect dialect, const ReadOptions& options = {});

}  // namespace shapeid

#endif  // SHAPEID_CORE_IO_XYZ_READER_H_
