#include "core/descriptors/dfsd.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "Eigen/Geometry"
#include "absl/status/status.h"
#include "core/descriptor.h"
#include "core/descriptor_registry.h"
#include "core/descriptors/dfsd_kernels.h"
#include "core/descriptors/point_smoothing.h"
#include "core/point_cloud.h"
#include "core/simd.h"
#include "core/testing/test_clouds.h"
#include "core/views/test_surfaces.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using dfsd_internal::Frequency;
using dfsd_internal::KeptFrequencies;
using ::testing::HasSubstr;

std::unique_ptr<Descriptor> MustCreate(const std::string& spec) {
  absl::StatusOr<std::unique_ptr<Descriptor>> d = CreateDescriptor(spec);
  EXPECT_TRUE(d.ok()) << spec << ": " << d.status();
  return d.ok() ? std::move(d).value() : nullptr;
}

std::vector<float> MustCompute(const Descriptor& d, const PointCloud& cloud) {
  absl::StatusOr<std::vector<float>> v = d.Compute(cloud);
  EXPECT_TRUE(v.ok()) << v.status();
  return v.ok() ? *v : std::vector<float>{};
}

// A cloud with three different spreads and skewed along its first two principal axes, so its
// principal frame is well defined (what the pca frame needs to be stable).
PointCloud SkewedCloud(size_t n, uint32_t seed) {
  const PointCloud base = testing_clouds::UniformCloud(n, seed);
  PointCloud cloud;
  for (size_t i = 0; i < base.size(); ++i) {
    const Eigen::Vector3f p = base.point(i);
    const float y = 0.25f * (p.y() + 2) * (p.y() + 2) - 2;  // skewed towards -y
    const float x = 0.5f * (p.x() + 1) * (p.x() + 1) - 1;   // skewed towards -x
    cloud.Add(x, y, p.z());
  }
  return cloud;
}

PointCloud Transformed(const PointCloud& cloud, const Eigen::Matrix3f& rotation,
                       const Eigen::Vector3f& shift, float scale) {
  PointCloud out;
  for (size_t i = 0; i < cloud.size(); ++i) out.Add(scale * (rotation * cloud.point(i)) + shift);
  return out;
}

// The definition, straight from docs/descriptors.md section 5, in double: every cell against
// every point, then the full triple sum of the DCT. Axes frame.
std::vector<double> ReferenceDfsd(const PointCloud& cloud, int g, int order, bool isotropic_first,
                                  int fields) {
  Eigen::Vector3d lo = cloud.point(0).cast<double>(), hi = lo;
  for (size_t p = 0; p < cloud.size(); ++p) {
    lo = lo.cwiseMin(cloud.point(p).cast<double>());
    hi = hi.cwiseMax(cloud.point(p).cast<double>());
  }
  const Eigen::Vector3d center = 0.5 * (lo + hi), half = 0.5 * (hi - lo);
  std::vector<double> out;
  for (int f = 0; f < fields; ++f) {
    const bool isotropic = f == 0 ? isotropic_first : !isotropic_first;
    Eigen::Vector3d scale;
    for (int a = 0; a < 3; ++a) scale[a] = 1.0 / (isotropic ? half.maxCoeff() : half[a]);
    std::vector<double> field(static_cast<size_t>(g) * g * g);
    for (int i = 0; i < g; ++i) {
      for (int j = 0; j < g; ++j) {
        for (int k = 0; k < g; ++k) {
          const Eigen::Vector3d c((2.0 * i + 1) / g - 1, (2.0 * j + 1) / g - 1,
                                  (2.0 * k + 1) / g - 1);
          double best = 1e300;
          for (size_t p = 0; p < cloud.size(); ++p) {
            const Eigen::Vector3d v = (cloud.point(p).cast<double>() - center).cwiseProduct(scale);
            best = std::min(best, (v - c).norm());
          }
          field[(static_cast<size_t>(i) * g + j) * g + k] = std::sqrt(best) / std::pow(g, 1.5);
        }
      }
    }
    const auto basis = [g](int freq, int i) {
      return std::sqrt((freq == 0 ? 1.0 : 2.0) / g) *
             std::cos(M_PI * (2 * i + 1) * freq / (2.0 * g));
    };
    for (const Frequency& q : KeptFrequencies(g, order)) {
      double sum = 0;
      for (int i = 0; i < g; ++i) {
        for (int j = 0; j < g; ++j) {
          for (int k = 0; k < g; ++k) {
            sum += field[(static_cast<size_t>(i) * g + j) * g + k] * basis(q.a, i) * basis(q.b, j) *
                   basis(q.c, k);
          }
        }
      }
      out.push_back(sum);
    }
  }
  return out;
}

