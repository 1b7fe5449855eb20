#include "core/descriptors/rphsd.h"

#include <cmath>
#include <utility>

#include "absl/strings/str_cat.h"
#include "core/descriptors/cost_model.h"
#include "core/descriptors/rphsd_kernels.h"
#include "core/enum_names.h"
#include "core/parallel_ranges.h"
#include "core/status_macros.h"

namespace shapeid {
namespace {

constexpr EnumNames<RphsdOptions::Variant, 2> kVariantNames = {{
    {RphsdOptions::Variant::kComplete, "complete"},
    {RphsdOptions::Variant::kReduced, "reduced"},
}};

constexpr int kMaxBins = 100000;
// The diagonal of the [-1, 1]^3 cube: the largest distance between a normalized point and
// a reference inside the cube. Farther pairs (custom references outside the cube, float
// rounding at the corners) are clamped into the last bin.
const double kMaxDistance = 2.0 * std::sqrt(3.0);

struct HistogramFeatures {
  double variance, entropy, idm;
};

// c ln c for the small counts that fill most bins, so the entropy of a histogram costs table
// lookups instead of one logarithm per bin (27 x 100 logarithms would otherwise take as long
// as counting a 1,024-point cloud).
constexpr uint32_t kCLnCTableSize = 4096;
const double* CLnCTable() {
  static const double* const table = [] {
    auto* t = new double[kCLnCTableSize];
    t[0] = 0.0;  // 0 ln 0 = 0
    for (uint32_t c = 1; c < kCLnCTableSize; ++c) t[c] = c * std::log(static_cast<double>(c));
    return t;
  }();
  return table;
}

// Step 3 of the definition, in double, from the integer counts of one histogram of M bins
// over n points, with h_i = c_i / n:
//   entropy  -sum h ln h = ln n - (1/n) sum c ln c      (since sum c = n)
//   IDM      sum h / (1 + i^2), with the weights 1 / (1 + i^2) precomputed.
HistogramFeatures FeaturesOf(const uint32_t* counts, int bins, size_t num_points,
                             const double* idm_weights) {
  const double* c_ln_c = CLnCTable();
  const double n = static_cast<double>(num_points);
  const double mean = 1.0 / bins;
  double sum_sq = 0, sum_c_ln_c = 0, idm = 0;
  for (int i = 0; i < bins; ++i) {
    const uint32_t c = counts[i];
    const double h = c / n;
    sum_sq += (h - mean) * (h - mean);
    sum_c_ln_c += c < kCLnCTableSize ? c_ln_c[c] : c * std::log(static_cast<double>(c));
    idm += h * idm_weights[i];
  }
  return {sum_sq / bins, std::log(n) - sum_c_ln_c / n, idm};
}

void MeanAndStd(const std::vector<double>& values, float* mean_out, float* std_out) {
  double mean = 0;
  for (double v : values) mean += v;
  mean /= static_cast<double>(values.size());
  double sum_sq = 0;
  for (double v : values) sum_sq += (v - mean) * (v - mean);
  *mean_out = static_cast<float>(mean);
  *std_out = static_cast<float>(std::sqrt(sum_sq / static_cast<double>(values.size())));
}

}  // namespace

Rphsd::Rphsd(DescriptorSpec spec, size_t dimension, RphsdOptions options)
    : Descriptor(std::move(spec), dimension), options_(std::move(options)) {
  idm_weights_.resize(options_.bins);
  for (int i = 0; i < options_.bins; ++i)
    idm_weights_[i] = 1.0 / (1.0 + static_cast<double>(i) * i);
  const size_t k = options_.references.points.size();
  const size_t lanes = rphsd_internal::kReferenceLanes;
  const size_t padded = (k + lanes - 1) / lanes * lanes;
  ref_x_.assign(padded, 0.0f);
  ref_y_.assign(padded, 0.0f);
  ref_z_.assign(padded, 0.0f);
  for (size_t i = 0; i < k; ++i) {
    ref_x_[i] = options_.references.points[i].x();
    ref_y_[i] = options_.references.points[i].y();
    ref_z_[i] = options_.references.points[i].z();
  }
}

absl::StatusOr<std::unique_ptr<Rphsd>> Rphsd::Create(RphsdOptions options) {
  if (options.bins < 1 || options.bins > kMaxBins) {
    return absl::InvalidArgumentError(
        absl::StrCat("rphsd: bins=", options.bins, " is outside [1, ", kMaxBins, "]"));
  }
  const size_t k = options.references.points.size();
  if (k == 0 || k > static_cast<size_t>(kMaxReferencePoints)) {
    return absl::InvalidArgumentError(
        absl::StrCat("rphsd: ", k, " reference points; need 1 to ", kMaxReferencePoints));
  }
  for (const Eigen::Vector3f& q : options.references.points) {
    if (!q.allFinite() || q.cwiseAbs().maxCoeff() > kMaxReferenceCoordinate) {
      return absl::InvalidArgumentError(absl::StrCat(
          "rphsd: reference point (", q.x(), ", ", q.y(), ", ", q.z(), ") is outside [-",
          kMaxReferenceCoordinate, ", ", kMaxReferenceCoordinate, "]^3"));
    }
  }
  const bool reduced = options.variant == RphsdOptions::Variant::kReduced;
  DescriptorSpec spec{"rphsd",
                      {{"refs", options.references.name},
                       {"bins", absl::StrCat(options.bins)},
                       {"variant", std::string(NameOf(kVariantNames, options.variant))}}};
  const size_t dimension = reduced ? 6 : 3 * k;
  return std::unique_ptr<Rphsd>(new Rphsd(std::move(spec), dimension, std::move(options)));
}

DescribeCost Rphsd::EstimateCost(size_t num_points) const {
  // CPU: per point, a SIMD distance to every reference and one counter increment each; per
  // histogram bin, the three features. Constants: docs/performance.md, "Describe cost".
  constexpr double kNsBase = 1000, kNsPerPoint = 2.7, kNsPerPointReference = 0.74, kNsPerBin = 1.7;
  const double n = static_cast<double>(num_points);
  const double k = static_cast<double>(options_.references.points.size());
  const double m = static_cast<double>(options_.bins);
  DescribeCost cost;
  cost.cpu = cost_model::Nanoseconds(kNsBase + n * (kNsPerPoint + kNsPerPointReference * k) +
                                     kNsPerBin * k * m);
  const size_t refs = options_.references.points.size();
  const size_t lanes = rphsd_internal::kReferenceLanes;
  cost.working_bytes = refs * static_cast<size_t>(options_.bins) * sizeof(uint32_t)  // counts
                       + 3 * refs * sizeof(double)                                   // features
                       + 2 * (refs + lanes) * sizeof(int32_t)  // the kernel's slots, offsets
                       + kCLnCTableSize * sizeof(double)       // built by the first call
                       + dimension() * sizeof(float) + cost_model::kHeapSlack;
  return cost;
}

absl::Status Rphsd::ComputeValidated(const PointCloud& cloud, const CloudStats& stats,
                                     const CloudLimits& limits, absl::Span<float> out) const {
  return ComputeWith(cloud, stats, ActiveSimdLevel(), limits.max_threads, out);
}

absl::Status Rphsd::ComputeAtLevel(const PointCloud& cloud, SimdLevel level,
                                   std::vector<float>* out, const CloudLimits& limits) const {
  if (level > DetectedSimdLevel()) {
    return absl::FailedPreconditionError(
        absl::StrCat("this CPU does not support ", SimdLevelName(level)));
  }
  SHAPEID_ASSIGN_OR_RETURN(const CloudStats stats, ValidateCloud(cloud, limits));
  out->resize(dimension());
  return ComputeWith(cloud, stats, level, limits.max_threads, absl::MakeSpan(*out));
}

absl::Status Rphsd::ComputeWith(const PointCloud& cloud, const CloudStats& stats, SimdLevel level,
                                int max_threads, absl::Span<float> out) const {
  // Step 1: center on the centroid, scale by the L-infinity radius into [-1, 1]^3.
  const double radius = stats.MaxAbsCentered();
  const float inv_scale = static_cast<float>(1.0 / radius);
  if (!(radius > 0) || !std::isfinite(inv_scale)) {
    return absl::InvalidArgumentError(absl::StrCat(
        "rphsd: the cloud's extent (", radius, ") is too small to normalize in float precision"));
  }
  const size_t num_refs = options_.references.points.size();
  const int bins = options_.bins;

  // Step 2: K histograms of M bins, counted in one pass over the points.
  rphsd_internal::HistogramInput input;
  input.xyz = cloud.data();
  input.num_points = cloud.size();
  for (int a = 0; a < 3; ++a) input.center[a] = static_cast<float>(stats.centroid[a]);
  input.inv_scale = inv_scale;
  input.ref_x = ref_x_.data();
  input.ref_y = ref_y_.data();
  input.ref_z = ref_z_.data();
  input.num_refs = num_refs;
  input.bins = bins;
  input.bin_scale = static_cast<float>(bins / kMaxDistance);
  const size_t histogram_values = num_refs * static_cast<size_t>(bins);
  const int64_t num_points = static_cast<int64_t>(cloud.size());
  const int parts = ParallelParts(num_points, max_threads, kMinPointsPerThread);
  std::vector<uint32_t> counts(histogram_values * static_cast<size_t>(parts), 0);
  ParallelRanges(num_points, parts, kMinPointsPerThread, [&](int part, int64_t begin, int64_t end) {
    rphsd_internal::HistogramInput range = input;
    range.xyz = input.xyz + 3 * begin;
    range.num_points = static_cast<size_t>(end - begin);
    rphsd_internal::AccumulateHistograms(
        range, &counts[histogram_values * static_cast<size_t>(part)], level);
  });
  for (int part = 1; part < parts; ++part) {
    const uint32_t* part_counts = &counts[histogram_values * static_cast<size_t>(part)];
    for (size_t i = 0; i < histogram_values; ++i) counts[i] += part_counts[i];
  }

  // Steps 3 and 4.
  std::vector<double> variances(num_refs), entropies(num_refs), idms(num_refs);
  for (size_t k = 0; k < num_refs; ++k) {
    const HistogramFeatures f =
        FeaturesOf(&counts[k * bins], bins, cloud.size(), idm_weights_.data());
    variances[k] = f.variance;
    entropies[k] = f.entropy;
    idms[k] = f.idm;
  }
  if (options_.variant == RphsdOptions::Variant::kReduced) {
    MeanAndStd(variances, &out[0], &out[1]);
    MeanAndStd(entropies, &out[2], &out[3]);
    MeanAndStd(idms, &out[4], &out[5]);
    return absl::OkStatus();
  }
  for (size_t k = 0; k < num_refs; ++k) {
    out[k] = static_cast<float>(variances[k]);
    out[num_refs + k] = static_cast<float>(entropies[k]);
    out[2 * num_refs + k] = static_cast<float>(idms[k]);
  }
  return absl::OkStatus();
}

DescriptorKind RphsdKind() {
  return {
      "rphsd",
      "Reference Points Histograms Shape Descriptor: distance histograms from reference points",
      {{"refs", "cubic27",
        "reference arrangement: cross7, cubic27, spherical27, fibonacci:N (N in [1, 4095]) or a "
        "list [x,y,z;x,y,z;...] in the normalized cube"},
       {"bins", "100", "histogram size M, in [1, 100000]"},
       {"variant", "complete",
        "complete (3K values: variance, entropy, IDM per reference) or reduced (6 values: mean "
        "and std of each)"}},
      [](const DescriptorSpec& spec) -> absl::StatusOr<std::unique_ptr<Descriptor>> {
        const SpecParams params(spec);
        RphsdOptions options;
        SHAPEID_ASSIGN_OR_RETURN(const std::string refs, params.Text("refs"));
        SHAPEID_ASSIGN_OR_RETURN(options.references, ParseReferenceArrangement(refs));
        SHAPEID_ASSIGN_OR_RETURN(const int64_t bins, params.Int("bins", 1, kMaxBins));
        options.bins = static_cast<int>(bins);
        SHAPEID_ASSIGN_OR_RETURN(options.variant, params.Choice("variant", kVariantNames));
        SHAPEID_ASSIGN_OR_RETURN(auto rphsd, Rphsd::Create(std::move(options)));
        return std::unique_ptr<Descriptor>(std::move(rphsd));
      }};
}

}  // namespace shapeid
