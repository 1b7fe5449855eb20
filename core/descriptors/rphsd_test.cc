#include "core/descriptors/rphsd.h"

#include <algorithm>
#include <cmath>
#include <random>

#include "absl/strings/str_cat.h"
#include "core/descriptor_registry.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;

std::unique_ptr<Descriptor> MustCreate(absl::string_view spec) {
  auto d = CreateDescriptor(spec);
  EXPECT_TRUE(d.ok()) << d.status();
  return std::move(d).value();
}

std::vector<float> MustCompute(const Descriptor& d, const PointCloud& cloud) {
  auto v = d.Compute(cloud);
  EXPECT_TRUE(v.ok()) << v.status();
  return v.ok() ? *v : std::vector<float>();
}

PointCloud RandomCloud(size_t n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> gauss(0.0f, 1.0f);
  PointCloud cloud;
  for (size_t i = 0; i < n; ++i) {
    // An anisotropic blob, so the descriptor has structure to see.
    cloud.Add(3.0f * gauss(rng), gauss(rng), 0.5f * gauss(rng) + 0.2f * gauss(rng) * gauss(rng));
  }
  return cloud;
}

// Worked by hand. Cloud {(2,0,0), (-2,0,0), (0,1,0), (0,-1,0)}: centroid 0, L-infinity
// radius 2, so normalized {(1,0,0), (-1,0,0), (0,.5,0), (0,-.5,0)}.
// References q1 = (0,0,0), q2 = (1,0,0); M = 4, bin width d_max / M = 2 sqrt(3) / 4 = 0.8660.
//   q1: distances 1, 1, .5, .5  -> bins 1, 1, 0, 0       -> h1 = [.5, .5, 0, 0]
//   q2: distances 0, 2, 1.118, 1.118 -> bins 0, 2, 1, 1  -> h2 = [.25, .5, .25, 0]
// (distance / 0.866: 1.155, 0.577, 0, 2.309, 1.291: all well inside their bins).
// Features, mean bin height 1/M = .25:
//   var(h1) = (4 * .25^2) / 4 = .0625           var(h2) = (0 + .25^2 + 0 + .25^2) / 4 = .03125
//   ent(h1) = -2 (.5 ln .5) = ln 2              ent(h2) = -(2 * .25 ln .25 + .5 ln .5) = 1.5 ln 2
//   idm(h1) = .5/1 + .5/2 = .75                 idm(h2) = .25/1 + .5/2 + .25/5 = .55
// Reduced: mean/std over the two references: var .046875 / .015625, ent 1.25 ln 2 / .25 ln 2,
// idm .65 / .1.
TEST(RphsdTest, HandComputedCompleteAndReduced) {
  const PointCloud cloud{{2, 0, 0}, {-2, 0, 0}, {0, 1, 0}, {0, -1, 0}};
  const double ln2 = std::log(2.0);
  const auto complete = MustCreate("rphsd:refs=[0,0,0;1,0,0],bins=4");
  EXPECT_THAT(MustCompute(*complete, cloud),
              ::testing::Pointwise(::testing::FloatNear(1e-7f),
                                   std::vector<float>{0.0625f, 0.03125f, float(ln2),
                                                      float(1.5 * ln2), 0.75f, 0.55f}));
  const auto reduced = MustCreate("rphsd:refs=[0,0,0;1,0,0],bins=4,variant=reduced");
  EXPECT_THAT(MustCompute(*reduced, cloud),
              ::testing::Pointwise(::testing::FloatNear(1e-7f),
                                   std::vector<float>{0.046875f, 0.015625f, float(1.25 * ln2),
                                                      float(0.25 * ln2), 0.65f, 0.1f}));
}

// A reference at the far corner sees the opposite corner at exactly d_max: the clamp puts it
// in the last bin instead of writing past the histogram (the author's code had no clamp).
// {(1,1,1), (-1,-1,-1), (1,-1,-1), (-1,1,1)} has centroid 0, radius 1. From q = (1,1,1) the
// distances are 0, 2 sqrt 3 (= d_max), 2 sqrt 2, 2 -> with M = 2: bins 0, 1 (clamped from 2),
// floor(2 * 2.828 / 3.464) = 1, floor(2 * 2 / 3.464) = 1 -> h = [.25, .75].
TEST(RphsdTest, FarthestPairLandsInLastBin) {
  const PointCloud cloud{{1, 1, 1}, {-1, -1, -1}, {1, -1, -1}, {-1, 1, 1}};
  const auto d = MustCreate("rphsd:refs=[1,1,1],bins=2");
  const std::vector<float> v = MustCompute(*d, cloud);
  // var = ((.25-.5)^2 + (.75-.5)^2) / 2 = .0625; ent = -(.25 ln .25 + .75 ln .75);
  // idm = .25 + .75/2 = .625.
  const double ent = -(0.25 * std::log(0.25) + 0.75 * std::log(0.75));
  EXPECT_THAT(v, ::testing::Pointwise(::testing::FloatNear(1e-7f),
                                      std::vector<float>{0.0625f, float(ent), 0.625f}));
}

