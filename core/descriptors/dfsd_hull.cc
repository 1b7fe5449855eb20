// The convex hulls of DFSD's box and upright frames: Andrew's monotone chain after the octagon
// filter, in memory (ConvexHull) or from passes over a cloud too large to project in memory
// (StreamedHull), which must give the very same polygon.
#include "core/descriptors/dfsd_hull.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <utility>
#include <vector>

#include "core/descriptors/cost_model.h"
#include "core/simd.h"
#include "core/target_region.h"

#if defined(__x86_64__)
#include <immintrin.h>
#endif

namespace shapeid {
namespace dfsd_internal {
namespace {

double Turn(const Eigen::Vector2d& o, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
}

// The order of the chain: by x, then y.
struct Ascending {
  bool operator()(const Eigen::Vector2d& a, const Eigen::Vector2d& b) const {
    return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y());
  }
};
struct Descending {
  bool operator()(const Eigen::Vector2d& a, const Eigen::Vector2d& b) const {
    return Ascending()(b, a);
  }
};

// Directions of the octagon's extremes: x, x+y, y, y-x, -x, -x-y, -y, x-y, counter-clockwise
// around the cloud.
constexpr double kOctagonDirections[8][2] = {{1, 0},  {1, 1},   {0, 1},  {-1, 1},
                                             {-1, 0}, {-1, -1}, {0, -1}, {1, -1}};

// The octagon's edges as Octagon::Inside reads them.
struct OctagonEdges {
  double ox[8], oy[8], ex[8], ey[8];
  bool skip[8];
};

// Octagon::See's value of point p along direction k.
inline double OctagonValue(int k, const Eigen::Vector2d& p) {
  return kOctagonDirections[k][0] * p.x() + kOctagonDirections[k][1] * p.y();
}

// Strictly inside every edge: not on the hull. All eight turns, without branches (points
// fall inside and outside at random, which a branch predicts badly).
inline bool InsideEdges(const OctagonEdges& e, const Eigen::Vector2d& p) {
  bool inside = true;
  for (int k = 0; k < 8; ++k) {
    const double turn = e.ex[k] * (p.y() - e.oy[k]) - e.ey[k] * (p.x() - e.ox[k]);
    inside &= e.skip[k] | (turn > 0);
  }
  return inside;
}

#if defined(__x86_64__)
SHAPEID_TARGET_REGION_BEGIN("avx2")
// Octagon::Inside for four points at a time, with its very operations (so the same bits):
// inside[p] = 1 where the point is strictly inside every edge.
void InsideFlagsAvx2(const OctagonEdges& e, const Eigen::Vector2d* points, size_t count,
                     uint8_t* inside) {
  static_assert(sizeof(Eigen::Vector2d) == 2 * sizeof(double));
  const double* xy = reinterpret_cast<const double*>(points);
  size_t p = 0;
  for (; p + 4 <= count; p += 4) {
    const __m256d a = _mm256_loadu_pd(xy + 2 * p);      // x0 y0 x1 y1
    const __m256d b = _mm256_loadu_pd(xy + 2 * p + 4);  // x2 y2 x3 y3
    const __m256d x = _mm256_unpacklo_pd(a, b);         // x0 x2 x1 x3
    const __m256d y = _mm256_unpackhi_pd(a, b);         // y0 y2 y1 y3
    __m256d all = _mm256_castsi256_pd(_mm256_set1_epi64x(-1));
    for (int k = 0; k < 8; ++k) {
      if (e.skip[k]) continue;
      const __m256d turn = _mm256_sub_pd(
          _mm256_mul_pd(_mm256_set1_pd(e.ex[k]), _mm256_sub_pd(y, _mm256_set1_pd(e.oy[k]))),
          _mm256_mul_pd(_mm256_set1_pd(e.ey[k]), _mm256_sub_pd(x, _mm256_set1_pd(e.ox[k]))));
      all = _mm256_and_pd(all, _mm256_cmp_pd(turn, _mm256_setzero_pd(), _CMP_GT_OQ));
    }
    const int bits = _mm256_movemask_pd(all);  // lanes hold points 0, 2, 1, 3
    inside[p] = bits & 1;
    inside[p + 1] = (bits >> 2) & 1;
    inside[p + 2] = (bits >> 1) & 1;
    inside[p + 3] = (bits >> 3) & 1;
  }
  for (; p < count; ++p) inside[p] = InsideEdges(e, points[p]);
}

// Per direction k, the largest value of Octagon::See's expression over `count` points (four
// at a time, the same operations) and the first point that has it: best[k], first[k];
// first[k] = count when there are no points. Two passes: the maxima of all eight directions
// at once, then each one's first point, so no step waits on the one before.
void OctagonExtremesAvx2(const Eigen::Vector2d* points, size_t count, double* best, size_t* first) {
  const double* xy = points[0].data();
  const size_t groups = count / 4;
  const auto values = [xy](size_t g, int k) {
    const __m256d a = _mm256_loadu_pd(xy + 8 * g);      // x0 y0 x1 y1
    const __m256d b = _mm256_loadu_pd(xy + 8 * g + 4);  // x2 y2 x3 y3
    const __m256d x = _mm256_unpacklo_pd(a, b);         // x0 x2 x1 x3
    const __m256d y = _mm256_unpackhi_pd(a, b);         // y0 y2 y1 y3
    return _mm256_add_pd(_mm256_mul_pd(_mm256_set1_pd(kOctagonDirections[k][0]), x),
                         _mm256_mul_pd(_mm256_set1_pd(kOctagonDirections[k][1]), y));
  };
  __m256d top[8];
  for (int k = 0; k < 8; ++k) top[k] = _mm256_set1_pd(-std::numeric_limits<double>::infinity());
  for (size_t g = 0; g < groups; ++g) {
    for (int k = 0; k < 8; ++k) top[k] = _mm256_max_pd(top[k], values(g, k));
  }
  for (int k = 0; k < 8; ++k) {
    alignas(32) double lanes[4];
    _mm256_store_pd(lanes, top[k]);
    best[k] = std::max(std::max(lanes[0], lanes[1]), std::max(lanes[2], lanes[3]));
    first[k] = count;
    if (groups > 0) {
      const __m256d wanted = _mm256_set1_pd(best[k]);
      for (size_t g = 0; g < groups; ++g) {
        const int equal = _mm256_movemask_pd(_mm256_cmp_pd(values(g, k), wanted, _CMP_EQ_OQ));
        if (equal == 0) continue;
        // Lanes hold points 0, 2, 1, 3 of the group: the first point is the lowest of these.
        constexpr size_t kLaneOffset[4] = {0, 2, 1, 3};
        size_t offset = 4;
        for (int l = 0; l < 4; ++l) {
          if (equal >> l & 1) offset = std::min(offset, kLaneOffset[l]);
        }
        first[k] = 4 * g + offset;
        break;
      }
    }
    for (size_t p = 4 * groups; p < count; ++p) {
      const double v = OctagonValue(k, points[p]);
      if (v > best[k]) {
        best[k] = v;
        first[k] = p;
      }
    }
  }
}
SHAPEID_TARGET_REGION_END
#endif  // __x86_64__

// The polygon of the extreme points in 8 directions.
class Octagon {
 public:
  // Points in order: of equal extremes, the first counts.
  void See(const Eigen::Vector2d& p) {
    for (int k = 0; k < 8; ++k) {
      const double v = OctagonValue(k, p);
      if (v > best_[k]) {
        best_[k] = v;
        extreme_[k] = p;
      }
    }
  }

