#ifndef SHAPEID_BENCH_SOAK_CLOUD_POOL_H_
#define SHAPEID_BENCH_SOAK_CLOUD_POOL_H_

// The clouds the soak clients train and classify with.

#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

namespace shapeid::soak {

struct Pool {
  std::vector<std::string> xyz;      // train clouds as PointChunk bytes
  std::vector<std::string> labels;   // label of each: a cloud always trains under one label
  std::vector<std::string> queries;  // query clouds (never trained), PointChunk bytes
  std::string source;                // where they came from, for the report
};

// `per_class` train clouds and `per_class / 2` test clouds of every ModelNet10 class under
// `root`, or synthetic 1,024-point clouds under 10 labels where the data is absent.
Pool LoadPool(const std::filesystem::path& root, size_t per_class);

}  // namespace shapeid::soak

#endif  // SHAPEID_BENCH_SOAK_CLOUD_POOL_H_