TEST(RphsdTest, DimensionsFollowReferencesAndVariant) {
  EXPECT_EQ(MustCreate("rphsd")->dimension(), 81u);
  EXPECT_EQ(MustCreate("rphsd:refs=cross7")->dimension(), 21u);
  EXPECT_EQ(MustCreate("rphsd:refs=spherical27")->dimension(), 81u);
  EXPECT_EQ(MustCreate("rphsd:refs=fibonacci:64")->dimension(), 3u * 65u);
  EXPECT_EQ(MustCreate("rphsd:variant=reduced,refs=fibonacci:64")->dimension(), 6u);
}

TEST(RphsdTest, CanonicalSpecFillsDefaultsAndNormalizes) {
  EXPECT_EQ(MustCreate("rphsd")->spec().ToString(), "rphsd:refs=cubic27,bins=100,variant=complete");
  EXPECT_EQ(MustCreate("RPHSD:variant=Reduced,bins=010,refs=Cross7")->spec().ToString(),
            "rphsd:refs=cross7,bins=10,variant=reduced");
  EXPECT_EQ(MustCreate("rphsd:refs=[0,0,0; 0.5,1e-1,-1]")->spec().ToString(),
            "rphsd:refs=[0,0,0;0.5,0.100000001,-1],bins=100,variant=complete");
  // The canonical text describes the same descriptor.
  const auto a = MustCreate("rphsd:refs=[0,0,0; 0.5,1e-1,-1]");
  const auto b = MustCreate(a->spec().ToString());
  const PointCloud cloud = RandomCloud(500, 1);
  EXPECT_EQ(MustCompute(*a, cloud), MustCompute(*b, cloud));
}

TEST(RphsdTest, RejectsBadSpecs) {
  for (const auto& [spec, message] : std::vector<std::pair<std::string, std::string>>{
           {"rphsd:bins=0", "bins=0 is outside [1, 100000]"},
           {"rphsd:bins=many", "bins=many is not an integer"},
           {"rphsd:refs=octahedron", "is not an arrangement"},
           {"rphsd:refs=fibonacci:0", "fibonacci:N needs N"},
           {"rphsd:refs=[0,0]", "needs 3 coordinates"},
           {"rphsd:refs=[0,0,nan]", "is not a number"},
           {"rphsd:refs=[0,0,1000]", "is not a number in [-100, 100]"},
           {"rphsd:variant=tiny", "variant=tiny is not one of complete, reduced"},
           {"rphsd:bin=3", "rphsd has no parameter \"bin\"; its parameters: refs, bins, variant"},
       }) {
    const auto d = CreateDescriptor(spec);
    ASSERT_FALSE(d.ok()) << spec;
    EXPECT_EQ(d.status().code(), absl::StatusCode::kInvalidArgument) << spec;
    EXPECT_THAT(d.status().message(), HasSubstr(message)) << spec;
  }
}

TEST(RphsdTest, InvariantToTranslationAndUniformScale) {
  // Powers of two keep the scaled cloud exact, so the descriptors match to the bit; an
  // arbitrary factor and offset match to float rounding.
  const PointCloud cloud = RandomCloud(2000, 2);
  for (const char* spec :
       {"rphsd", "rphsd:refs=cross7,bins=10,variant=reduced", "rphsd:refs=spherical27,bins=50"}) {
    const auto d = MustCreate(spec);
    const std::vector<float> base = MustCompute(*d, cloud);
    std::vector<float> pow2(cloud.xyz().begin(), cloud.xyz().end());
    for (float& v : pow2) v *= 8.0f;
    EXPECT_EQ(MustCompute(*d, PointCloud(pow2)), base) << spec;

    PointCloud moved;
    for (size_t i = 0; i < cloud.size(); ++i) {
      const auto p = cloud.point(i);
      moved.Add(p.x() * 3.7f + 12.5f, p.y() * 3.7f - 4.0f, p.z() * 3.7f + 100.0f);
    }
    const std::vector<float> other = MustCompute(*d, moved);
    ASSERT_EQ(other.size(), base.size());
    // Rounding can move a point across a bin edge; with 2000 points that changes a bin height
    // by 1/2000, hence the tolerance.
    for (size_t i = 0; i < base.size(); ++i)
      EXPECT_NEAR(other[i], base[i], 2e-3) << spec << " " << i;
  }
}

