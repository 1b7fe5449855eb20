// DFSD (docs/descriptors.md section 5).
//
// Cost: the distance grid is exact (each cell's nearest point), with the separable tables of
// dfsd_kernels.h: a point costs a cell two additions and a minimum, in SIMD, and a cell reads
// only the blocks of nearby points that can hold its nearest (the pruned kernel). Figures:
// docs/performance.md, "DFSD's pruned kernel".
// The cosine transform runs one axis at a time and stops at the kept frequencies, so it
// costs O(G^3 * order), nothing next to the grid.
#include "core/descriptors/dfsd.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "absl/strings/str_cat.h"
#include "core/descriptor.h"
#include "core/descriptor_spec.h"
#include "core/descriptors/cost_model.h"
#include "core/descriptors/dfsd_frame.h"
#include "core/descriptors/dfsd_kernels.h"
#include "core/descriptors/point_smoothing.h"
#include "core/enum_names.h"
#include "core/simd.h"
#include "core/status_macros.h"

namespace shapeid {
namespace dfsd_internal {
namespace {

constexpr double kPi = 3.14159265358979323846;
// A zero extent (a flat or straight cloud) would make ln(extent) infinite; such an axis
// counts as this fraction of the largest extent instead.
constexpr double kMinRelativeExtent = 1e-6;
// Largest share of the cloud smoothing averages around each point: beyond it, points would
// be drawn to the middle of the object rather than to its surface.
constexpr double kMaxSmooth = 0.25;

// The distance kernel takes at most this many points per pass (a multiple of kPointLanes).
// See ComputeFramed.
constexpr size_t kPointsPerChunk = size_t{1} << 16;

bool HasPoseVariants(DfsdOptions::Frame frame) {
  return frame == DfsdOptions::Frame::kBox || frame == DfsdOptions::Frame::kUpright;
}

constexpr EnumNames<DfsdOptions::Frame, 4> kFrameNames = {{
    {DfsdOptions::Frame::kAxes, "axes"},
    {DfsdOptions::Frame::kPca, "pca"},
    {DfsdOptions::Frame::kBox, "box"},
    {DfsdOptions::Frame::kUpright, "upright"},
}};

constexpr EnumNames<DfsdOptions::Fields, 3> kFieldsNames = {{
    {DfsdOptions::Fields::kBoth, "both"},
    {DfsdOptions::Fields::kIsotropic, "isotropic"},
    {DfsdOptions::Fields::kAnisotropic, "anisotropic"},
}};

constexpr EnumNames<DfsdOptions::Up, 6> kUpNames = {{
    {DfsdOptions::Up::kPlusZ, "z"},
    {DfsdOptions::Up::kPlusY, "y"},
    {DfsdOptions::Up::kPlusX, "x"},
    {DfsdOptions::Up::kMinusZ, "-z"},
    {DfsdOptions::Up::kMinusY, "-y"},
    {DfsdOptions::Up::kMinusX, "-x"},
}};

absl::string_view FrameName(DfsdOptions::Frame frame) { return NameOf(kFrameNames, frame); }
absl::string_view FieldsName(DfsdOptions::Fields fields) { return NameOf(kFieldsNames, fields); }
absl::string_view UpName(DfsdOptions::Up up) { return NameOf(kUpNames, up); }

int NumFields(DfsdOptions::Fields fields) { return fields == DfsdOptions::Fields::kBoth ? 2 : 1; }

// out[c] = sqrt(sqrt(double(squared[c]))) * scale. With SSE2, two at a time: the same
// correctly rounded square roots, without the errno check that keeps std::sqrt scalar.
void FourthRoots(const float* squared, size_t n, double scale, double* out) {
  size_t c = 0;
#if defined(__SSE2__)
  const __m128d factor = _mm_set1_pd(scale);
  for (; c + 2 <= n; c += 2) {
    const __m128d v = _mm_cvtps_pd(
        _mm_castsi128_ps(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(squared + c))));
    _mm_storeu_pd(out + c, _mm_mul_pd(_mm_sqrt_pd(_mm_sqrt_pd(v)), factor));
  }
#endif
  for (; c < n; ++c) out[c] = std::sqrt(std::sqrt(static_cast<double>(squared[c]))) * scale;
}

// Points per pass of the distance kernel for a cloud of n (see ComputeFramed).
size_t KernelChunk(size_t n) {
  const size_t chunks = std::max<size_t>(1, (n + kPointsPerChunk - 1) / kPointsPerChunk);
  return ((n + chunks - 1) / chunks + kPointLanes - 1) / kPointLanes * kPointLanes;
}

class DfsdDescriptor : public Descriptor {
 public:
  DfsdDescriptor(DescriptorSpec canonical, const DfsdOptions& options)
      : Descriptor(std::move(canonical), DfsdDimension(options)),
        options_(options),
        kept_(KeptFrequencies(options.grid, options.order)) {
    if (HasPoseVariants(options.frame)) {
      poses_ = MakePoses(options);
    }
    const int g = options.grid;
    cosines_.resize(static_cast<size_t>(g) * g);
    for (int a = 0; a < g; ++a) {
      const double alpha = std::sqrt((a == 0 ? 1.0 : 2.0) / g);
      for (int i = 0; i < g; ++i) {
        cosines_[static_cast<size_t>(a) * g + i] =
            alpha * std::cos(kPi * (2 * i + 1) * a / (2.0 * g));
      }
    }
    centers_.resize(static_cast<size_t>(g));
    for (int i = 0; i < g; ++i) {
      centers_[static_cast<size_t>(i)] = static_cast<float>((2.0 * i + 1.0) / g - 1.0);
    }
    for (int i = 1; i < g; ++i) {
      cell_spacing_ =
          std::max(cell_spacing_, static_cast<double>(centers_[static_cast<size_t>(i)]) -
                                      centers_[static_cast<size_t>(i) - 1]);
    }
  }