  // See for `count` points in order, several at a time where the CPU can.
  void SeeAll(const Eigen::Vector2d* points, size_t count) {
#if defined(__x86_64__)
    if (ActiveSimdLevel() >= SimdLevel::kAvx2) {
      double best[8];
      size_t first[8];
      OctagonExtremesAvx2(points, count, best, first);
      for (int k = 0; k < 8; ++k) {
        if (first[k] < count && best[k] > best_[k]) {  // an earlier pass's equal one stays
          best_[k] = best[k];
          extreme_[k] = points[first[k]];
        }
      }
      return;
    }
#endif
    for (size_t p = 0; p < count; ++p) See(points[p]);
  }

  // After the last See: each edge's start and direction, so Inside computes each turn
  // with the very operations of Turn(start, end, p).
  void Finish() {
    for (int k = 0; k < 8; ++k) {
      const Eigen::Vector2d& a = extreme_[k];
      const Eigen::Vector2d& b = extreme_[(k + 1) % 8];
      // A repeated extreme gives a zero edge, which says nothing: it never rules p out.
      edges_.skip[k] = a == b;
      edges_.ox[k] = a.x();
      edges_.oy[k] = a.y();
      edges_.ex[k] = b.x() - a.x();
      edges_.ey[k] = b.y() - a.y();
    }
  }

