// Descriptor::EstimateCost against what describing really takes. working_bytes must bound the
// peak heap from above, measured by heap_meter (this binary's malloc counts every block);
// CPU estimates are checked by bench/describe_cost_bench, never by a timed test.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "core/descriptor.h"
#include "core/descriptor_registry.h"
#include "core/descriptors/dfsd_golden_clouds.h"
#include "core/descriptors/heap_meter.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

constexpr const char* kNoMeter =
    "the heap meter replaces malloc, which AddressSanitizer and ThreadSanitizer replace in "
    "this build; the ci build runs this test";

std::unique_ptr<Descriptor> Make(const std::string& spec) {
  auto descriptor = CreateDescriptor(spec);
  EXPECT_TRUE(descriptor.ok()) << spec << ": " << descriptor.status();
  return descriptor.ok() ? std::move(*descriptor) : nullptr;
}

// Peak heap of one describe into empty vectors, the way a server calls it.
int64_t PeakOf(const Descriptor& descriptor, const PointCloud& cloud, bool with_variants) {
  std::vector<float> out, variants;
  heap_meter::Start();
  const absl::Status status = with_variants
                                  ? descriptor.ComputeWithPoseVariants(cloud, &out, &variants)
                                  : descriptor.Compute(cloud, &out);
  const int64_t peak = heap_meter::Stop();
  EXPECT_TRUE(status.ok()) << descriptor.spec().ToString() << ": " << status;
  return peak;
}

void ExpectBounded(const std::string& spec, const PointCloud& cloud, const std::string& what) {
  const std::unique_ptr<Descriptor> descriptor = Make(spec);
  ASSERT_NE(descriptor, nullptr);
  const size_t estimate = descriptor->EstimateCost(cloud.size()).working_bytes;
  for (bool with_variants : {false, true}) {
    const int64_t peak = PeakOf(*descriptor, cloud, with_variants);
    EXPECT_GT(peak, 0) << spec;
    EXPECT_LE(peak, static_cast<int64_t>(estimate))
        << spec << " on " << what << (with_variants ? " with variants" : "");
  }
}

TEST(DescribeCostTest, WorkingBytesBoundThePeakHeapOfEveryKind) {
  if (!heap_meter::Available()) GTEST_SKIP() << kNoMeter;
  const std::vector<std::string> specs = {
      "rphsd",
      "rphsd:refs=cross7,bins=1000",
      "rphsd:refs=fibonacci:255,bins=10000,variant=reduced",
      "comsd",
      "comsd:grid=16",
      "comsd:grid=200",
      "cnsd",
      "cnsd:max_points=500",
      "cnsd:max_points=500,downsample=random",
      "cnsd:t_step=0.01,max_points=1500",
      "dfsd",
      "dfsd:frame=upright",
      "dfsd:frame=pca,fields=anisotropic",
      "dfsd:frame=axes,grid=32,order=10",
      "dfsd:grid=4,order=3,fields=isotropic,size=0.15",
      "dfsd:smooth=0.02",
      "dfsd:frame=upright,smooth=0.25",
      "learned",
  };
  for (size_t n : {3, 100, 5000, 100000}) {
    const PointCloud cloud = dfsd_golden::MakeCloud("surface_rotated", n);
    for (const std::string& spec : specs) ExpectBounded(spec, cloud, absl::StrCat(n, " points"));
  }
}

// The frames' worst clouds: many hull candidates; past 1,048,576 of them (a straight cloud
// seen side-on, a cylinder from above), sorted in slabs.
TEST(DescribeCostTest, DfsdWorkingBytesBoundDegenerateClouds) {
  if (!heap_meter::Available()) GTEST_SKIP() << kNoMeter;
  struct Case {
    const char* shape;
    size_t n;
    const char* spec;
  };
  for (const Case& c : std::vector<Case>{{"straight", 1100000, "dfsd"},
                                         {"cylinder", 1100000, "dfsd:frame=upright"},
                                         {"flat_grid", 100000, "dfsd"},
                                         {"sphere", 100000, "dfsd"},
                                         {"duplicates", 100000, "dfsd:frame=upright"},
                                         {"few_distinct", 1000, "dfsd"}}) {
    ExpectBounded(c.spec, dfsd_golden::MakeCloud(c.shape, c.n), absl::StrCat(c.shape, " of ", c.n));
  }
}

// DFSD's working memory stops growing with the cloud: every per-point array is a chunk.
TEST(DescribeCostTest, DfsdPeakHeapIsBounded) {
  if (!heap_meter::Available()) GTEST_SKIP() << kNoMeter;
  for (const char* spec : {"dfsd", "dfsd:frame=upright", "dfsd:frame=axes", "dfsd:smooth=0.02"}) {
    const std::unique_ptr<Descriptor> descriptor = Make(spec);
    ASSERT_NE(descriptor, nullptr);
    const int64_t small =
        PeakOf(*descriptor, dfsd_golden::MakeCloud("surface_rotated", 300000), true);
    const int64_t large =
        PeakOf(*descriptor, dfsd_golden::MakeCloud("surface_rotated", 2000000), true);
    // The cloud grows 6.7x (24 MB); the peak may grow by the hull's in-memory sort (12 MiB).
    EXPECT_LE(large, small + (int64_t{13} << 20)) << spec;
    EXPECT_LE(large, int64_t{32} << 20) << spec;
    EXPECT_LE(descriptor->EstimateCost(1000000000).working_bytes, size_t{48} << 20) << spec;
  }
}

TEST(DescribeCostTest, EstimatingAllocatesNothingAndGrowsWithTheCloud) {
  for (const char* spec :
       {"rphsd", "comsd", "cnsd", "cnsd:downsample=random", "dfsd", "dfsd:frame=upright",
        "dfsd:frame=pca", "dfsd:frame=axes", "dfsd:smooth=0.02"}) {
    const std::unique_ptr<Descriptor> descriptor = Make(spec);
    ASSERT_NE(descriptor, nullptr);
    heap_meter::Start();
    const DescribeCost small = descriptor->EstimateCost(1000);
    const DescribeCost large = descriptor->EstimateCost(1000000);
    EXPECT_EQ(heap_meter::Stop(), 0) << spec;
    EXPECT_GT(small.cpu, absl::ZeroDuration()) << spec;
    EXPECT_GT(large.cpu, small.cpu) << spec;
    EXPECT_GT(small.working_bytes, 0u) << spec;
    EXPECT_GE(large.working_bytes, small.working_bytes) << spec;
  }
}

}  // namespace
}  // namespace shapeid