TEST(DfsdTest, DefaultSpecIsCanonicalAndHas240Values) {
  auto d = MustCreate("dfsd");
  ASSERT_NE(d, nullptr);
  EXPECT_EQ(d->spec().ToString(), "dfsd:grid=12,order=8,frame=box,fields=both,size=0");
  EXPECT_EQ(d->dimension(), 240u);
  EXPECT_EQ(MustCreate("dfsd:fields=isotropic")->dimension(), 120u);
  EXPECT_EQ(MustCreate("dfsd:size=0.15")->dimension(), 243u);
  EXPECT_EQ(MustCreate("dfsd:size=0.150")->spec().ToString(),
            "dfsd:grid=12,order=8,frame=box,fields=both,size=0.15");
}

TEST(DfsdTest, KeptFrequenciesAreTheLowPassInOrder) {
  const std::vector<Frequency> kept = KeptFrequencies(12, 8);
  ASSERT_EQ(kept.size(), 120u);  // C(8 + 2, 3)
  EXPECT_EQ(kept[0].a + kept[0].b + kept[0].c, 0);
  for (size_t q = 1; q < kept.size(); ++q) {
    const int prev = kept[q - 1].a + kept[q - 1].b + kept[q - 1].c;
    const int cur = kept[q].a + kept[q].b + kept[q].c;
    EXPECT_LE(prev, cur);
    EXPECT_LT(cur, 8);
  }
  // An order past what the grid holds keeps every frequency exactly once.
  EXPECT_EQ(KeptFrequencies(4, 10).size(), 64u);
  EXPECT_EQ(KeptFrequencies(5, 3).size(), 10u);
}

TEST(DfsdTest, MatchesTheDefinitionComputedInDouble) {
  const PointCloud cloud = SkewedCloud(300, 7);
  for (const auto& [spec, isotropic_first, fields] :
       std::vector<std::tuple<std::string, bool, int>>{
           {"dfsd:grid=6,order=5,frame=axes", true, 2},
           {"dfsd:grid=7,order=19,fields=anisotropic,frame=axes", false, 1},
           {"dfsd:grid=5,order=1,fields=isotropic,frame=axes", true, 1}}) {
    SCOPED_TRACE(spec);
    auto d = MustCreate(spec);
    ASSERT_NE(d, nullptr);
    const std::vector<float> got = MustCompute(*d, cloud);
    const int g = std::stoi(d->spec().Find("grid")->c_str());
    const int order = std::stoi(d->spec().Find("order")->c_str());
    const std::vector<double> want = ReferenceDfsd(cloud, g, order, isotropic_first, fields);
    ASSERT_EQ(got.size(), want.size());
    for (size_t q = 0; q < want.size(); ++q) EXPECT_NEAR(got[q], want[q], 2e-6) << q;
  }
}

// The kernel's input over `tables`: G rows of dx2, then of dy2, then of dz2, `stride` apart.
dfsd_internal::FieldInput KernelInput(const std::vector<float>& tables, int g, size_t stride) {
  return dfsd_internal::LaidOutInput(tables.data(), g, stride);
}