  // The smallest and largest x seen.
  double min_x() const { return extreme_[4].x(); }
  double max_x() const { return extreme_[0].x(); }

  // Strictly inside every edge: not on the hull.
  bool Inside(const Eigen::Vector2d& p) const { return InsideEdges(edges_, p); }

  // inside[p] = Inside(points[p]) for count points, several at a time where the CPU can.
  void InsideFlags(const Eigen::Vector2d* points, size_t count, uint8_t* inside) const {
#if defined(__x86_64__)
    if (ActiveSimdLevel() >= SimdLevel::kAvx2)
      return InsideFlagsAvx2(edges_, points, count, inside);
#endif
    for (size_t p = 0; p < count; ++p) inside[p] = Inside(points[p]);
  }

 private:
  static constexpr double kLow = -std::numeric_limits<double>::infinity();
  Eigen::Vector2d extreme_[8];
  double best_[8] = {kLow, kLow, kLow, kLow, kLow, kLow, kLow, kLow};
  OctagonEdges edges_;
};

// Andrew's monotone chain fed one point at a time: the lower hull from the points in
// ascending order, the upper hull from the same points in descending order, so that each
// half can come from its own stream of sorted slabs. It pops exactly where the textbook
// loops over one sorted array pop: there the upper hull's first edge starts at the lower
// hull's last point, the largest point, which is also the first point the upper chain gets.
//
// Equal points (equal (x, y), possibly zeros of different signs) make the same turns in any
// order, and after the second of a run more copies change nothing but which copy stays; so a
// stream may cut runs to two points, and the order in which a sort leaves equal points does
// not matter (which copy stays differs at most in the sign of a zero coordinate, which no
// later step of a frame can see: it is only compared, added to non-zeros or squared).
class HullChain {
 public:
  void AddLower(const Eigen::Vector2d& p) {
    while (lower_.size() >= 2 && Turn(lower_[lower_.size() - 2], lower_.back(), p) <= 0) {
      lower_.pop_back();
    }
    lower_.push_back(p);
  }

  void AddUpper(const Eigen::Vector2d& p) {
    if (!has_top_) {
      top_ = p;
      has_top_ = true;
    }
    while (!upper_.empty() &&
           Turn(upper_.size() >= 2 ? upper_[upper_.size() - 2] : top_, upper_.back(), p) <= 0) {
      upper_.pop_back();
    }
    upper_.push_back(p);
  }

  // Counter-clockwise from the smallest point; the upper chain's last point (the smallest
  // again) is dropped.
  std::vector<Eigen::Vector2d> Hull() {
    std::vector<Eigen::Vector2d> hull = std::move(lower_);
    hull.insert(hull.end(), upper_.begin(), upper_.end());
    if (hull.size() > 1) hull.pop_back();
    lower_.clear();
    upper_.clear();
    return hull;
  }

