#include "core/descriptors/dfsd_hull.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include "gtest/gtest.h"

namespace shapeid::dfsd_internal {
namespace {

// ConvexHull as DFSD computed it before issue 25 (octagon filter, then the chain over one
// sorted array): the reference the in-memory and streamed hulls must match.
double Turn(const Eigen::Vector2d& o, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
}

std::vector<Eigen::Vector2d> ReferenceHull(std::vector<Eigen::Vector2d> points) {
  if (points.size() >= 16) {
    static constexpr double kDirections[8][2] = {{1, 0},  {1, 1},   {0, 1},  {-1, 1},
                                                 {-1, 0}, {-1, -1}, {0, -1}, {1, -1}};
    Eigen::Vector2d extreme[8];
    double best[8];
    for (int k = 0; k < 8; ++k) best[k] = -std::numeric_limits<double>::infinity();
    for (const Eigen::Vector2d& p : points) {
      for (int k = 0; k < 8; ++k) {
        const double v = kDirections[k][0] * p.x() + kDirections[k][1] * p.y();
        if (v > best[k]) {
          best[k] = v;
          extreme[k] = p;
        }
      }
    }
    size_t kept = 0;
    for (const Eigen::Vector2d& p : points) {
      bool inside = true;
      for (int k = 0; k < 8 && inside; ++k) {
        const Eigen::Vector2d& a = extreme[k];
        const Eigen::Vector2d& b = extreme[(k + 1) % 8];
        inside = (a == b) || Turn(a, b, p) > 0;
      }
      if (!inside) points[kept++] = p;
    }
    points.resize(kept);
  }
  std::sort(points.begin(), points.end(), [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y());
  });
  std::vector<Eigen::Vector2d> hull(2 * points.size());
  size_t h = 0;
  for (const Eigen::Vector2d& p : points) {
    while (h >= 2 && Turn(hull[h - 2], hull[h - 1], p) <= 0) --h;
    hull[h++] = p;
  }
  const size_t lower = h + 1;
  for (size_t i = points.size(); i-- > 0;) {
    while (h >= lower && Turn(hull[h - 2], hull[h - 1], points[i]) <= 0) --h;
    hull[h++] = points[i];
  }
  hull.resize(h > 1 ? h - 1 : h);
  return hull;
}

std::vector<Eigen::Vector2d> Streamed(const std::vector<Eigen::Vector2d>& points, size_t slab,
                                      int* passes = nullptr) {
  // In chunks of 1,000, as a frame's passes give them.
  const auto each_chunk = [&](auto fn) {
    for (size_t first = 0; first < points.size(); first += 1000) {
      fn(points.data() + first, std::min<size_t>(1000, points.size() - first));
    }
  };
  StreamedHull hull(points.size(), slab);
  each_chunk([&](const Eigen::Vector2d* chunk, size_t count) { hull.See(chunk, count); });
  int count = 1;
  while (!hull.done()) {
    hull.BeginPass();
    each_chunk([&](const Eigen::Vector2d* chunk, size_t size) { hull.Offer(chunk, size); });
    hull.EndPass();
    ++count;
  }
  if (passes != nullptr) *passes = count;
  return hull.Hull();
}

// Uniform in [-1, 1), the same sequence on every run.
class Uniform {
 public:
  double operator()() {
    state_ = state_ * 6364136223846793005ULL + 1442695040888963407ULL;
    return static_cast<double>(state_ >> 11) * 0x1p-52 - 1.0;
  }

 private:
  uint64_t state_ = 12345;
};

// Sets where hulls go wrong: random, on a circle (every point a vertex candidate), on a line,
// on a lattice, duplicated, with zeros of both signs, and tiny.
std::vector<std::pair<std::string, std::vector<Eigen::Vector2d>>> PointSets() {
  std::vector<std::pair<std::string, std::vector<Eigen::Vector2d>>> sets;
  Uniform uniform;
  std::vector<Eigen::Vector2d> v;
  for (int i = 0; i < 3000; ++i) v.emplace_back(uniform(), 0.5 * uniform());
  sets.emplace_back("uniform", v);
  v.clear();
  for (int i = 0; i < 3000; ++i) {
    const double a = 3.14159265358979 * uniform();
    v.emplace_back(static_cast<float>(std::cos(a)), static_cast<float>(std::sin(a)));
  }
  sets.emplace_back("circle", v);
  v.clear();
  for (int i = 0; i < 2000; ++i) v.emplace_back(uniform(), 0.0);
  sets.emplace_back("segment", v);
  v.clear();
  for (int i = 0; i < 2000; ++i) {
    const double t = uniform();
    v.emplace_back(t, 3 * t);
  }
  sets.emplace_back("slanted_segment", v);
  v.clear();
  for (int i = 0; i < 40; ++i) {
    for (int j = 0; j < 40; ++j) v.emplace_back(i, j);
  }
  sets.emplace_back("lattice", v);
  v.clear();
  for (int i = 0; i < 700; ++i) {
    const Eigen::Vector2d p(uniform(), uniform());
    for (int c = 0; c < 3; ++c) v.push_back(p);
  }
  for (int i = 0; i < 500; ++i) v.emplace_back(1.0, 1.0);
  sets.emplace_back("duplicates", v);
  v.clear();
  for (int i = 0; i < 1000; ++i) {
    const double y = uniform();
    v.emplace_back(i % 2 ? -0.0 : 0.0, y);
    v.emplace_back(uniform(), i % 3 ? -0.0 : 0.0);
  }
  sets.emplace_back("signed_zeros", v);
  v.clear();
  for (int i = 0; i < 5000; ++i) v.emplace_back(7.0, 7.0);
  sets.emplace_back("one_point", v);
  for (size_t n : {1, 2, 3, 15, 16, 17}) {
    v.clear();
    for (size_t i = 0; i < n; ++i) v.emplace_back(uniform(), uniform());
    sets.emplace_back("small" + std::to_string(n), v);
  }
  return sets;
}

bool SameBits(const std::vector<Eigen::Vector2d>& a, const std::vector<Eigen::Vector2d>& b) {
  return a.size() == b.size() &&
         (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(Eigen::Vector2d)) == 0);
}