TEST(DfsdTest, EverySimdLevelGivesTheSameBits) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(0.0f, 4.0f);
  for (int g : {4, 5, 7, 12}) {
    for (size_t n : {size_t{3}, size_t{16}, size_t{37}}) {
      const size_t stride = (n + dfsd_internal::kPointLanes - 1) / dfsd_internal::kPointLanes *
                            dfsd_internal::kPointLanes;
      std::vector<float> tables(3 * g * stride, dfsd_internal::kFarSquared);
      for (int a = 0; a < 3 * g; ++a) {
        for (size_t p = 0; p < n; ++p) tables[a * stride + p] = u(rng);
      }
      const dfsd_internal::FieldInput in = KernelInput(tables, g, stride);
      std::vector<float> scalar(g * g * g), vector(g * g * g);
      dfsd_internal::NearestSquaredDistances(in, scalar.data(), SimdLevel::kScalar);
      // Spot check against the plain definition.
      EXPECT_EQ(scalar[0], [&] {
        float m = dfsd_internal::kFarSquared;
        for (size_t p = 0; p < n; ++p) m = std::min(m, (in.dx2[p] + in.dy2[p]) + in.dz2[p]);
        return m;
      }());
      for (SimdLevel level : {SimdLevel::kAvx2, SimdLevel::kAvx512}) {
        if (level > DetectedSimdLevel()) continue;
        dfsd_internal::NearestSquaredDistances(in, vector.data(), level);
        EXPECT_EQ(0, std::memcmp(scalar.data(), vector.data(), scalar.size() * sizeof(float)))
            << "grid " << g << " points " << n << " level " << SimdLevelName(level);
      }
    }
  }
}

TEST(DfsdTest, AccumulatingChunksGivesTheBitsOfOnePass) {
  // Tables of 48 points in one pass, and the same points as 32 then 16 with accumulate.
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0.0f, 4.0f);
  const int g = 7;
  const auto make_tables = [&](size_t stride, const std::vector<float>& values, size_t first,
                               size_t count) {
    std::vector<float> tables(3 * g * stride, dfsd_internal::kFarSquared);
    for (int a = 0; a < 3 * g; ++a) {
      for (size_t p = 0; p < count; ++p) tables[a * stride + p] = values[a * 48 + first + p];
    }
    return tables;
  };
  std::vector<float> values(3 * g * 48);
  for (float& v : values) v = u(rng);
  const auto run = [&](const std::vector<float>& tables, size_t stride, bool accumulate,
                       SimdLevel level, std::vector<float>* out) {
    dfsd_internal::FieldInput in = KernelInput(tables, g, stride);
    in.accumulate = accumulate;
    dfsd_internal::NearestSquaredDistances(in, out->data(), level);
  };
  for (SimdLevel level : {SimdLevel::kScalar, SimdLevel::kAvx2, SimdLevel::kAvx512}) {
    if (level > DetectedSimdLevel()) continue;
    std::vector<float> whole(g * g * g), chunked(g * g * g);
    run(make_tables(48, values, 0, 48), 48, false, level, &whole);
    run(make_tables(32, values, 0, 32), 32, false, level, &chunked);
    run(make_tables(16, values, 32, 16), 16, true, level, &chunked);
    EXPECT_EQ(0, std::memcmp(whole.data(), chunked.data(), whole.size() * sizeof(float)))
        << SimdLevelName(level);
  }
}

TEST(DfsdTest, CloudsOfSeveralKernelChunksMatchTheDefinition) {
  // 300,000 points: the kernel sees them as chunks of 65,536, four times, then 37,856 (a
  // short last one).
  const PointCloud cloud = SkewedCloud(300000, 21);
  auto d = MustCreate("dfsd:grid=6,order=5,frame=axes");
  const std::vector<float> got = MustCompute(*d, cloud);
  const std::vector<double> want = ReferenceDfsd(cloud, 6, 5, true, 2);
  ASSERT_EQ(got.size(), want.size());
  for (size_t q = 0; q < want.size(); ++q) EXPECT_NEAR(got[q], want[q], 2e-6) << q;
  // Another order puts other points in each chunk: the same bits, as for one pass.
  PointCloud reversed;
  for (size_t i = cloud.size(); i-- > 0;) reversed.Add(cloud.point(i));
  EXPECT_EQ(MustCompute(*d, reversed), got);
}