 private:
  std::vector<Eigen::Vector2d> lower_, upper_;
  Eigen::Vector2d top_;
  bool has_top_ = false;
};

// Chains points sorted by Ascending: all of them into the lower hull, then backwards into
// the upper hull.
std::vector<Eigen::Vector2d> ChainSorted(const std::vector<Eigen::Vector2d>& sorted) {
  HullChain chain;
  for (const Eigen::Vector2d& p : sorted) chain.AddLower(p);
  for (size_t i = sorted.size(); i-- > 0;) chain.AddUpper(sorted[i]);
  return chain.Hull();
}

// One pass's slab of the hull candidates in `Order`: those after the previous slab (the
// cursor) that the caller lets through, up to a bound that keeps at most `capacity` of them
// (set, and only lowered, when the buffer fills). Runs of equal points are cut to two (see
// HullChain).
template <typename Order>
class SlabSelector {
 public:
  explicit SlabSelector(size_t capacity) : capacity_(capacity) {}

  // The buffer never holds more than capacity() points: reserved once, no growth.
  void BeginPass(size_t n) {
    buffer_.reserve(std::min(n, capacity_));
    buffer_.clear();
    has_bound_ = false;
  }

  // Whether p belongs to this pass's slab as the slab stands.
  bool Wants(const Eigen::Vector2d& p) const {
    return (!has_cursor_ || before_(cursor_, p)) && (!has_bound_ || !before_(bound_, p));
  }

  // p must be wanted.
  void Offer(const Eigen::Vector2d& p) {
    buffer_.push_back(p);
    if (buffer_.size() == capacity_) Shrink();
  }

  // The slab, sorted; the next pass continues after it.
  const std::vector<Eigen::Vector2d>& EndPass() {
    std::sort(buffer_.begin(), buffer_.end(), before_);
    size_t kept = 0;
    for (const Eigen::Vector2d& p : buffer_) {
      if (kept >= 2 && !before_(buffer_[kept - 2], p)) continue;  // a third equal point
      buffer_[kept++] = p;
    }
    buffer_.resize(kept);
    if (!buffer_.empty()) {
      cursor_ = buffer_.back();
      has_cursor_ = true;
    }
    return buffer_;
  }

  // The next slab starts after p (in `Order`), as if p ended the previous one.
  void ContinueBelow(const Eigen::Vector2d& p) {
    cursor_ = p;
    has_cursor_ = true;
  }

  // Whether this pass's slab stopped at a bound (so more points of its range remain).
  bool bounded() const { return has_bound_; }
  const Eigen::Vector2d& cursor() const { return cursor_; }
  size_t capacity() const { return capacity_; }

  // The points as offered, in order: every wanted point while !bounded().
  std::vector<Eigen::Vector2d>& offered() { return buffer_; }

  void Release() { std::vector<Eigen::Vector2d>().swap(buffer_); }

 private:
  // Keeps the first two thirds of the points (room for more before the next shrink) and, if
  // a later one equals the last of them, that one too (a run of equal points at the bound
  // keeps two); the bound is the last point kept.
  void Shrink() {
    const size_t keep = std::max<size_t>(capacity_ * 2 / 3, 1);
    const auto nth = buffer_.begin() + static_cast<std::ptrdiff_t>(keep - 1);
    std::nth_element(buffer_.begin(), nth, buffer_.end(), before_);
    bound_ = *nth;
    has_bound_ = true;
    auto end = nth + 1;
    const auto equal = std::find_if(end, buffer_.end(),
                                    [&](const Eigen::Vector2d& p) { return !before_(bound_, p); });
    if (equal != buffer_.end()) std::iter_swap(end++, equal);
    buffer_.erase(end, buffer_.end());
  }