TEST(RphsdTest, InvariantToPointOrder) {
  const PointCloud cloud = RandomCloud(3000, 3);
  std::vector<size_t> order(cloud.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::shuffle(order.begin(), order.end(), std::mt19937(7));
  PointCloud shuffled;
  for (size_t i : order) shuffled.Add(cloud.point(i));
  const auto d = MustCreate("rphsd");
  const std::vector<float> a = MustCompute(*d, cloud);
  const std::vector<float> b = MustCompute(*d, shuffled);
  ASSERT_EQ(a.size(), b.size());
  // Only the centroid's summation order changes; its effect is below float resolution.
  for (size_t i = 0; i < a.size(); ++i) EXPECT_NEAR(a[i], b[i], 1e-6) << i;
}

// Rotations by 90 degrees about an axis map cross7 and cubic27 onto themselves, so they
// permute the histograms, and the reduced descriptor (means and stds over references) stays.
TEST(RphsdTest, ReducedInvariantUnderAxisRotations) {
  const PointCloud cloud = RandomCloud(2000, 4);
  using Rot = Eigen::Vector3f (*)(const Eigen::Vector3f&);
  const std::vector<std::pair<const char*, Rot>> rotations = {
      {"x+90", [](const Eigen::Vector3f& p) { return Eigen::Vector3f(p.x(), -p.z(), p.y()); }},
      {"y+90", [](const Eigen::Vector3f& p) { return Eigen::Vector3f(p.z(), p.y(), -p.x()); }},
      {"z+90", [](const Eigen::Vector3f& p) { return Eigen::Vector3f(-p.y(), p.x(), p.z()); }},
      {"z+180", [](const Eigen::Vector3f& p) { return Eigen::Vector3f(-p.x(), -p.y(), p.z()); }},
  };
  for (const char* spec :
       {"rphsd:refs=cross7,variant=reduced", "rphsd:refs=cubic27,variant=reduced",
        "rphsd:refs=cubic27,bins=10,variant=reduced"}) {
    const auto d = MustCreate(spec);
    const std::vector<float> base = MustCompute(*d, cloud);
    for (const auto& [name, rotate] : rotations) {
      PointCloud rotated;
      for (size_t i = 0; i < cloud.size(); ++i) rotated.Add(rotate(cloud.point(i)));
      const std::vector<float> v = MustCompute(*d, rotated);
      for (size_t i = 0; i < base.size(); ++i) {
        EXPECT_NEAR(v[i], base[i], 1e-6) << spec << " " << name << " value " << i;
      }
    }
  }
}

TEST(RphsdTest, CompleteDescriptorSeesRotation) {
  // The contrast to the test above: per-reference features are orientation dependent.
  const PointCloud cloud = RandomCloud(2000, 5);
  PointCloud rotated;
  for (size_t i = 0; i < cloud.size(); ++i) {
    const auto p = cloud.point(i);
    rotated.Add(-p.y(), p.x(), p.z());
  }
  const auto d = MustCreate("rphsd:refs=cross7");
  EXPECT_NE(MustCompute(*d, cloud), MustCompute(*d, rotated));
}

TEST(RphsdTest, BitIdenticalOnRepeatedRunsAndAcrossSimdLevels) {
  const PointCloud cloud = RandomCloud(20000, 6);
  for (const char* spec : {"rphsd", "rphsd:refs=cross7,bins=10", "rphsd:refs=fibonacci:100,bins=37",
                           "rphsd:refs=spherical27,variant=reduced"}) {
    auto created = Rphsd::Create([&] {
      auto generic = CreateDescriptor(spec);
      EXPECT_TRUE(generic.ok());
      return static_cast<const Rphsd&>(**generic).options();
    }());
    ASSERT_TRUE(created.ok());
    const Rphsd& d = **created;
    std::vector<float> reference;
    ASSERT_TRUE(d.ComputeAtLevel(cloud, SimdLevel::kScalar, &reference).ok());
    EXPECT_EQ(MustCompute(d, cloud), reference) << spec;
    EXPECT_EQ(MustCompute(d, cloud), MustCompute(d, cloud)) << spec;
    for (SimdLevel level : {SimdLevel::kAvx2, SimdLevel::kAvx512}) {
      if (level > DetectedSimdLevel()) {
        std::cout << "[  NOTE    ] " << SimdLevelName(level) << " not supported by this CPU\n";
        continue;
      }
      std::vector<float> v;
      ASSERT_TRUE(d.ComputeAtLevel(cloud, level, &v).ok());
      EXPECT_EQ(v, reference) << spec << " at " << SimdLevelName(level);
    }
  }
}

// A cloud split across threads (CloudLimits::max_threads) counts the same histograms: the
// same bits for every thread count, including splits that leave a part of odd size.
TEST(RphsdTest, BitIdenticalWhateverTheThreadCount) {
  const size_t n = 3 * static_cast<size_t>(Rphsd::kMinPointsPerThread) + 7;
  const PointCloud cloud = RandomCloud(n, 11);
  for (const char* spec : {"rphsd", "rphsd:refs=fibonacci:40,bins=53,variant=reduced"}) {
    auto created = CreateDescriptor(spec);
    ASSERT_TRUE(created.ok()) << created.status();
    const Descriptor& d = **created;
    const std::vector<float> one_thread = MustCompute(d, cloud);
    for (const int threads : {2, 3, 8}) {
      CloudLimits limits;
      limits.max_threads = threads;
      std::vector<float> v;
      ASSERT_TRUE(d.Compute(cloud, &v, limits).ok());
      EXPECT_EQ(v, one_thread) << spec << " on " << threads << " threads";
    }
  }
}

TEST(RphsdTest, HistogramsSumToOne) {
  // Every point lands in exactly one bin of every histogram: with M = 1 each histogram is
  // [1], so variance 0, entropy 0, IDM 1, whatever the cloud.
  const auto d = MustCreate("rphsd:refs=cubic27,bins=1");
  const std::vector<float> v = MustCompute(*d, RandomCloud(1000, 8));
  for (size_t k = 0; k < 27; ++k) {
    EXPECT_EQ(v[k], 0.0f);
    EXPECT_EQ(v[27 + k], 0.0f);
    EXPECT_EQ(v[54 + k], 1.0f);
  }
}

TEST(RphsdTest, InvalidCloudsAreErrorsNotCrashes) {
  const auto d = MustCreate("rphsd");
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  const std::vector<std::pair<PointCloud, std::string>> cases = {
      {PointCloud(), "cloud has 0 points; at least 3 are needed"},
      {PointCloud{{1, 2, 3}, {4, 5, 6}}, "cloud has 2 points"},
      {PointCloud{{1, 2, 3}, {nan, 5, 6}, {1, 1, 1}}, "point 1 has a non-finite coordinate"},
      {PointCloud{{1, 2, 3}, {4, 5, 6}, {1, inf, 1}}, "point 2 has a non-finite coordinate"},
      {PointCloud{{1, 2, 3}, {1, 2, 3}, {1, 2, 3}}, "all 3 points are identical"},
  };
  for (const auto& [cloud, message] : cases) {
    const auto v = d->Compute(cloud);
    ASSERT_FALSE(v.ok()) << message;
    EXPECT_EQ(v.status().code(), absl::StatusCode::kInvalidArgument);
    EXPECT_THAT(v.status().message(), HasSubstr(message));
  }
  const auto limited = d->Compute(RandomCloud(100, 9), CloudLimits{50});
  EXPECT_EQ(limited.status().code(), absl::StatusCode::kResourceExhausted);
  EXPECT_THAT(limited.status().message(),
              HasSubstr("cloud has 100 points, more than the limit of 50"));
}

TEST(RphsdTest, TinyAndHugeExtentsStayFinite) {
  const auto d = MustCreate("rphsd");
  for (float scale : {1e-30f, 1e-10f, 1e10f, 1e30f}) {
    PointCloud cloud;
    const PointCloud base = RandomCloud(200, 10);
    for (size_t i = 0; i < base.size(); ++i) cloud.Add(base.point(i) * scale);
    const auto v = d->Compute(cloud);
    ASSERT_TRUE(v.ok()) << scale << ": " << v.status();
    for (float x : *v) EXPECT_TRUE(std::isfinite(x)) << scale;
  }
}

}  // namespace
}  // namespace shapeid