 public:
  std::array<float, 3> up_direction() const override {
    constexpr std::array<std::array<float, 3>, 6> kDirections = {
        {{0, 0, 1}, {0, 1, 0}, {1, 0, 0}, {0, 0, -1}, {0, -1, 0}, {-1, 0, 0}}};
    return kDirections[static_cast<int>(options_.up)];  // in DfsdOptions::Up's order
  }

  DescribeCost EstimateCost(size_t num_points) const override {
    // CPU: the distance kernel is per point and cell of each field (the pruned kernel reads
    // a share of the points that depends on the shape: priced as a typical object's); the
    // frames are per point (box: the most passes and sorts), and more so once their hulls
    // take slabs: ordinary shapes have about a fifth of their points outside the octagon,
    // past 2^20 of them (some 5 million points) each slab is another pass. Constants:
    // docs/performance.md, "Describe cost" and "DFSD's pruned kernel".
    constexpr double kNsBase = 10000, kNsPerPoint = 5, kNsPerPointCell = 0.04, kNsPerPointRow = 0.3,
                     kSlabbedPoints = 5e6;
    // Smoothing: finding each kept point's k nearest (the candidates grow with k), and one
    // pass to reduce a large cloud.
    constexpr double kNsPerSmoothedPoint = 1000, kNsPerNeighbor = 50, kNsPerReducedPoint = 5;
    // axes, pca, box, upright; the second for each kSlabbedPoints beyond the first.
    constexpr double kNsPerFramedPoint[] = {0, 25, 220, 75};
    constexpr double kNsPerSlabbedPoint[] = {0, 0, 225, 165};
    const int g = options_.grid;
    const size_t cells = static_cast<size_t>(g) * g * g;
    const int fields = NumFields(options_.fields);
    const size_t n = num_points;
    // Smoothing describes at most kSmoothingReferencePoints points. (Memory below is bounded
    // for all n: a cloud whose smoothed points collapse is described as given; its CPU, rare
    // past 4,096 points, a cloud a few float steps wide, is not in this estimate.)
    const bool smooth = options_.smooth > 0;
    const size_t described = smooth ? std::min(n, kSmoothingReferencePoints) : n;
    const size_t described_chunk = KernelChunk(described);
    const size_t padded = (described + described_chunk - 1) / std::max<size_t>(described_chunk, 1) *
                          described_chunk;  // kernel's work
    const int frame = static_cast<int>(options_.frame);
    const double frame_ns = kNsPerFramedPoint[frame] +
                            kNsPerSlabbedPoint[frame] *
                                std::max(0.0, static_cast<double>(described) / kSlabbedPoints - 1);
    const double neighbors = std::max(static_cast<double>(kMinSmoothingNeighbors),
                                      options_.smooth * static_cast<double>(described));
    const double smooth_ns = smooth ? (kNsPerSmoothedPoint + kNsPerNeighbor * neighbors) *
                                              static_cast<double>(described) +
                                          kNsPerReducedPoint * static_cast<double>(n)
                                    : 0;
    DescribeCost cost;
    cost.cpu = cost_model::Nanoseconds(
        kNsBase + smooth_ns + (kNsPerPoint + frame_ns) * static_cast<double>(described) +
        fields * (kNsPerPointCell * static_cast<double>(cells) * static_cast<double>(padded) +
                  kNsPerPointRow * 3 * g * static_cast<double>(described)));
    const size_t chunk = KernelChunk(n);
    // The frame, the kernel's buffers and the pose variants come one after another.
    const size_t t = static_cast<size_t>(std::min(options_.order, g));
    const size_t kernel = 4 * static_cast<size_t>(g) * chunk * sizeof(float)  // tables, z by block
                          + 3 * chunk * sizeof(double)                        // coordinates
                          + 2 * chunk * sizeof(float)     // normalized, the kernel's x-y sums
                          + 2 * chunk * sizeof(uint32_t)  // spatial order and its keys
                          + (size_t{1} << 15) * sizeof(uint32_t)  // the order's buckets
                          // block bounds (three axes) and the kernel's x-y bounds
                          + 4 * static_cast<size_t>(g) * BlockStride(chunk) * sizeof(float) +
                          cells * (2 * sizeof(float) + sizeof(double))  // squared, reach, field
                          + (static_cast<size_t>(g) * g * t + g * t * t) * sizeof(double);
    const size_t variants = HasPoseVariants(options_.frame)
                                ? cost_model::GrownBytes(poses_.size() * dimension(), sizeof(float))
                                : 0;
    // The smoothed cloud lives through the frame and the kernel (its scratch is counted too:
    // a bound, not a sum of what is alive at once).
    const size_t smoothing = smooth ? SmoothPointsBytes(n) : 0;
    cost.working_bytes = dimension() * sizeof(float) + smoothing +
                         std::max({FrameBytes(n, options_.frame), kernel, variants}) +
                         cost_model::kHeapSlack;
    return cost;
  }