TEST(DfsdTest, AxesFrameIgnoresPointOrderShiftAndScaleButNotRotation) {
  auto d = MustCreate("dfsd:frame=axes");
  const PointCloud cloud = SkewedCloud(1024, 11);
  const std::vector<float> base = MustCompute(*d, cloud);
  PointCloud reversed;
  for (size_t i = cloud.size(); i-- > 0;) reversed.Add(cloud.point(i));
  EXPECT_EQ(MustCompute(*d, reversed), base);  // minima and box do not depend on order
  const std::vector<float> moved = MustCompute(
      *d, Transformed(cloud, Eigen::Matrix3f::Identity(), Eigen::Vector3f(5, -3, 2), 4.0f));
  for (size_t q = 0; q < base.size(); ++q) EXPECT_NEAR(moved[q], base[q], 1e-5) << q;
  const Eigen::Matrix3f turn =
      Eigen::AngleAxisf(0.7f, Eigen::Vector3f(1, 2, 3).normalized()).toRotationMatrix();
  const std::vector<float> turned =
      MustCompute(*d, Transformed(cloud, turn, Eigen::Vector3f::Zero(), 1.0f));
  double diff = 0;
  for (size_t q = 0; q < base.size(); ++q) diff += std::abs(turned[q] - base[q]);
  EXPECT_GT(diff, 1e-2);
}

TEST(DfsdTest, PcaFrameIsRotationInvariant) {
  auto pca = MustCreate("dfsd:frame=pca");
  const PointCloud cloud = SkewedCloud(1024, 5);
  const std::vector<float> base = MustCompute(*pca, cloud);
  std::mt19937 rng(9);
  std::normal_distribution<float> g;
  for (int trial = 0; trial < 5; ++trial) {
    const Eigen::Quaternionf q(g(rng), g(rng), g(rng), g(rng));
    const std::vector<float> turned = MustCompute(
        *pca, Transformed(cloud, q.normalized().toRotationMatrix(), Eigen::Vector3f(1, 2, 3), 2));
    for (size_t k = 0; k < base.size(); ++k) EXPECT_NEAR(turned[k], base[k], 2e-4) << k;
  }
}

// Squared distance between two descriptors.
double DistanceSq(const std::vector<float>& a, const float* b) {
  double sum = 0;
  for (size_t q = 0; q < a.size(); ++q) sum += (a[q] - b[q]) * (a[q] - b[q]);
  return sum;
}

// The least squared distance from `query` or any of its pose variants to `reference`.
double BestPoseDistanceSq(const Descriptor& d, const PointCloud& query,
                          const std::vector<float>& reference) {
  std::vector<float> canonical, variants;
  EXPECT_TRUE(d.ComputeWithPoseVariants(query, &canonical, &variants).ok());
  double best = DistanceSq(canonical, reference.data());
  for (size_t o = 0; o < variants.size(); o += d.dimension()) {
    best = std::min(best, DistanceSq(reference, variants.data() + o));
  }
  return best;
}

TEST(DfsdTest, PoseMapIsTheDescriptorOfTheReorderedMirroredCloud) {
  // In the axes frame, reorder and reverse the cloud's axes about its box center
  // explicitly: the descriptor must be PoseMap applied to the original's.
  DfsdOptions anisotropic;
  anisotropic.fields = DfsdOptions::Fields::kAnisotropic;
  anisotropic.size_weight = 0.3;
  DfsdOptions small;
  small.grid = 8;
  small.order = 5;
  for (const auto& [spec, options] : std::vector<std::pair<std::string, DfsdOptions>>{
           {"dfsd:frame=axes", DfsdOptions()},
           {"dfsd:fields=anisotropic,size=0.3,frame=axes", anisotropic},
           {"dfsd:grid=8,order=5,frame=axes", small}}) {
    auto d = MustCreate(spec);
    const PointCloud cloud = SkewedCloud(800, 21);
    const std::vector<float> base = MustCompute(*d, cloud);
    const CloudStats stats = *ValidateCloud(cloud);
    const Eigen::Vector3f center = (0.5 * (stats.min + stats.max)).cast<float>();
    for (const auto& [axis_of, flips] : std::vector<std::pair<std::array<int, 3>, int>>{
             {{0, 1, 2}, 1}, {{0, 1, 2}, 6}, {{1, 0, 2}, 0}, {{2, 0, 1}, 5}, {{1, 2, 0}, 7}}) {
      PointCloud moved;
      for (size_t i = 0; i < cloud.size(); ++i) {
        const Eigen::Vector3f p = cloud.point(i) - center;
        Eigen::Vector3f q;
        for (int a = 0; a < 3; ++a) q[a] = (flips >> a & 1) ? -p[axis_of[a]] : p[axis_of[a]];
        moved.Add(q);
      }
      std::vector<int> source;
      std::vector<float> sign;
      dfsd_internal::PoseMap(options, axis_of, flips, &source, &sign);
      ASSERT_EQ(source.size(), base.size());
      const std::vector<float> expected = MustCompute(*d, moved);
      for (size_t q = 0; q < base.size(); ++q) {
        EXPECT_NEAR(sign[q] * base[static_cast<size_t>(source[q])], expected[q], 2e-5)
            << spec << " axes " << axis_of[0] << axis_of[1] << axis_of[2] << " flips " << flips
            << " value " << q;
      }
    }
  }
}

