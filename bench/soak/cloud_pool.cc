#include "bench/soak/cloud_pool.h"

#include <algorithm>
#include <cstdint>
#include <system_error>

#include "absl/strings/str_cat.h"
#include "bench/bench_clouds.h"
#include "core/io/point_cloud_reader.h"
#include "core/point_cloud.h"

namespace shapeid::soak {
namespace {

namespace fs = std::filesystem;

std::string Bytes(const PointCloud& cloud) {
  return std::string(reinterpret_cast<const char*>(cloud.data()), cloud.size() * 12);
}

}  // namespace

Pool LoadPool(const fs::path& root, size_t per_class) {
  Pool pool;
  std::error_code error;
  std::vector<fs::path> classes;
  for (const auto& entry : fs::directory_iterator(root, error)) {
    if (entry.is_directory()) classes.push_back(entry.path());
  }
  std::sort(classes.begin(), classes.end());
  for (const fs::path& cls : classes) {
    for (const char* split : {"train", "test"}) {
      std::vector<fs::path> files;
      for (const auto& entry : fs::directory_iterator(cls / split, error)) {
        files.push_back(entry.path());
      }
      std::sort(files.begin(), files.end());
      const size_t want = std::string(split) == "train" ? per_class : per_class / 2;
      for (size_t i = 0; i < files.size() && i < want; ++i) {
        auto read = ReadPointCloud(files[i].string());
        if (!read.ok()) continue;
        if (std::string(split) == "train") {
          pool.xyz.push_back(Bytes(read->cloud));
          pool.labels.push_back(cls.filename().string());
        } else {
          pool.queries.push_back(Bytes(read->cloud));
        }
      }
    }
  }
  if (!pool.xyz.empty() && !pool.queries.empty()) {
    pool.source = absl::StrCat("ModelNet10 (", pool.xyz.size(), " train and ", pool.queries.size(),
                               " test clouds, ", classes.size(), " classes, 1,024 points each)");
    return pool;
  }
  pool = Pool();
  for (size_t i = 0; i < 10 * per_class; ++i) {
    pool.xyz.push_back(Bytes(bench::SurfaceCloud(1024, 1000 + static_cast<uint32_t>(i))));
    pool.labels.push_back(absl::StrCat("shape-", i % 10));
  }
  for (size_t i = 0; i < 5 * per_class; ++i) {
    pool.queries.push_back(Bytes(bench::SurfaceCloud(1024, 900000 + static_cast<uint32_t>(i))));
  }
  pool.source = absl::StrCat("SYNTHETIC 1,024-point clouds under 10 labels (no ModelNet10 at ",
                             root.string(), ")");
  return pool;
}

}  // namespace shapeid::soak