 protected:
  absl::Status ComputeValidated(const PointCloud& cloud, const CloudStats& stats,
                                const CloudLimits& limits, absl::Span<float> out) const override {
    return ComputeValidatedWithPoseVariants(cloud, stats, limits, out, nullptr);
  }

  absl::Status ComputeValidatedWithPoseVariants(const PointCloud& cloud, const CloudStats& stats,
                                                const CloudLimits& /*limits*/,
                                                absl::Span<float> out,
                                                std::vector<float>* variants) const override {
    if (options_.smooth > 0) {
      const PointCloud smoothed = SmoothPoints(cloud, options_.smooth);
      const absl::StatusOr<CloudStats> smoothed_stats = ValidateCloud(smoothed);
      // A cloud whose smoothed points all coincide (always so for 8 points or fewer) is
      // described as given.
      if (smoothed_stats.ok()) {
        ComputeFromStats(smoothed, *smoothed_stats, out, variants);
        return absl::OkStatus();
      }
    }
    ComputeFromStats(cloud, stats, out, variants);
    return absl::OkStatus();
  }

 private:
  // The descriptor of a validated cloud, and its pose variants unless `variants` is null.
  void ComputeFromStats(const PointCloud& cloud, const CloudStats& stats, absl::Span<float> out,
                        std::vector<float>* variants) const {
    const CloudFrame frame = CloudFrame::Find(cloud, stats, options_);
    ComputeFramed(cloud, frame, out);
    if (variants != nullptr && HasPoseVariants(options_.frame)) {
      AppendPoseVariants(frame, out, variants);
    }
  }