TEST(DfsdTest, BoxFrameIsRotationAndMirrorInvariant) {
  auto box = MustCreate("dfsd:frame=box");
  EXPECT_EQ(box->spec().ToString(), "dfsd:grid=12,order=8,frame=box,fields=both,size=0");
  const PointCloud cloud = SkewedCloud(1024, 5);
  const std::vector<float> base = MustCompute(*box, cloud);
  double norm_sq = DistanceSq(base, std::vector<float>(base.size(), 0.0f).data());
  std::mt19937 rng(9);
  std::normal_distribution<float> g;
  for (int trial = 0; trial < 6; ++trial) {
    const Eigen::Quaternionf q(g(rng), g(rng), g(rng), g(rng));
    Eigen::Matrix3f turn = q.normalized().toRotationMatrix();
    if (trial % 2 == 1) turn.col(0) = -turn.col(0);  // a mirror image
    const PointCloud moved = Transformed(cloud, turn, Eigen::Vector3f(1, 2, 3), 2);
    EXPECT_LT(BestPoseDistanceSq(*box, moved, base), 1e-6 * norm_sq) << "trial " << trial;
  }
}

TEST(DfsdTest, BoxFrameOffersPoseVariantsOnlyWhereItIsAmbiguous) {
  auto box = MustCreate("dfsd:frame=box");
  std::vector<float> canonical, variants;
  // Extents 4 : 2 : 1 and skewed along x and y: only z's sign is a guess.
  ASSERT_TRUE(box->ComputeWithPoseVariants(SkewedCloud(1024, 5), &canonical, &variants).ok());
  EXPECT_EQ(variants.size(), 1 * box->dimension());
  // A cube's surface: every order and sign is plausible (47 others).
  const PointCloud cube = test_surfaces::BoxSurface({0, 0, 0}, {1, 1, 1}, 3000, 2);
  ASSERT_TRUE(box->ComputeWithPoseVariants(cube, &canonical, &variants).ok());
  EXPECT_EQ(variants.size(), 47 * box->dimension());
  EXPECT_EQ(canonical, MustCompute(*box, cube));
  // Frames that are not chosen by the shape have no variants.
  for (const char* spec : {"dfsd:frame=axes", "dfsd:frame=pca", "rphsd"}) {
    auto d = MustCreate(spec);
    ASSERT_TRUE(d->ComputeWithPoseVariants(cube, &canonical, &variants).ok());
    EXPECT_TRUE(variants.empty()) << spec;
  }
}

TEST(DfsdTest, BoxFrameMatchesARotatedCubeLikeObjectThroughItsVariants) {
  // A box of extents 2 : 1.9 : 1.8 (its order is a guess) with a bump on one face: under
  // rotation the canonical frame may pick another order, but one variant matches.
  auto box = MustCreate("dfsd:frame=box");
  PointCloud cloud = test_surfaces::BoxSurface({0, 0, 0}, {1, 0.95f, 0.9f}, 3000, 4);
  for (int i = 0; i < 200; ++i) cloud.Add(0.3f + 0.001f * i, 0.2f, 0.9f + 0.0005f * i);
  const std::vector<float> base = MustCompute(*box, cloud);
  const double norm_sq = DistanceSq(base, std::vector<float>(base.size(), 0.0f).data());
  std::mt19937 rng(3);
  std::normal_distribution<float> g;
  for (int trial = 0; trial < 6; ++trial) {
    const Eigen::Quaternionf q(g(rng), g(rng), g(rng), g(rng));
    const PointCloud moved =
        Transformed(cloud, q.normalized().toRotationMatrix(), Eigen::Vector3f::Zero(), 1);
    EXPECT_LT(BestPoseDistanceSq(*box, moved, base), 1e-4 * norm_sq) << "trial " << trial;
  }
}

