// Issue 28 "Readers as fast as the disk": each reader's points per second on a 10^6-point file
// of its format, beside the floor of reading the same bytes (one read of the file into memory
// plus a memcpy of them), measured in the same run. The files are written by this program
// into --dir (the page cache holds them: the figures are the readers' CPU, not a disk's).
// Prints a Markdown table for docs/performance.md. Run from a release build:
//   build/release/bench/reader_bench [--points 1000000] [--runs 5] [--dir /tmp/reader_bench]

#include <time.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <vector>

#include "CLI/CLI.hpp"
#include "absl/strings/str_format.h"
#include "core/io/pcd_writer.h"
#include "core/io/point_cloud_reader.h"
#include "core/random.h"

namespace shapeid {
namespace {

double Now() {
  timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

// The median wall time of `runs` calls of `work`.
double MedianSeconds(int runs, const std::function<void()>& work) {
  std::vector<double> seconds;
  for (int r = 0; r < runs; ++r) {
    const double start = Now();
    work();
    seconds.push_back(Now() - start);
  }
  std::sort(seconds.begin(), seconds.end());
  return seconds[seconds.size() / 2];
}

template <typename T>
void Put(std::string* out, T value) {
  char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));
  out->append(bytes, sizeof(T));
}

// A scanned-looking cloud: points on a unit sphere, scaled, georeferenced offsets added by the
// formats that carry them.
PointCloud MakeCloud(size_t n) {
  SplitMix64 random(12345);
  std::vector<float> xyz(3 * n);
  for (size_t i = 0; i < n; ++i) {
    float v[3];
    double norm = 0;
    for (float& c : v) {
      c = static_cast<float>(random.Uniform() * 2 - 1);
      norm += static_cast<double>(c) * c;
    }
    for (int a = 0; a < 3; ++a)
      xyz[3 * i + a] = static_cast<float>(5 * v[a] / std::sqrt(norm + 1e-12));
  }
  return PointCloud(std::move(xyz));
}

std::string Las(const PointCloud& cloud) {
  std::string h(227, '\0');
  std::memcpy(&h[0], "LASF", 4);
  h[24] = 1;
  h[25] = 2;
  const uint16_t header_size = 227;
  const uint32_t offset = 227, count = static_cast<uint32_t>(cloud.size());
  const uint16_t record = 20;
  std::memcpy(&h[94], &header_size, 2);
  std::memcpy(&h[96], &offset, 4);
  h[104] = 0;
  std::memcpy(&h[105], &record, 2);
  std::memcpy(&h[107], &count, 4);
  const double scale[3] = {1e-4, 1e-4, 1e-4}, origin[3] = {500000, 4000000, 100};
  std::memcpy(&h[131], scale, sizeof scale);
  std::memcpy(&h[155], origin, sizeof origin);
  h.reserve(227 + 20 * cloud.size());
  for (size_t i = 0; i < cloud.size(); ++i) {
    for (int a = 0; a < 3; ++a)
      Put<int32_t>(&h, static_cast<int32_t>(cloud.xyz()[3 * i + a] / 1e-4));
    h.append(8, '\0');
  }
  return h;
}

// A version-1.0 .npy header for an (n, 3) C-order array of `descr` ("<f4"), padded to 64.
std::string NpyHeader(const char* descr, size_t n) {
  std::string dict =
      absl::StrFormat("{'descr': '%s', 'fortran_order': False, 'shape': (%d, 3), }", descr, n);
  dict.append(64 - (10 + dict.size() + 1) % 64, ' ');
  dict += '\n';
  std::string out = "\x93NUMPY\x01";
  out += '\0';
  Put<uint16_t>(&out, static_cast<uint16_t>(dict.size()));
  return out + dict;
}

std::string Npy(const PointCloud& cloud) {
  std::string out = NpyHeader("<f4", cloud.size());
  out.append(reinterpret_cast<const char*>(cloud.data()), 12 * cloud.size());
  return out;
}

std::string PlyBinary(const PointCloud& cloud, bool big) {
  std::string out = absl::StrFormat(
      "ply\nformat binary_%s_endian 1.0\nelement vertex %d\nproperty float x\n"
      "property float y\nproperty float z\nend_header\n",
      big ? "big" : "little", cloud.size());
  if (!big) {
    out.append(reinterpret_cast<const char*>(cloud.data()), 12 * cloud.size());
    return out;
  }
  for (float v : cloud.xyz()) {
    uint32_t bits;
    std::memcpy(&bits, &v, 4);
    Put<uint32_t>(&out, __builtin_bswap32(bits));
  }
  return out;
}

// PCL's PointXYZRGB layout: x y z and a packed color, 16-byte records.
std::string PcdXyzRgb(const PointCloud& cloud) {
  std::string out = absl::StrFormat(
      "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z rgb\nSIZE 4 4 4 4\nTYPE F F F U\nCOUNT 1 1 1 1\n"
      "WIDTH %d\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS %d\nDATA binary\n",
      cloud.size(), cloud.size());
  out.reserve(out.size() + 16 * cloud.size());
  for (size_t i = 0; i < cloud.size(); ++i) {
    out.append(reinterpret_cast<const char*>(cloud.data() + 3 * i), 12);
    Put<uint32_t>(&out, 0x00ff8040u);
  }
  return out;
}

std::string NpyDouble(const PointCloud& cloud) {
  std::string out = NpyHeader("<f8", cloud.size());
  for (float v : cloud.xyz()) Put<double>(&out, v);
  return out;
}

std::string Xyz(const PointCloud& cloud) {
  std::string out;
  out.reserve(30 * cloud.size());
  for (size_t i = 0; i < cloud.size(); ++i) {
    absl::StrAppendFormat(&out, "%.6f %.6f %.6f\n", cloud.xyz()[3 * i], cloud.xyz()[3 * i + 1],
                          cloud.xyz()[3 * i + 2]);
  }
  return out;
}

}  // namespace
}  // namespace shapeid