  // A pose of the box frame other than the canonical one (see PoseMap).
  struct Pose {
    std::array<int, 3> axis_of;
    int flips;
    std::vector<int> source;
    std::vector<float> sign;
  };

  static std::vector<Pose> MakePoses(const DfsdOptions& options) {
    std::array<int, 3> axis_of = {0, 1, 2};
    std::vector<Pose> poses;
    do {
      for (int flips = 0; flips < 8; ++flips) {
        if (flips == 0 && axis_of == std::array<int, 3>{0, 1, 2}) continue;  // canonical
        Pose pose{axis_of, flips, {}, {}};
        PoseMap(options, axis_of, flips, &pose.source, &pose.sign);
        poses.push_back(std::move(pose));
      }
    } while (std::next_permutation(axis_of.begin(), axis_of.end()));
    return poses;
  }

  // Appends the descriptor in every pose the frame could as well have chosen: axes whose
  // extents are within kAxisOrderTolerance of each other may come in either order, and an
  // axis whose skewness is below kSkewnessTolerance may point either way.
  void AppendPoseVariants(const CloudFrame& frame, absl::Span<const float> canonical,
                          std::vector<float>* variants) const {
    const Eigen::Vector3d extent = 2.0 * frame.half_extent();
    // The upright frame never moves its vertical: only x and y are ordered.
    const bool upright = options_.frame == DfsdOptions::Frame::kUpright;
    const int ordered = upright ? 2 : 3;
    for (const Pose& pose : poses_) {
      bool plausible = !upright || pose.axis_of[2] == 2;
      for (int i = 0; i < 3 && plausible; ++i) {
        for (int j = i + 1; j < ordered && plausible; ++j) {
          // Pose axis i comes before pose axis j: fine unless its extent is clearly smaller.
          plausible =
              extent[pose.axis_of[i]] * (1 + kAxisOrderTolerance) >= extent[pose.axis_of[j]];
        }
        if ((pose.flips >> i & 1) && frame.skewness()[pose.axis_of[i]] >= kSkewnessTolerance) {
          plausible = false;
        }
      }
      if (!plausible) continue;
      for (size_t q = 0; q < canonical.size(); ++q) {
        variants->push_back(pose.sign[q] * canonical[static_cast<size_t>(pose.source[q])]);
      }
    }
  }

  void ComputeFramed(const PointCloud& cloud, const CloudFrame& frame,
                     absl::Span<float> out) const {
    const int g = options_.grid;
    const size_t cells = static_cast<size_t>(g) * g * g;
    const Eigen::Vector3d& half_extent = frame.half_extent();
    const double largest_half = half_extent.maxCoeff();  // > 0: ValidateCloud

    const size_t n = cloud.size();
    // A large cloud goes through the kernel in chunks whose three G-row tables (3 G x chunk
    // floats) stay in the last-level cache and bound the memory, all of about the same size:
    // the kernel runs over a whole stride, so a short last chunk would cost a full one
    // (docs/performance.md, "DFSD").
    const size_t chunk = KernelChunk(n);
    const size_t stride = chunk;
    const size_t block_stride = BlockStride(chunk);
    const AlignedFloats tables = MakeAlignedFloats(3 * static_cast<size_t>(g) * stride);
    std::vector<float> bounds(3 * static_cast<size_t>(g) * block_stride);
    std::vector<double> coords(3 * chunk);
    double* const coord[3] = {coords.data(), coords.data() + chunk, coords.data() + 2 * chunk};
    std::vector<uint32_t> order;
    std::vector<float> normalized(chunk);
    std::vector<float> squared(cells);
    std::vector<double> field(cells);
    size_t written = 0;
    const SimdLevel level = ActiveSimdLevel();
    for (int f = 0; f < NumFields(options_.fields); ++f) {
      const bool isotropic = options_.fields == DfsdOptions::Fields::kIsotropic ||
                             (options_.fields == DfsdOptions::Fields::kBoth && f == 0);
      for (size_t first = 0; first < n; first += chunk) {
        const size_t count = std::min(chunk, n - first);
        // One chunk (most clouds) keeps its coordinates and order for the second field.
        if (f == 0 || chunk < n) {
          frame.Coordinates(cloud, first, count, coord);
          SpatialOrder(coord, count, half_extent.data(), &order);
        }
        for (int a = 0; a < 3; ++a) {
          // An axis of zero extent keeps the common scale: its points all sit at 0.
          const double half = half_extent[a];
          const double scale = 1.0 / (isotropic || half == 0 ? largest_half : half);
          for (size_t p = 0; p < count; ++p) {
            normalized[p] = static_cast<float>(coord[a][order[p]] * scale);
          }
          // A last, shorter chunk leaves the previous chunk's values past `count` (this
          // field's: a field with several chunks fills every earlier one): points already
          // counted, so they cannot change a minimum.
          FillAxisTables(normalized.data(), count, centers_.data(), g, stride, block_stride,
                         /*pad=*/first == 0, tables.get() + static_cast<size_t>(a) * g * stride,
                         bounds.data() + static_cast<size_t>(a) * g * block_stride);
        }
        FieldInput input =
            LaidOutInput(tables.get(), g, stride, bounds.data(), block_stride, cell_spacing_);
        input.accumulate = first > 0;
        NearestSquaredDistances(input, squared.data(), level);
      }
      // sqrt of the distance: tames the far cells, whose large distances would otherwise
      // outweigh the detail near the surface. Divided by G^(3/2), so the field's Euclidean
      // norm is a root mean square over cells and does not grow with the grid.
      const double norm = 1.0 / std::pow(static_cast<double>(g), 1.5);
      FourthRoots(squared.data(), cells, norm, field.data());
      Transform(field, out.subspan(written, kept_.size()));
      written += kept_.size();
    }
    if (options_.size_weight > 0) {
      WriteSizeBlock(2.0 * half_extent, options_.size_weight, &out[written]);
    }
  }