TEST(DfsdTest, UprightFrameIgnoresYawButKnowsUp) {
  auto upright = MustCreate("dfsd:frame=upright");
  const PointCloud cloud = SkewedCloud(1024, 8);
  const std::vector<float> base = MustCompute(*upright, cloud);
  const double norm_sq = DistanceSq(base, std::vector<float>(base.size(), 0.0f).data());
  for (float yaw : {0.3f, 1.7f, 4.0f}) {
    const Eigen::Matrix3f turn =
        Eigen::AngleAxisf(yaw, Eigen::Vector3f::UnitZ()).toRotationMatrix();
    const PointCloud turned = Transformed(cloud, turn, Eigen::Vector3f(3, -1, 2), 1.5f);
    EXPECT_LT(BestPoseDistanceSq(*upright, turned, base), 1e-6 * norm_sq) << "yaw " << yaw;
  }
  // Upside down is another object to this frame (and no variant turns it back) ...
  const Eigen::Matrix3f flip =
      Eigen::AngleAxisf(3.14159265f, Eigen::Vector3f::UnitX()).toRotationMatrix();
  const PointCloud upside_down = Transformed(cloud, flip, Eigen::Vector3f::Zero(), 1);
  EXPECT_GT(BestPoseDistanceSq(*upright, upside_down, base), 1e-3 * norm_sq);
  // ... while the box frame, which cannot know up, sees the same object.
  auto box = MustCreate("dfsd:frame=box");
  EXPECT_LT(BestPoseDistanceSq(*box, upside_down, MustCompute(*box, cloud)), 1e-6 * norm_sq);

  // A square-footed object: x and y may swap, z never moves.
  const PointCloud tower = test_surfaces::BoxSurface({0, 0, 0}, {1, 1, 3}, 3000, 5);
  std::vector<float> canonical, variants;
  ASSERT_TRUE(upright->ComputeWithPoseVariants(tower, &canonical, &variants).ok());
  // Swaps and flips of x and y only: 2 orders x 4 signs, minus the canonical pose.
  EXPECT_EQ(variants.size(), 7 * upright->dimension());
}

TEST(DfsdTest, UprightFrameTakesTheClientsUpAxis) {
  // The same object stored z up, y up and -x up: each with its own `up` gives bit for bit the
  // descriptor of the z-up cloud, pose variants included (the axes are permuted, not
  // resampled).
  const PointCloud z_up = SkewedCloud(1024, 9);
  std::vector<float> expected, expected_variants;
  ASSERT_TRUE(MustCreate("dfsd:frame=upright")
                  ->ComputeWithPoseVariants(z_up, &expected, &expected_variants)
                  .ok());
  PointCloud y_up, minus_x_up;
  for (size_t p = 0; p < z_up.size(); ++p) {
    const Eigen::Vector3f q = z_up.point(p);
    y_up.Add(q.y(), q.z(), q.x());         // a cyclic permutation: +z goes to +y
    minus_x_up.Add(-q.z(), q.x(), q.y());  // +z goes to -x; x, y to y, z
  }
  for (const auto& [spec, cloud] : std::vector<std::pair<std::string, const PointCloud*>>{
           {"dfsd:frame=upright,up=y", &y_up}, {"dfsd:frame=upright,up=-x", &minus_x_up}}) {
    std::vector<float> got, variants;
    ASSERT_TRUE(MustCreate(spec)->ComputeWithPoseVariants(*cloud, &got, &variants).ok());
    EXPECT_EQ(got, expected) << spec;
    EXPECT_EQ(variants, expected_variants) << spec;
  }
  // With the wrong up, the y-up cloud is lying on its side: another object.
  EXPECT_NE(MustCompute(*MustCreate("dfsd:frame=upright"), y_up), expected);
  // `up` appears in the canonical spec only when it is not the default, so specs written
  // before it existed keep their text.
  EXPECT_EQ(MustCreate("dfsd:frame=upright,up=z")->spec().ToString(),
            "dfsd:grid=12,order=8,frame=upright,fields=both,size=0");
  EXPECT_EQ(MustCreate("dfsd:up=-y,frame=upright")->spec().ToString(),
            "dfsd:grid=12,order=8,frame=upright,fields=both,size=0,up=-y");
}