int main(int argc, char** argv) {
  using namespace shapeid;
  size_t points = 1000000;
  int runs = 5;
  std::string dir = "/tmp/shapeid_reader_bench";
  CLI::App app("Point-cloud readers against a plain read + memcpy of the same bytes");
  app.add_option("--points", points, "Points per file")->capture_default_str();
  app.add_option("--runs", runs, "Runs per figure (the median is printed)")->capture_default_str();
  app.add_option("--dir", dir, "Where the files are written")->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  namespace fs = std::filesystem;
  fs::create_directories(dir);
  const PointCloud cloud = MakeCloud(points);
  struct Format {
    std::string name;
    std::string file;
  };
  std::vector<Format> formats;
  const auto add = [&](const std::string& name, const std::string& file, const std::string& bytes) {
    std::ofstream(dir + "/" + file, std::ios::binary) << bytes;
    formats.push_back({name, dir + "/" + file});
  };
  add("PCD binary", "cloud.pcd", EncodePcd(cloud, PcdEncoding::kBinary));
  add("PCD binary x y z rgb", "cloud_rgb.pcd", PcdXyzRgb(cloud));
  add("PLY binary", "cloud.ply", PlyBinary(cloud, false));
  add("PLY binary big-endian", "cloud_big.ply", PlyBinary(cloud, true));
  add("LAS 1.2 format 0", "cloud.las", Las(cloud));
  add("NumPy .npy <f4", "cloud.npy", Npy(cloud));
  add("NumPy .npy <f8", "cloud_f8.npy", NpyDouble(cloud));
  add("XYZ text (%.6f)", "cloud.xyz", Xyz(cloud));
  add("PCD ascii", "cloud_ascii.pcd", EncodePcd(cloud, PcdEncoding::kAscii));

  std::printf(
      "| format | file MB | read + memcpy (ms) | ReadPointCloud (ms) | Mpoints/s | ratio to read + "
      "memcpy |\n");
  std::printf("|---|---:|---:|---:|---:|---:|\n");
  for (const Format& f : formats) {
    const double bytes = static_cast<double>(fs::file_size(f.file));
    std::vector<char> copy(static_cast<size_t>(bytes));
    const double floor = MedianSeconds(runs, [&] {
      absl::StatusOr<std::string> contents = ReadFileContents(f.file);
      std::memcpy(copy.data(), contents->data(), contents->size());
    });
    size_t read_points = 0;
    const double reader = MedianSeconds(runs, [&] {
      absl::StatusOr<ReadResult> read = ReadPointCloud(f.file);
      if (!read.ok()) {
        std::fprintf(stderr, "%s\n", read.status().ToString().c_str());
        std::exit(1);
      }
      read_points = read->cloud.size();
    });
    std::printf("| %s | %.1f | %.1f | %.1f | %.1f | %.1fx |\n", f.name.c_str(), bytes / 1e6,
                1e3 * floor, 1e3 * reader, read_points / reader / 1e6, reader / floor);
  }
  return 0;
}