  // The kept coefficients of the orthonormal 3D DCT-II of `field` (index (i * G + j) * G + k,
  // i along x), one axis at a time: z for every frequency that can be kept, then y, then x.
  void Transform(const std::vector<double>& field, absl::Span<float> out) const {
    const int g = options_.grid;
    const int t = std::min(options_.order, g);  // frequencies per axis that can be kept
    const auto cosine = [&](int freq, int i) {
      return cosines_[static_cast<size_t>(freq) * g + i];
    };
    std::vector<double> along_z(static_cast<size_t>(g) * g * t, 0.0);  // [i][j][c]
    for (int i = 0; i < g; ++i) {
      for (int j = 0; j < g; ++j) {
        const double* row = field.data() + (static_cast<size_t>(i) * g + j) * g;
        double* dst = along_z.data() + (static_cast<size_t>(i) * g + j) * t;
        for (int c = 0; c < t; ++c) {
          double sum = 0;
          for (int k = 0; k < g; ++k) sum += row[k] * cosine(c, k);
          dst[c] = sum;
        }
      }
    }
    std::vector<double> along_y(static_cast<size_t>(g) * t * t, 0.0);  // [i][b][c]
    for (int i = 0; i < g; ++i) {
      for (int b = 0; b < t; ++b) {
        for (int c = 0; b + c < options_.order && c < t; ++c) {
          double sum = 0;
          for (int j = 0; j < g; ++j) {
            sum += along_z[(static_cast<size_t>(i) * g + j) * t + c] * cosine(b, j);
          }
          along_y[(static_cast<size_t>(i) * t + b) * t + c] = sum;
        }
      }
    }
    for (size_t q = 0; q < kept_.size(); ++q) {
      const Frequency& k = kept_[q];
      double sum = 0;
      for (int i = 0; i < g; ++i) {
        sum += along_y[(static_cast<size_t>(i) * t + k.b) * t + k.c] * cosine(k.a, i);
      }
      out[q] = static_cast<float>(sum);
    }
  }