TEST(DfsdTest, UpDirectionIsTheSpecsUp) {
  using Direction = std::array<float, 3>;
  EXPECT_EQ(MustCreate("dfsd")->up_direction(), (Direction{0, 0, 1}));
  EXPECT_EQ(MustCreate("dfsd:frame=upright,up=y")->up_direction(), (Direction{0, 1, 0}));
  EXPECT_EQ(MustCreate("dfsd:frame=upright,up=-x")->up_direction(), (Direction{-1, 0, 0}));
  EXPECT_EQ(MustCreate("rphsd")->up_direction(), (Direction{0, 0, 1}));
}

TEST(DfsdTest, SizeBlockCarriesTheLogExtentsLargestFirst) {
  auto d = MustCreate("dfsd:frame=axes,size=0.5");
  const PointCloud cloud = testing_clouds::UniformCloud(2000, 1);  // extents ~2, 4, 1
  const std::vector<float> small = MustCompute(*d, cloud);
  const std::vector<float> large =
      MustCompute(*d, Transformed(cloud, Eigen::Matrix3f::Identity(), Eigen::Vector3f::Zero(), 3));
  const size_t n = small.size();
  ASSERT_EQ(n, 243u);
  EXPECT_NEAR(small[n - 3], 0.5 * std::log(4.0), 0.01);
  EXPECT_NEAR(small[n - 2], 0.5 * std::log(2.0), 0.01);
  EXPECT_NEAR(small[n - 1], 0.5 * std::log(1.0), 0.01);
  for (size_t q = 0; q < n - 3; ++q) EXPECT_NEAR(large[q], small[q], 1e-5);
  for (size_t q = n - 3; q < n; ++q) EXPECT_NEAR(large[q] - small[q], 0.5 * std::log(3.0), 1e-5);
}

TEST(DfsdTest, FlatAndStraightCloudsGiveFiniteValues) {
  PointCloud flat, line;
  for (int i = 0; i < 50; ++i) {
    flat.Add(static_cast<float>(i % 7), static_cast<float>(i / 7), 0.0f);
    line.Add(static_cast<float>(i), 0.0f, 0.0f);
  }
  for (const char* spec : {"dfsd:frame=axes,size=1", "dfsd:frame=pca,size=1", "dfsd:size=1",
                           "dfsd:frame=upright,size=1"}) {
    auto d = MustCreate(spec);
    for (const PointCloud* cloud : {&flat, &line}) {
      for (float v : MustCompute(*d, *cloud)) ASSERT_TRUE(std::isfinite(v)) << spec;
    }
  }
}

TEST(DfsdTest, SmoothingIsInTheSpecOnlyWhenOn) {
  EXPECT_EQ(MustCreate("dfsd:smooth=0")->spec().ToString(),
            "dfsd:grid=12,order=8,frame=box,fields=both,size=0");
  EXPECT_EQ(MustCreate("dfsd:smooth=0.10")->spec().ToString(),
            "dfsd:grid=12,order=8,frame=box,fields=both,size=0,smooth=0.1");
  const PointCloud cloud = SkewedCloud(500, 3);
  EXPECT_EQ(MustCompute(*MustCreate("dfsd:smooth=0"), cloud),
            MustCompute(*MustCreate("dfsd"), cloud));
  EXPECT_NE(MustCompute(*MustCreate("dfsd:smooth=0.1"), cloud),
            MustCompute(*MustCreate("dfsd"), cloud));
  // At most 8 points all average to one point: described as given.
  const PointCloud few = {{0, 0, 0}, {1, 0, 0}, {0, 2, 0}, {0, 0, 3}, {1, 1, 1}};
  EXPECT_EQ(MustCompute(*MustCreate("dfsd:smooth=0.02"), few),
            MustCompute(*MustCreate("dfsd"), few));
}