// Equal as numbers: a slab may keep the other of two equal points, whose zeros may differ in
// sign (see HullChain in dfsd_hull.cc).
void ExpectSamePolygon(const std::vector<Eigen::Vector2d>& got,
                       const std::vector<Eigen::Vector2d>& want, const std::string& what) {
  ASSERT_EQ(got.size(), want.size()) << what;
  for (size_t i = 0; i < got.size(); ++i) EXPECT_EQ(got[i], want[i]) << what << " vertex " << i;
}

TEST(DfsdHullTest, ConvexHullIsCounterClockwiseWithoutInteriorOrCollinearPoints) {
  // A 4 x 4 lattice square: the hull is its four corners, from the lowest-leftmost one.
  std::vector<Eigen::Vector2d> points;
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j) points.emplace_back(i, j);
  }
  const std::vector<Eigen::Vector2d> hull = ConvexHull(points);
  ASSERT_EQ(hull.size(), 4u);
  EXPECT_EQ(hull[0], Eigen::Vector2d(0, 0));
  EXPECT_EQ(hull[1], Eigen::Vector2d(3, 0));
  EXPECT_EQ(hull[2], Eigen::Vector2d(3, 3));
  EXPECT_EQ(hull[3], Eigen::Vector2d(0, 3));
}

TEST(DfsdHullTest, ConvexHullIsTheReferenceBitForBit) {
  for (auto& [name, points] : PointSets()) {
    std::vector<Eigen::Vector2d> copy = points;
    const std::vector<Eigen::Vector2d> got = ConvexHull(copy);
    const std::vector<Eigen::Vector2d> want = ReferenceHull(points);
    EXPECT_TRUE(SameBits(got, want)) << name;
  }
}

TEST(DfsdHullTest, StreamedHullIsConvexHullInMemoryAndInSlabs) {
  for (auto& [name, points] : PointSets()) {
    std::vector<Eigen::Vector2d> copy = points;
    const std::vector<Eigen::Vector2d> want = ConvexHull(copy);
    // In memory: the octagon pass and one more, and the very bits of ConvexHull.
    int passes = 0;
    const std::vector<Eigen::Vector2d> in_memory = Streamed(points, kHullCandidates, &passes);
    EXPECT_TRUE(SameBits(in_memory, want)) << name;
    EXPECT_LE(passes, 2) << name;
    for (size_t slab : {3, 4, 7, 64, 501}) {
      ExpectSamePolygon(Streamed(points, slab), want,
                        name + " in slabs of " + std::to_string(slab));
    }
  }
}

TEST(DfsdHullTest, SlabsTakeAboutCandidatesOverSlabPasses) {
  Uniform uniform;
  std::vector<Eigen::Vector2d> segment;
  for (int i = 0; i < 10000; ++i) segment.emplace_back(uniform(), 0.0);  // all candidates
  int passes = 0;
  Streamed(segment, 1000, &passes);
  // The octagon, the pass that fills up (and counts), then slabs of 1,000 points at most:
  // about 10 up and 9 down (the last slab up is the first down).
  EXPECT_GE(passes, 2 * 10000 / 1000);
  EXPECT_LE(passes, 1 + 2 * 10000 / 666 + 2);
}

TEST(DfsdHullTest, MinAreaRectangleFindsATurnedRectangle) {
  // A 4 x 1 rectangle turned by 30 degrees: its long side's direction and area come back.
  const double angle = 30 * 3.14159265358979323846 / 180;
  const Eigen::Vector2d u(std::cos(angle), std::sin(angle)), v(-u.y(), u.x());
  std::vector<Eigen::Vector2d> points = {2 * u + 0.5 * v, -2 * u + 0.5 * v, -2 * u - 0.5 * v,
                                         2 * u - 0.5 * v};
  Eigen::Vector2d direction;
  double area = 0;
  ASSERT_TRUE(MinAreaRectangle(ConvexHull(points), &direction, &area));
  EXPECT_NEAR(area, 4.0, 1e-12);
  EXPECT_NEAR(std::abs(direction.dot(u)) + std::abs(direction.dot(v)), 1.0, 1e-12);
}

TEST(DfsdHullTest, MinAreaRectangleNeedsThreeHullPoints) {
  Eigen::Vector2d direction;
  double area = 0;
  EXPECT_FALSE(MinAreaRectangle({{0, 0}, {1, 1}}, &direction, &area));
}

}  // namespace
}  // namespace shapeid::dfsd_internal
