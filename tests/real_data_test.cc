// Every descriptor on real clouds: ModelNet10 meshes sampled to 1,024 points and DALES aerial
// LiDAR objects (sparse, partial, georeferenced). The data lives in ../shared/data beside the
// repository and is never committed; where it is absent these tests skip and say so.

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "core/descriptor_registry.h"
#include "core/io/point_cloud_reader.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

namespace fs = std::filesystem;

fs::path DataDir() { return fs::path(SHAPEID_SOURCE_DIR) / ".." / "shared" / "data"; }

// The first `per_class` files (sorted, so the choice is stable) of each class folder.
std::vector<fs::path> Sample(const fs::path& root, const std::string& sub, int per_class) {
  std::vector<fs::path> picked;
  std::vector<fs::path> classes;
  for (const auto& entry : fs::directory_iterator(root)) {
    if (entry.is_directory()) classes.push_back(entry.path());
  }
  std::sort(classes.begin(), classes.end());
  for (const fs::path& cls : classes) {
    std::vector<fs::path> files;
    const fs::path dir = sub.empty() ? cls : cls / sub;
    if (!fs::is_directory(dir)) continue;
    for (const auto& entry : fs::directory_iterator(dir)) files.push_back(entry.path());
    std::sort(files.begin(), files.end());
    for (int i = 0; i < per_class && i < static_cast<int>(files.size()); ++i)
      picked.push_back(files[i]);
  }
  return picked;
}

const std::vector<std::string>& Specs() {
  static const auto* const specs = new std::vector<std::string>{
      "rphsd",  // complete, cubic27, M = 100
      "rphsd:refs=cross7,bins=10,variant=reduced",
      "rphsd:refs=spherical27,bins=50",
      "rphsd:refs=fibonacci:64,bins=30",
      "comsd",
      "comsd:grid=100",
      "cnsd",
      "cnsd:downsample=random,max_points=500",
  };
  return *specs;
}

void DescribeAll(const std::vector<fs::path>& files, size_t expected_points) {
  ASSERT_FALSE(files.empty());
  for (const std::string& spec : Specs()) {
    auto descriptor = CreateDescriptor(spec);
    ASSERT_TRUE(descriptor.ok()) << spec << ": " << descriptor.status();
    std::vector<std::vector<float>> seen;
    for (const fs::path& file : files) {
      auto read = ReadPointCloud(file.string());
      ASSERT_TRUE(read.ok()) << read.status();
      if (expected_points != 0) {
        EXPECT_EQ(read->cloud.size(), expected_points) << file;
      }
      auto values = (*descriptor)->Compute(read->cloud);
      ASSERT_TRUE(values.ok()) << spec << " on " << file << ": " << values.status();
      ASSERT_EQ(values->size(), (*descriptor)->dimension()) << spec;
      for (float v : *values) ASSERT_TRUE(std::isfinite(v)) << spec << " on " << file;
      seen.push_back(*values);
    }
    // Different objects must not collapse onto one vector.
    std::sort(seen.begin(), seen.end());
    EXPECT_EQ(std::unique(seen.begin(), seen.end()), seen.end()) << spec << " gave equal vectors";
  }
}

TEST(RealDataTest, EveryDescriptorOnModelNet10Clouds) {
  const fs::path root = DataDir() / "modelnet10";
  if (!fs::is_directory(root)) GTEST_SKIP() << "ModelNet10 not found at " << root << "; skipping";
  DescribeAll(Sample(root, "test", 1), 1024);
}

TEST(RealDataTest, EveryDescriptorOnDalesObjects) {
  const fs::path root = DataDir() / "dales-objects";
  if (!fs::is_directory(root))
    GTEST_SKIP() << "DALES Objects not found at " << root << "; skipping";
  DescribeAll(Sample(root, "", 1), 0);
}

}  // namespace
}  // namespace shapeid