TEST(DfsdTest, SmoothingBringsANoisyCloudsDescriptorBackTowardsTheCleanOne) {
  // A box's surface with Gaussian noise of 2 % of its diagonal: smoothing both sides alike
  // leaves the noisy descriptor nearer the clean one than describing them as they are.
  const PointCloud clean =
      test_surfaces::BoxSurface(Eigen::Vector3f(0, 0, 0), Eigen::Vector3f(1, 0.6f, 0.3f), 1024, 11);
  std::mt19937 rng(4);
  std::normal_distribution<float> noise(0.0f, 0.02f * 2.4f);
  PointCloud noisy;
  for (size_t i = 0; i < clean.size(); ++i) {
    noisy.Add(clean.point(i) + Eigen::Vector3f(noise(rng), noise(rng), noise(rng)));
  }
  double gap[2];
  for (int smooth = 0; smooth < 2; ++smooth) {
    auto d = MustCreate(smooth ? "dfsd:frame=axes,smooth=0.03" : "dfsd:frame=axes");
    const std::vector<float> a = MustCompute(*d, clean), b = MustCompute(*d, noisy);
    gap[smooth] =
        std::sqrt(DistanceSq(a, b.data()) / DistanceSq(a, std::vector<float>(a.size()).data()));
  }
  EXPECT_LT(gap[1], gap[0] / 2) << "relative distance unsmoothed " << gap[0];
}

TEST(DfsdTest, SmoothingKeepsTheBoxFrameRotationInvariant) {
  // Nearest points do not depend on the axes.
  auto box = MustCreate("dfsd:smooth=0.02");
  const PointCloud cloud = SkewedCloud(1024, 5);
  const std::vector<float> base = MustCompute(*box, cloud);
  const double norm_sq = DistanceSq(base, std::vector<float>(base.size(), 0.0f).data());
  const Eigen::Matrix3f turn =
      Eigen::AngleAxisf(1.1f, Eigen::Vector3f(3, -1, 2).normalized()).toRotationMatrix();
  const PointCloud moved = Transformed(cloud, turn, Eigen::Vector3f(1, 2, 3), 2);
  EXPECT_LT(BestPoseDistanceSq(*box, moved, base), 1e-5 * norm_sq);
}

TEST(DfsdTest, SmoothingLargeCloudsDescribesAReducedCloudOfTheSameShape) {
  // Past kSmoothingReferencePoints the smoothed points are a fixed-seed subset, smoothed: the
  // same shape at the grid's resolution, so the descriptor is near the small cloud's.
  auto d = MustCreate("dfsd:frame=axes,smooth=0.02");
  const std::vector<float> small = MustCompute(*d, SkewedCloud(4000, 8));
  const std::vector<float> large = MustCompute(*d, SkewedCloud(100000, 8));
  EXPECT_LT(DistanceSq(small, large.data()),
            0.01 * DistanceSq(small, std::vector<float>(small.size()).data()));
}

TEST(DfsdTest, BadParametersAndCloudsAreRefusedByName) {
  for (const auto& [spec, fragment] : std::vector<std::pair<std::string, std::string>>{
           {"dfsd:grid=3", "grid"},
           {"dfsd:grid=33", "grid"},
           {"dfsd:order=0", "order"},
           {"dfsd:grid=4,order=11", "order"},
           {"dfsd:frame=world", "frame"},
           {"dfsd:fields=all", "fields"},
           {"dfsd:size=-1", "size"},
           {"dfsd:size=nan", "size"},
           {"dfsd:smooth=-0.1", "smooth"},
           {"dfsd:smooth=0.5", "smooth"},
           {"dfsd:frame=upright,up=w", "up"},
           {"dfsd:up=y", "needs frame=upright"},
           {"dfsd:frame=axes,up=-z", "needs frame=upright"}}) {
    absl::StatusOr<std::unique_ptr<Descriptor>> d = CreateDescriptor(spec);
    ASSERT_FALSE(d.ok()) << spec;
    EXPECT_EQ(d.status().code(), absl::StatusCode::kInvalidArgument);
    EXPECT_THAT(d.status().message(), HasSubstr(fragment)) << spec;
  }
  auto d = MustCreate("dfsd");
  EXPECT_EQ(d->Compute(PointCloud{{0, 0, 0}, {1, 1, 1}}).status().code(),
            absl::StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace shapeid