  DfsdOptions options_;
  std::vector<Frequency> kept_;
  std::vector<Pose> poses_;      // frames with pose variants (box, upright) only
  std::vector<double> cosines_;  // [frequency][cell index]
  std::vector<float> centers_;   // cell center coordinates in [-1, 1]
  double cell_spacing_ = 0;      // the largest gap between neighboring centers
};

absl::StatusOr<std::unique_ptr<Descriptor>> CreateFromSpec(const DescriptorSpec& filled) {
  const SpecParams params(filled);
  DfsdOptions options;
  SHAPEID_ASSIGN_OR_RETURN(const int64_t grid, params.Int("grid", kMinGrid, kMaxGrid));
  options.grid = static_cast<int>(grid);
  SHAPEID_ASSIGN_OR_RETURN(const int64_t order, params.Int("order", 1, 3 * (grid - 1) + 1));
  options.order = static_cast<int>(order);
  SHAPEID_ASSIGN_OR_RETURN(options.frame, params.Choice("frame", kFrameNames));
  SHAPEID_ASSIGN_OR_RETURN(options.fields, params.Choice("fields", kFieldsNames));
  SHAPEID_ASSIGN_OR_RETURN(options.size_weight, params.Double("size", 0.0, 1000.0));
  SHAPEID_ASSIGN_OR_RETURN(options.up, params.Choice("up", kUpNames));
  SHAPEID_ASSIGN_OR_RETURN(options.smooth, params.Double("smooth", 0.0, kMaxSmooth));
  return CreateDfsd(options);
}

}  // namespace

void PoseMap(const DfsdOptions& options, const std::array<int, 3>& axis_of, int flips,
             std::vector<int>* source, std::vector<float>* sign) {
  // Reversing an axis maps cell i to G - 1 - i (the grid is centered on the box), which
  // multiplies the cosine coefficient of frequency a along it by (-1)^a; reordering axes
  // reorders frequencies. a + b + c is unchanged, so every frequency of the pose is kept.
  const std::vector<Frequency> kept = KeptFrequencies(options.grid, options.order);
  // Dense (a, b, c) -> q over the grid's frequencies: 47 poses look up every kept frequency,
  // up to 32^3 of them (a std::map made a spec like dfsd:grid=32,order=94 cost 2 s to build;
  // found by fuzz/descriptor_spec_fuzzer).
  const int g = options.grid;
  std::vector<int> index_of(static_cast<size_t>(g) * g * g, -1);
  const auto cell = [g](const std::array<int, 3>& f) { return (f[0] * g + f[1]) * g + f[2]; };
  for (size_t q = 0; q < kept.size(); ++q) {
    index_of[cell({kept[q].a, kept[q].b, kept[q].c})] = static_cast<int>(q);
  }
  const size_t dimension = DfsdDimension(options);
  source->assign(dimension, 0);
  sign->assign(dimension, 1.0f);
  const int per_field = static_cast<int>(kept.size());
  const int fields = NumFields(options.fields);
  for (int q = 0; q < per_field; ++q) {
    const std::array<int, 3> now = {kept[q].a, kept[q].b, kept[q].c};
    std::array<int, 3> before{};
    float s = 1;
    for (int i = 0; i < 3; ++i) {
      before[axis_of[i]] = now[i];
      if ((flips >> i & 1) && (now[i] & 1)) s = -s;
    }
    const int from = index_of[cell(before)];
    for (int f = 0; f < fields; ++f) {
      (*source)[f * per_field + q] = f * per_field + from;
      (*sign)[f * per_field + q] = s;
    }
  }
  // The size block holds sorted extents: the same in every pose.
  for (size_t q = static_cast<size_t>(fields) * kept.size(); q < dimension; ++q) {
    (*source)[q] = static_cast<int>(q);
  }
}

std::vector<Frequency> KeptFrequencies(int grid, int order) {
  std::vector<Frequency> kept;
  for (int total = 0; total < order; ++total) {
    for (int a = 0; a <= total && a < grid; ++a) {
      for (int b = 0; a + b <= total && b < grid; ++b) {
        const int c = total - a - b;
        if (c < grid) kept.push_back({a, b, c});
      }
    }
  }
  return kept;
}

void WriteSizeBlock(const Eigen::Vector3d& extent, double weight, float* out) {
  Eigen::Vector3d sorted = extent;
  std::sort(sorted.data(), sorted.data() + 3, std::greater<double>());
  for (int a = 0; a < kSizeFeatures; ++a) {
    const double e = std::max(sorted[a], sorted[0] * kMinRelativeExtent);
    out[a] = static_cast<float>(weight * std::log(e));
  }
}

size_t DfsdDimension(const DfsdOptions& options) {
  return KeptFrequencies(options.grid, options.order).size() * NumFields(options.fields) +
         (options.size_weight > 0 ? kSizeFeatures : 0);
}

absl::StatusOr<std::unique_ptr<Descriptor>> CreateDfsd(const DfsdOptions& options) {
  if (options.grid < kMinGrid || options.grid > kMaxGrid) {
    return absl::InvalidArgumentError(
        absl::StrCat("dfsd: grid=", options.grid, " is outside [", kMinGrid, ", ", kMaxGrid, "]"));
  }
  const int max_order = 3 * (options.grid - 1) + 1;
  if (options.order < 1 || options.order > max_order) {
    return absl::InvalidArgumentError(absl::StrCat(
        "dfsd: order=", options.order, " is outside [1, ", max_order, "] for grid=", options.grid));
  }
  if (!(options.size_weight >= 0 && options.size_weight <= 1000)) {
    return absl::InvalidArgumentError(
        absl::StrCat("dfsd: size=", options.size_weight, " is outside [0, 1000]"));
  }
  if (!(options.smooth >= 0 && options.smooth <= kMaxSmooth)) {
    return absl::InvalidArgumentError(
        absl::StrCat("dfsd: smooth=", options.smooth, " is outside [0, ", kMaxSmooth, "]"));
  }
  if (options.up != DfsdOptions::Up::kPlusZ && options.frame != DfsdOptions::Frame::kUpright) {
    return absl::InvalidArgumentError(absl::StrCat(
        "dfsd: up=", UpName(options.up), " needs frame=upright (frame=", FrameName(options.frame),
        " does not use which way is up)"));
  }
  DescriptorSpec canonical{"dfsd",
                           {{"grid", absl::StrCat(options.grid)},
                            {"order", absl::StrCat(options.order)},
                            {"frame", std::string(FrameName(options.frame))},
                            {"fields", std::string(FieldsName(options.fields))},
                            {"size", FormatSpecNumber(options.size_weight)}}};
  // Written only when it is not the default, so that every spec made before `up` existed
  // keeps its canonical text (stored galleries compare it).
  if (options.up != DfsdOptions::Up::kPlusZ) {
    canonical.params.emplace_back("up", std::string(UpName(options.up)));
  }
  if (options.smooth != 0) {
    canonical.params.emplace_back("smooth", FormatSpecNumber(options.smooth));
  }
  return std::unique_ptr<Descriptor>(
      std::make_unique<DfsdDescriptor>(std::move(canonical), options));
}

}  // namespace dfsd_internal

