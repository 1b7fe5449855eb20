#ifndef SHAPEID_CORE_DESCRIPTORS_DFSD_HULL_H_
#define SHAPEID_CORE_DESCRIPTORS_DFSD_HULL_H_

// Plane geometry of DFSD's box and upright frames (docs/descriptors.md section 5.2): the
// convex hull of a cloud's projection and the smallest rectangle around it. Internal to core;
// exposed for dfsd_frame.cc and tests.

#include <cstddef>
#include <memory>
#include <vector>

#include "Eigen/Core"

namespace shapeid {
namespace dfsd_internal {

// Hull candidates StreamedHull holds at once (16 bytes each: 16 MiB).
inline constexpr size_t kHullCandidates = size_t{1} << 20;

// Vertices per chain up to which StreamedHull::PeakBytes bounds a hull's memory. The hull of a
// cloud of floats seen from any side has far fewer (docs/descriptors.md, "Cost"); only
// points placed on a convex curve to double precision reach it.
inline constexpr size_t kHullVertexAllowance = size_t{1} << 15;

// The convex hull of 2D points, counter-clockwise from the smallest (x, y), without collinear
// points: Andrew's monotone chain over the points sorted by (x, y), after dropping those
// strictly inside the octagon of the extreme points in 8 directions (Akl and Toussaint 1978:
// they cannot be on the hull; on object surfaces they are most points). Reorders and shrinks
// `points`.
std::vector<Eigen::Vector2d> ConvexHull(std::vector<Eigen::Vector2d>& points);

// ConvexHull of a set too large to hold (a large cloud's projection), bit for bit, from
// passes that give every point again, in the same order each time:
//
//   StreamedHull hull(n);
//   for (every chunk of points, in order) hull.See(chunk, size);     // the octagon
//   while (!hull.done()) {
//     hull.BeginPass();
//     for (every chunk of points, in order) hull.Offer(chunk, size);
//     hull.EndPass();
//   }
//   std::vector<Eigen::Vector2d> polygon = hull.Hull();
//
// The second pass collects the points outside the octagon (the candidates) and, where there
// are fewer than `candidates`, sorts them in memory: two passes in all. Where there are more
// (clouds of millions of points; a cylinder seen end-on, a flat cloud seen edge-on), it keeps
// the lowest as the lower chain's first slab and counts all of them in bins of x; each
// further pass sorts the next slab of at most `candidates`, upwards for the lower chain, then
// downwards for the upper chain (whose first slab is the lower chain's last). Memory: 16
// bytes a candidate held, and the hull's own vertices.
class StreamedHull {
 public:
  explicit StreamedHull(size_t n, size_t candidates = kHullCandidates);
  ~StreamedHull();
  StreamedHull(StreamedHull&&) noexcept;
  StreamedHull& operator=(StreamedHull&&) noexcept;

  void See(const Eigen::Vector2d* points, size_t count);
  bool done() const;
  void BeginPass();
  void Offer(const Eigen::Vector2d* points, size_t count);
  void EndPass();
  // Once done(); empties the object.
  std::vector<Eigen::Vector2d> Hull();

  // The most heap one StreamedHull over n points allocates, Hull() included, for hulls of at
  // most kHullVertexAllowance vertices per chain; and what one holds before its first pass.
  static size_t PeakBytes(size_t n, size_t candidates = kHullCandidates);
  static size_t IdleBytes();

 private:
  struct State;
  std::unique_ptr<State> state_;
};

// The direction (unit 2D vector) of the smallest-area rectangle around a convex polygon:
// some side of that rectangle lies along a polygon edge (Freeman and Shapira 1975), so
// trying every edge direction is exact. Returns false for fewer than 3 hull points.
bool MinAreaRectangle(const std::vector<Eigen::Vector2d>& hull, Eigen::Vector2d* direction,
                      double* area);

}  // namespace dfsd_internal
}  // namespace shapeid

#endif  // SHAPEID_CORE_DESCRIPTORS_DFSD_HULL_H_
