#include "core/io/pcd_reader.h"

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "core/io/cloud_accumulator.h"
#include "core/io/pcd_internal.h"
#include "core/io/text_lines.h"
#include "core/status_macros.h"

namespace shapeid {
namespace {

using pcd_internal::DataKind;
using pcd_internal::DecodeCompressed;
using pcd_internal::Header;
using pcd_internal::Layout;
using pcd_internal::LoadCoordinate;
using pcd_internal::MulOverflows;

absl::Status LineError(absl::string_view name, uint64_t line, absl::string_view message) {
  return absl::InvalidArgumentError(absl::StrCat(name, ": line ", line, ": ", message));
}

absl::Status ParseUints(absl::string_view name, uint64_t line, absl::string_view keyword,
                        const std::vector<absl::string_view>& values, std::vector<uint64_t>* out) {
  out->clear();
  for (absl::string_view v : values) {
    uint64_t n = 0;
    if (!absl::SimpleAtoi(v, &n)) {
      return LineError(
          name, line,
          absl::StrCat(keyword, " value ", QuoteForMessage(v), " is not a non-negative integer"));
    }
    out->push_back(n);
  }
  return absl::OkStatus();
}

absl::Status ParseOneUint(absl::string_view name, uint64_t line, absl::string_view keyword,
                          const std::vector<absl::string_view>& values, uint64_t* out) {
  if (values.size() != 1) {
    return LineError(name, line, absl::StrCat(keyword, " takes one value, found ", values.size()));
  }
  std::vector<uint64_t> parsed;
  SHAPEID_RETURN_IF_ERROR(ParseUints(name, line, keyword, values, &parsed));
  *out = parsed[0];
  return absl::OkStatus();
}

// Reads header lines up to and including DATA.
absl::StatusOr<Header> ParseHeader(absl::string_view contents, absl::string_view name) {
  Header h;
  LineReader lines(contents);
  absl::string_view line;
  std::vector<absl::string_view> values;
  while (lines.Next(&line)) {
    const absl::string_view content = StripComment(line);
    if (content.empty()) continue;
    const uint64_t ln = lines.line_number();
    Tokenizer tokens(content);
    absl::string_view keyword;
    tokens.Next(&keyword);
    values.clear();
    for (absl::string_view v; tokens.Next(&v);) values.push_back(v);

    const std::pair<absl::string_view, uint64_t*> keywords[] = {
        {"VERSION", &h.version_line}, {"FIELDS", &h.fields_line},       {"SIZE", &h.size_line},
        {"TYPE", &h.type_line},       {"COUNT", &h.count_line},         {"WIDTH", &h.width_line},
        {"HEIGHT", &h.height_line},   {"VIEWPOINT", &h.viewpoint_line}, {"POINTS", &h.points_line},
        {"DATA", &h.data_line}};
    uint64_t* seen = nullptr;
    for (const auto& [word, line_of] : keywords) {
      if (keyword == word) seen = line_of;
    }
    if (seen == nullptr) {
      return LineError(
          name, ln,
          absl::StrCat("unknown PCD header keyword ", QuoteForMessage(keyword),
                       h.version_line == 0 && h.fields_line == 0 ? " (is this a PCD file?)" : ""));
    }
    if (*seen != 0) {
      return LineError(name, ln,
                       absl::StrCat(keyword, " appears twice (first on line ", *seen, ")"));
    }
    *seen = ln;
    const bool needs_values = keyword != "VERSION";
    if (needs_values && values.empty()) {
      return LineError(name, ln, absl::StrCat(keyword, " has no value"));
    }

    if (keyword == "VERSION") {
      // Any version: the keywords decide what can be read, and PCL still writes ".7".
    } else if (keyword == "FIELDS") {
      h.fields = values;
    } else if (keyword == "SIZE") {
      SHAPEID_RETURN_IF_ERROR(ParseUints(name, ln, keyword, values, &h.sizes));
    } else if (keyword == "TYPE") {
      for (absl::string_view v : values) {
        if (v != "F" && v != "I" && v != "U") {
          return LineError(
              name, ln, absl::StrCat("TYPE value ", QuoteForMessage(v), " is not one of F, I, U"));
        }
        h.types.push_back(v[0]);
      }
    } else if (keyword == "COUNT") {
      SHAPEID_RETURN_IF_ERROR(ParseUints(name, ln, keyword, values, &h.counts));
    } else if (keyword == "WIDTH") {
      SHAPEID_RETURN_IF_ERROR(ParseOneUint(name, ln, keyword, values, &h.width));
    } else if (keyword == "HEIGHT") {
      SHAPEID_RETURN_IF_ERROR(ParseOneUint(name, ln, keyword, values, &h.height));
    } else if (keyword == "POINTS") {
      SHAPEID_RETURN_IF_ERROR(ParseOneUint(name, ln, keyword, values, &h.points));
    } else if (keyword == "VIEWPOINT") {
      // A sensor pose (translation, quaternion). PCL does not apply it to the points either.
      double unused = 0;
      for (absl::string_view v : values) {
        if (!ParseDouble(v, &unused)) {
          return LineError(
              name, ln, absl::StrCat("VIEWPOINT value ", QuoteForMessage(v), " is not a number"));
        }
      }
      if (values.size() != 7) {
        return LineError(name, ln, absl::StrCat("VIEWPOINT takes 7 values, found ", values.size()));
      }
    } else {  // DATA
      if (values.size() != 1) {
        return LineError(name, ln, absl::StrCat("DATA takes one value, found ", values.size()));
      }
      if (values[0] == "ascii") {
        h.data = DataKind::kAscii;
      } else if (values[0] == "binary") {
        h.data = DataKind::kBinary;
      } else if (values[0] == "binary_compressed") {
        h.data = DataKind::kBinaryCompressed;
      } else {
        return LineError(name, ln,
                         absl::StrCat("unknown DATA kind ", QuoteForMessage(values[0]),
                                      "; expected ascii, binary or binary_compressed"));
      }
      h.data_offset = lines.offset();
      return h;
    }
  }
  return absl::InvalidArgumentError(
      absl::StrCat(name, ": the PCD header has no DATA line (", lines.line_number(), " lines read)",
                   h.version_line == 0 && h.fields_line == 0 ? "; is this a PCD file?" : ""));
}

absl::StatusOr<Layout> MakeLayout(Header& h, absl::string_view name) {
  const uint64_t at_data = h.data_line;
  for (const auto& [keyword, line] : {std::pair<const char*, uint64_t>{"FIELDS", h.fields_line},
                                      {"SIZE", h.size_line},
                                      {"TYPE", h.type_line},
                                      {"WIDTH", h.width_line}}) {
    if (line == 0) {
      return LineError(name, at_data, absl::StrCat("the header has no ", keyword, " line"));
    }
  }
  const size_t n = h.fields.size();
  if (h.count_line == 0) h.counts.assign(n, 1);  // COUNT arrived in v0.7
  for (const auto& [keyword, line, size] :
       {std::tuple<const char*, uint64_t, size_t>{"SIZE", h.size_line, h.sizes.size()},
        {"TYPE", h.type_line, h.types.size()},
        {"COUNT", h.count_line, h.counts.size()}}) {
    if (size != n) {
      return LineError(name, line,
                       absl::StrCat(keyword, " has ", size, " values but FIELDS (line ",
                                    h.fields_line, ") has ", n));
    }
  }

  Layout layout;
  int coord_field[3] = {-1, -1, -1};
  for (size_t i = 0; i < n; ++i) {
    const uint64_t size = h.sizes[i];
    if (size != 1 && size != 2 && size != 4 && size != 8) {
      return LineError(name, h.size_line,
                       absl::StrCat("field ", QuoteForMessage(h.fields[i]), " has SIZE ", size,
                                    "; must be 1, 2, 4 or 8"));
    }
    if (h.types[i] == 'F' && size != 4 && size != 8) {
      return LineError(name, h.type_line,
                       absl::StrCat("field ", QuoteForMessage(h.fields[i]),
                                    " has TYPE F with SIZE ", size, "; must be 4 or 8"));
    }
    if (h.counts[i] == 0) {
      return LineError(name, h.count_line,
                       absl::StrCat("field ", QuoteForMessage(h.fields[i]), " has COUNT 0"));
    }
    for (int a = 0; a < 3; ++a) {
      if (h.fields[i] != absl::string_view(&"xyz"[a], 1)) continue;
      if (coord_field[a] >= 0) {
        return LineError(name, h.fields_line,
                         absl::StrCat("field ", QuoteForMessage(h.fields[i]), " appears twice"));
      }
      coord_field[a] = static_cast<int>(i);
      layout.byte_offset[a] = layout.point_bytes;
      layout.value_index[a] = layout.point_values;
      layout.is_double[a] = size == 8;
    }
    uint64_t field_bytes = 0;
    if (MulOverflows(size, h.counts[i], &field_bytes) ||
        __builtin_add_overflow(layout.point_bytes, field_bytes, &layout.point_bytes) ||
        __builtin_add_overflow(layout.point_values, h.counts[i], &layout.point_values)) {
      return LineError(name, h.count_line != 0 ? h.count_line : h.size_line,
                       "the point size overflows 64 bits");
    }
  }
  for (int a = 0; a < 3; ++a) {
    const int f = coord_field[a];
    if (f < 0) {
      return LineError(name, h.fields_line,
                       absl::StrCat("no \"", std::string(1, "xyz"[a]), "\" field (FIELDS are ",
                                    absl::StrJoin(h.fields, " "), ")"));
    }
    if (h.types[f] != 'F') {
      return absl::UnimplementedError(absl::StrCat(
          name, ": line ", h.type_line, ": field \"", std::string(1, "xyz"[a]), "\" has TYPE ",
          std::string(1, h.types[f]), "; shapeid reads F (float or double) coordinates"));
    }
    if (h.counts[f] != 1) {
      return LineError(name, h.count_line,
                       absl::StrCat("field \"", std::string(1, "xyz"[a]), "\" has COUNT ",
                                    h.counts[f], "; a coordinate must have COUNT 1"));
    }
  }

  uint64_t width_height = 0;
  if (MulOverflows(h.width, h.height, &width_height)) {
    return LineError(name, h.height_line != 0 ? h.height_line : h.width_line,
                     "WIDTH * HEIGHT overflows 64 bits");
  }
  if (h.points_line == 0) {
    h.points = width_height;
  } else if (h.points != width_height) {
    return LineError(name, h.points_line,
                     absl::StrCat("POINTS ", h.points, " does not match WIDTH * HEIGHT = ", h.width,
                                  " * ", h.height, " = ", width_height));
  }
  return layout;
}

absl::StatusOr<ReadResult> DecodeBinary(absl::string_view contents, absl::string_view name,
                                        const Header& h, const Layout& layout,
                                        const ReadOptions& options) {
  const uint64_t available = contents.size() - h.data_offset;
  uint64_t expected = 0;
  const bool overflow = MulOverflows(h.points, layout.point_bytes, &expected);
  if (overflow || expected > available) {
    return absl::InvalidArgumentError(
        absl::StrCat(name, ": byte offset ", h.data_offset, ": binary data is truncated: expected ",
                     overflow ? std::string("over 2^64") : absl::StrCat(expected), " bytes (",
                     h.points, " points of ", layout.point_bytes, " bytes), found ", available));
  }
  const char* data = contents.data() + h.data_offset;
  if (!layout.is_double[0] && !layout.is_double[1] && !layout.is_double[2]) {
    FloatColumns columns;
    for (int a = 0; a < 3; ++a) {
      columns.axis[a] = data + layout.byte_offset[a];
      columns.stride[a] = layout.point_bytes;
    }
    columns.where = h.data_offset;
    columns.where_step = layout.point_bytes;
    return ReadFloatColumns(columns, h.points, "byte offset", options);
  }
  return ReadPointsTwice(
      h.points,
      [&](size_t i, double* p) {
        const char* point = data + i * layout.point_bytes;
        for (int a = 0; a < 3; ++a) {
          p[a] = LoadCoordinate(point + layout.byte_offset[a], layout.is_double[a]);
        }
      },
      [&](size_t i) { return h.data_offset + i * layout.point_bytes; }, name, "byte offset",
      options);
}

absl::StatusOr<ReadResult> DecodeAscii(absl::string_view contents, absl::string_view name,
                                       const Header& h, const Layout& layout,
                                       const ReadOptions& options) {
  const absl::string_view text = contents.substr(h.data_offset);
  CloudAccumulator cloud(name, "line");
  // The header's POINTS is not trusted for memory: each point needs at least "0 0 0\n".
  cloud.Reserve(std::min<uint64_t>(h.points, text.size() / 6 + 1));
  LineReader lines(text, h.data_line + 1);
  absl::string_view line;
  uint64_t read = 0;
  while (lines.Next(&line)) {
    const uint64_t ln = lines.line_number();
    Tokenizer tokens(line);
    absl::string_view token, coord[3];
    uint64_t k = 0;
    for (; tokens.Next(&token); ++k) {
      if (k == 0 && token[0] == '#') break;
      for (int a = 0; a < 3; ++a) {
        if (k == layout.value_index[a]) coord[a] = token;
      }
    }
    if (k == 0) continue;  // blank or comment
    if (read == h.points) {
      return LineError(
          name, ln, absl::StrCat("more data than the ", h.points, " points the header promises"));
    }
    if (k != layout.point_values) {
      return LineError(name, ln,
                       absl::StrCat("expected ", layout.point_values, " values per point (FIELDS ",
                                    absl::StrJoin(h.fields, " "), "), found ", k));
    }
    double v[3];
    for (int a = 0; a < 3; ++a) {
      if (!ParseDouble(coord[a], &v[a])) {
        return LineError(name, ln,
                         absl::StrCat(std::string(1, "xyz"[a]), " value ",
                                      QuoteForMessage(coord[a]), " is not a number"));
      }
    }
    cloud.Add(v[0], v[1], v[2], ln);
    ++read;
  }
  if (read < h.points) {
    return LineError(
        name, std::max(lines.line_number(), h.data_line),
        absl::StrCat("ascii data ends after ", read, " points; the header promises ", h.points));
  }
  return std::move(cloud).Finish(options);
}

}  // namespace

absl::StatusOr<ReadResult> ParsePcd(absl::string_view contents, absl::string_view name,
                                    const ReadOptions& options) {
  SHAPEID_ASSIGN_OR_RETURN(Header header, ParseHeader(contents, name));
  SHAPEID_ASSIGN_OR_RETURN(const Layout layout, MakeLayout(header, name));
  if (header.data == DataKind::kAscii) return DecodeAscii(contents, name, header, layout, options);
  if (header.data == DataKind::kBinaryCompressed) {
    return DecodeCompressed(contents, name, header, layout, options);
  }
  return DecodeBinary(contents, name, header, layout, options);
}

}  // namespace shapeid