DescriptorKind DfsdKind() {
  return {"dfsd",
          "DFSD: low frequencies of the object's distance field on a grid (shapeid's own; 240 "
          "values by default)",
          {{"grid", "12", "cells per axis of the distance grid; integer in [4, 32]"},
           {"order", "8",
            "cosine coefficients (a, b, c) kept per field: a + b + c < order (8: 120 per "
            "field); integer in [1, 3 * (grid - 1) + 1]"},
           {"frame", "box",
            "box: the tightest box's axes, with pose variants (any pose; the default) | "
            "upright: z kept as the vertical, x and y from the tightest box seen from above "
            "(gravity-aligned clouds in any yaw) | axes: the cloud's own axes (upright, "
            "aligned objects only) | pca: the principal axes"},
           {"fields", "both",
            "both | isotropic (one scale: proportions kept) | anisotropic (each axis to its "
            "extent)"},
           {"size", "0",
            "weight of the absolute size block (ln of the 3 box extents); 0 = off; use ~0.15 "
            "when every cloud of a gallery is in metres"},
           {"up", "z",
            "frame=upright only: the input axis that points up: z | y | x | -z | -y | -x "
            "(most meshes are y up; LiDAR and ROS are z up)",
            /*omitted_at_default=*/true},
           {"smooth", "0",
            "before describing, move each point to the mean of its nearest points (this share "
            "of the cloud, at least 8); 0 = off; 0.015 for noisy scans of whole objects (not "
            "partial views); in [0, 0.25]",
            /*omitted_at_default=*/true}},
          &dfsd_internal::CreateFromSpec};
}

}  // namespace shapeid
