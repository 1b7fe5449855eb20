// The "plain scalar program" of issue 28's whole-process goal: reads a binary PCD with fread and
// computes RPHSD (cubic27 references, 100 bins, complete variant) exactly as
// /work/shared/spec/descriptors.md section 1 defines it, with plain loops and no code from
// core/. bench/describe_file_bench times it beside `shapeid describe --local --spec rphsd`.
// Usage: plain_rphsd FILE.pcd; prints the file name and the 81 values, as `shapeid describe`.
// Reads only what the benchmark writes: DATA binary, float32 x y z at any place in the record.

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

namespace {

[[noreturn]] void Fail(const char* what) {
  std::fprintf(stderr, "plain_rphsd: %s\n", what);
  std::exit(1);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) Fail("usage: plain_rphsd FILE.pcd");
  std::FILE* f = std::fopen(argv[1], "rb");
  if (f == nullptr) Fail("cannot open the file");

  // Header: FIELDS and SIZE give each coordinate's place in the record; POINTS the count.
  std::vector<std::string> fields;
  std::vector<int> sizes;
  long points = -1;
  char line[4096];
  bool binary = false;
  while (std::fgets(line, sizeof line, f) != nullptr) {
    char* save = nullptr;
    const char* keyword = strtok_r(line, " \t\r\n", &save);
    if (keyword == nullptr) continue;
    const std::string key = keyword;
    for (const char* w; (w = strtok_r(nullptr, " \t\r\n", &save)) != nullptr;) {
      if (key == "FIELDS") fields.push_back(w);
      if (key == "SIZE") sizes.push_back(std::atoi(w));
      if (key == "POINTS") points = std::atol(w);
      if (key == "DATA") binary = std::string(w) == "binary";
    }
    if (key == "DATA") break;
  }
  if (!binary || points < 3 || fields.size() != sizes.size()) Fail("not a binary PCD");
  int record = 0, offset[3] = {-1, -1, -1};
  for (size_t i = 0; i < fields.size(); ++i) {
    for (int a = 0; a < 3; ++a) {
      if (fields[i] == std::string(1, "xyz"[a])) offset[a] = record;
    }
    record += sizes[i];
  }
  if (offset[0] < 0 || offset[1] < 0 || offset[2] < 0) Fail("no x, y, z fields");
  const size_t n = static_cast<size_t>(points);
  std::vector<char> data(n * static_cast<size_t>(record));
  if (std::fread(data.data(), 1, data.size(), f) != data.size()) Fail("truncated data");
  std::fclose(f);
  std::vector<float> xyz(3 * n);
  for (size_t i = 0; i < n; ++i) {
    for (int a = 0; a < 3; ++a) {
      std::memcpy(&xyz[3 * i + a], &data[i * record + offset[a]], sizeof(float));
    }
  }

  // 1. Center on the centroid (accumulated in double), scale by the largest |coordinate|.
  double centroid[3] = {0, 0, 0};
  for (size_t i = 0; i < n; ++i) {
    for (int a = 0; a < 3; ++a) centroid[a] += xyz[3 * i + a];
  }
  for (int a = 0; a < 3; ++a) centroid[a] /= static_cast<double>(n);
  double radius = 0;
  for (size_t i = 0; i < n; ++i) {
    for (int a = 0; a < 3; ++a) radius = std::fmax(radius, std::fabs(xyz[3 * i + a] - centroid[a]));
  }
  if (!(radius > 0)) Fail("zero extent");

  // 2. cubic27 references, x outermost; 100 bins over [0, 2 sqrt(3)], last bin clamped.
  constexpr int kRefs = 27, kBins = 100;
  float ref[kRefs][3];
  for (int k = 0; k < kRefs; ++k) {
    ref[k][0] = static_cast<float>(k / 9 - 1);
    ref[k][1] = static_cast<float>(k / 3 % 3 - 1);
    ref[k][2] = static_cast<float>(k % 3 - 1);
  }
  const float bin_scale = static_cast<float>(kBins / (2.0 * std::sqrt(3.0)));
  const float inv_radius = static_cast<float>(1.0 / radius);
  const float cx = static_cast<float>(centroid[0]), cy = static_cast<float>(centroid[1]),
              cz = static_cast<float>(centroid[2]);
  std::vector<unsigned> counts(kRefs * kBins, 0);
  for (size_t i = 0; i < n; ++i) {
    const float x = (xyz[3 * i] - cx) * inv_radius;
    const float y = (xyz[3 * i + 1] - cy) * inv_radius;
    const float z = (xyz[3 * i + 2] - cz) * inv_radius;
    for (int k = 0; k < kRefs; ++k) {
      const float dx = x - ref[k][0], dy = y - ref[k][1], dz = z - ref[k][2];
      int bin = static_cast<int>(std::sqrt(dx * dx + dy * dy + dz * dz) * bin_scale);
      if (bin > kBins - 1) bin = kBins - 1;
      ++counts[k * kBins + bin];
    }
  }

  // 3-4. Variance, entropy and inverse difference moment of each normalized histogram.
  double features[3][kRefs];
  for (int k = 0; k < kRefs; ++k) {
    double variance = 0, entropy = 0, idm = 0;
    for (int b = 0; b < kBins; ++b) {
      const double h = counts[k * kBins + b] / static_cast<double>(n);
      variance += (h - 1.0 / kBins) * (h - 1.0 / kBins);
      if (h > 0) entropy -= h * std::log(h);
      idm += h / (1.0 + static_cast<double>(b) * b);
    }
    features[0][k] = variance / kBins;
    features[1][k] = entropy;
    features[2][k] = idm;
  }
  std::printf("%s", argv[1]);
  for (auto& feature : features) {
    for (double v : feature) std::printf(" %.9g", static_cast<float>(v));
  }
  std::printf("\n");
  return 0;
}