  Order before_;
  size_t capacity_;
  std::vector<Eigen::Vector2d> buffer_;
  Eigen::Vector2d cursor_, bound_;
  bool has_cursor_ = false, has_bound_ = false;
};

// Candidates counted by x in kBins equal bins between the smallest and largest x, so that
// each slab pass can take a run of bins that fits and reject the other points by their bin.
// The bin of x never decreases as x grows, so a run of bins is a run of the sorted order.
class XHistogram {
 public:
  static constexpr size_t kBins = 4096;

  XHistogram(double lo, double hi)
      : lo_(lo), scale_(hi > lo ? static_cast<double>(kBins) / (hi - lo) : 0.0), counts_(kBins) {}

  size_t Bin(double x) const {
    const double t = (x - lo_) * scale_;
    return t >= static_cast<double>(kBins - 1) ? kBins - 1 : t > 0 ? static_cast<size_t>(t) : 0;
  }
  void Count(double x) { ++counts_[Bin(x)]; }
  size_t count(size_t bin) const { return counts_[bin]; }

 private:
  double lo_, scale_;
  std::vector<size_t> counts_;
};

}  // namespace

std::vector<Eigen::Vector2d> ConvexHull(std::vector<Eigen::Vector2d>& points) {
  if (points.size() >= 16) {
    Octagon octagon;
    octagon.SeeAll(points.data(), points.size());
    octagon.Finish();
    size_t kept = 0;
    for (const Eigen::Vector2d& p : points) {
      if (!octagon.Inside(p)) points[kept++] = p;  // keeps the survivors' order
    }
    points.resize(kept);
  }
  std::sort(points.begin(), points.end(), Ascending());
  return ChainSorted(points);
}

struct StreamedHull::State {
  State(size_t points, size_t capacity) : n(points), lower(capacity), upper(capacity) {}

  enum class Mode { kSmall, kOctagon, kInMemory, kLowerSlabs, kUpperSlabs, kDone };

  // The run of bins a chain's next slab draws from: [from, to] going up for the lower chain,
  // down for the upper one.
  struct Run {
    size_t from, to;
    bool last = false;  // the run reaches the last bin
  };

  // The run from `run.from` that the histogram says fits a slab without a bound (at least one
  // bin), going up or down.
  void Plan(Run& run, int step, size_t capacity) const {
    size_t end = run.from, total = histogram->count(end);
    while (true) {
      const bool edge = step > 0 ? end + 1 == XHistogram::kBins : end == 0;
      if (edge) break;
      const size_t next = step > 0 ? end + 1 : end - 1;
      if (total + histogram->count(next) >= capacity) break;
      total += histogram->count(next);
      end = next;
    }
    run.to = end;
    run.last = step > 0 ? end + 1 == XHistogram::kBins : end == 0;
  }

  // After a pass: whether the chain has all its points; if not, its next run.
  template <typename Selector>
  bool Advance(Run& run, const Selector& selector, int step) {
    if (selector.bounded()) {
      run.from = histogram->Bin(selector.cursor().x());  // the bound's bin has more points
      return false;
    }
    if (run.last) return true;
    run.from = step > 0 ? run.to + 1 : run.to - 1;
    return false;
  }

  // The in-memory pass needs no histogram while every candidate fits: it starts when the
  // buffer fills, from the candidates held (all of them so far), and counts every later one.
  void StartHistogram() {
    histogram = std::make_unique<XHistogram>(octagon.min_x(), octagon.max_x());
    for (const Eigen::Vector2d& p : lower.offered()) histogram->Count(p.x());
  }

