#include "core/io/pcd_writer.h"

#include <charconv>
#include <cstdio>
#include <cstring>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"
#include "absl/types/span.h"
#include "core/io/file_writer.h"

namespace shapeid {

std::string EncodePcd(const PointCloud& cloud, PcdEncoding encoding) {
  const size_t n = cloud.size();
  const bool ascii = encoding == PcdEncoding::kAscii;
  std::string out;
  absl::StrAppend(&out, "# .PCD v0.7 - Point Cloud Data file format\n", "VERSION 0.7\n",
                  "FIELDS x y z\n", "SIZE 4 4 4\n", "TYPE F F F\n", "COUNT 1 1 1\n");
  absl::StrAppend(&out, "WIDTH ", n, "\n", "HEIGHT 1\n", "VIEWPOINT 0 0 0 1 0 0 0\n");
  absl::StrAppend(&out, "POINTS ", n, "\n", "DATA ", ascii ? "ascii" : "binary", "\n");
  const absl::Span<const float> xyz = cloud.xyz();
  if (!ascii) {
    if (!xyz.empty()) {
      out.append(reinterpret_cast<const char*>(xyz.data()), xyz.size() * sizeof(float));
    }
    return out;
  }
  // std::to_chars rather than printf: the same %.9g digits, but never a locale's decimal comma.
  out.reserve(out.size() + 3 * 16 * n);
  char buffer[32];
  for (size_t i = 0; i < xyz.size(); ++i) {
    const std::to_chars_result r =
        std::to_chars(buffer, buffer + sizeof buffer, xyz[i], std::chars_format::general, 9);
    out.append(buffer, r.ptr);
    out.push_back(i % 3 == 2 ? '\n' : ' ');
  }
  return out;
}

absl::Status WritePcd(const std::string& path, const PointCloud& cloud, PcdEncoding encoding) {
  return WriteFileAtomically(path, EncodePcd(cloud, encoding));
}

}  // namespace shapeid