  size_t n;
  Mode mode = Mode::kOctagon;
  Octagon octagon;
  std::vector<Eigen::Vector2d> small;  // kSmall: every point
  std::unique_ptr<XHistogram> histogram;
  // One buffer at a time: the lower chain's slabs, then the upper chain's.
  SlabSelector<Ascending> lower;
  SlabSelector<Descending> upper;
  Run lower_run{0, 0}, upper_run{XHistogram::kBins - 1, 0};
  HullChain chain;
  std::vector<Eigen::Vector2d> hull;
};

StreamedHull::StreamedHull(size_t n, size_t candidates)
    : state_(std::make_unique<State>(n, std::max<size_t>(candidates, 3))) {
  // ConvexHull keeps every point of a small set (no octagon below 16 points).
  if (n < 16) state_->mode = State::Mode::kSmall;
}

StreamedHull::~StreamedHull() = default;
StreamedHull::StreamedHull(StreamedHull&&) noexcept = default;
StreamedHull& StreamedHull::operator=(StreamedHull&&) noexcept = default;

void StreamedHull::See(const Eigen::Vector2d* points, size_t count) {
  State& s = *state_;
  if (s.mode == State::Mode::kSmall) {
    s.small.insert(s.small.end(), points, points + count);
  } else {
    s.octagon.SeeAll(points, count);
  }
}

bool StreamedHull::done() const {
  return state_->mode == State::Mode::kSmall || state_->mode == State::Mode::kDone;
}

void StreamedHull::BeginPass() {
  State& s = *state_;
  if (s.mode == State::Mode::kOctagon) {
    // The lower chain's selector takes every candidate, in point order, until it fills;
    // then it keeps the lowest, the first slab, and the histogram plans the rest.
    s.octagon.Finish();
    s.mode = State::Mode::kInMemory;
    s.lower.BeginPass(s.n);
  } else if (s.mode == State::Mode::kLowerSlabs) {
    // A run the histogram says fits never reaches the bound: no selection work.
    s.Plan(s.lower_run, +1, s.lower.capacity());
    s.lower.BeginPass(s.n);
  } else if (s.mode == State::Mode::kUpperSlabs) {
    s.Plan(s.upper_run, -1, s.upper.capacity());
    s.upper.BeginPass(s.n);
  }
}

void StreamedHull::Offer(const Eigen::Vector2d* points, size_t count) {
  State& s = *state_;
  if (s.mode == State::Mode::kInMemory) {
    // The octagon's verdicts a block at a time, on the stack.
    constexpr size_t kBlock = 256;
    uint8_t inside[kBlock];
    for (size_t first = 0; first < count; first += kBlock) {
      const size_t block = std::min(kBlock, count - first);
      s.octagon.InsideFlags(points + first, block, inside);
      for (size_t i = 0; i < block; ++i) {
        if (inside[i]) continue;
        const Eigen::Vector2d& p = points[first + i];
        if (!s.histogram) {
          if (s.lower.offered().size() + 1 < s.lower.capacity()) {
            s.lower.Offer(p);  // wanted: no slab bound yet
            continue;
          }
          s.StartHistogram();  // p fills the buffer
        }
        s.histogram->Count(p.x());
        if (s.lower.Wants(p)) s.lower.Offer(p);
      }
    }
  } else if (s.mode == State::Mode::kLowerSlabs) {
    const State::Run& run = s.lower_run;
    for (size_t i = 0; i < count; ++i) {
      const Eigen::Vector2d& p = points[i];
      // The cheap tests first: most points are outside the run of bins.
      const size_t bin = s.histogram->Bin(p.x());
      if (bin < run.from || bin > run.to || !s.lower.Wants(p) || s.octagon.Inside(p)) continue;
      s.lower.Offer(p);
    }
  } else if (s.mode == State::Mode::kUpperSlabs) {
    const State::Run& run = s.upper_run;
    for (size_t i = 0; i < count; ++i) {
      const Eigen::Vector2d& p = points[i];
      const size_t bin = s.histogram->Bin(p.x());
      if (bin > run.from || bin < run.to || !s.upper.Wants(p) || s.octagon.Inside(p)) continue;
      s.upper.Offer(p);
    }
  }
}

void StreamedHull::EndPass() {
  State& s = *state_;
  if (s.mode == State::Mode::kInMemory && !s.lower.bounded()) {
    // Every candidate, in point order as ConvexHull keeps them.
    std::vector<Eigen::Vector2d>& candidates = s.lower.offered();
    std::sort(candidates.begin(), candidates.end(), Ascending());
    s.hull = ChainSorted(candidates);
    s.lower.Release();
    s.histogram.reset();
    s.mode = State::Mode::kDone;
  } else if (s.mode == State::Mode::kInMemory || s.mode == State::Mode::kLowerSlabs) {
    const std::vector<Eigen::Vector2d>& slab = s.lower.EndPass();
    for (const Eigen::Vector2d& p : slab) s.chain.AddLower(p);
    s.mode = State::Mode::kLowerSlabs;
    if (s.Advance(s.lower_run, s.lower, +1)) {
      // The last slab holds the highest candidates: read backwards, it is the upper chain's
      // first, and the upper chain's passes continue below it.
      for (size_t i = slab.size(); i-- > 0;) s.chain.AddUpper(slab[i]);
      if (!slab.empty()) {
        s.upper.ContinueBelow(slab.front());
        s.upper_run.from = s.histogram->Bin(slab.front().x());
      }
      s.lower.Release();
      s.mode = State::Mode::kUpperSlabs;
    }
  } else if (s.mode == State::Mode::kUpperSlabs) {
    for (const Eigen::Vector2d& p : s.upper.EndPass()) s.chain.AddUpper(p);
    if (s.Advance(s.upper_run, s.upper, -1)) {
      s.upper.Release();
      s.histogram.reset();
      s.hull = s.chain.Hull();
      s.mode = State::Mode::kDone;
    }
  }
}

std::vector<Eigen::Vector2d> StreamedHull::Hull() {
  State& s = *state_;
  if (s.mode == State::Mode::kSmall) return ConvexHull(s.small);
  return std::move(s.hull);
}

size_t StreamedHull::PeakBytes(size_t n, size_t candidates) {
  constexpr size_t kPoint = sizeof(Eigen::Vector2d);
  const size_t vertices = std::min(n, kHullVertexAllowance);
  // Both chains' stacks, grown by push_back, and the polygon Hull() joins them into.
  const size_t chains = 8 * vertices * kPoint;
  if (n < 16) return cost_model::GrownBytes(n, kPoint) + chains;
  const size_t buffer = std::min(n, std::max<size_t>(candidates, 3)) * kPoint;
  return XHistogram::kBins * sizeof(size_t) + buffer + chains + sizeof(State);
}

size_t StreamedHull::IdleBytes() { return sizeof(State); }

bool MinAreaRectangle(const std::vector<Eigen::Vector2d>& hull, Eigen::Vector2d* direction,
                      double* area) {
  if (hull.size() < 3) return false;
  *area = std::numeric_limits<double>::infinity();
  for (size_t i = 0; i < hull.size(); ++i) {
    Eigen::Vector2d e = hull[(i + 1) % hull.size()] - hull[i];
    const double length = e.norm();
    if (length == 0) continue;
    e /= length;
    double lo_u = std::numeric_limits<double>::infinity(), hi_u = -lo_u, lo_v = lo_u, hi_v = -lo_u;
    for (const Eigen::Vector2d& q : hull) {
      const double u = q.dot(e), v = e.x() * q.y() - e.y() * q.x();
      lo_u = std::min(lo_u, u);
      hi_u = std::max(hi_u, u);
      lo_v = std::min(lo_v, v);
      hi_v = std::max(hi_v, v);
    }
    const double a = (hi_u - lo_u) * (hi_v - lo_v);
    if (a < *area) {
      *area = a;
      *direction = e;
    }
  }
  return std::isfinite(*area);
}

}  // namespace dfsd_internal
}  // namespace shapeid
