// Descriptor speed: the RPHSD kernel at every SIMD level against the machine's limits, and
// each descriptor's per-cloud time. Run from a release build:
//   tools/bench.sh --benchmark_filter=Rphsd    (release build, medians of 5 repetitions)
// Figures and their reading: docs/performance.md.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "bench/bench_clouds.h"
#include "benchmark/benchmark.h"
#include "core/descriptor_registry.h"
#include "core/descriptors/dfsd_kernels_testing.h"
#include "core/descriptors/reference_points.h"
#include "core/descriptors/rphsd_kernels.h"
#include "core/io/point_cloud_reader.h"
#include "core/simd.h"
#include "core/views/perturb.h"

#if defined(__x86_64__)
#include <immintrin.h>
// GCC 12's AVX-512 headers trip these on their own placeholders (GCC bug 105593).
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Wuninitialized"
#endif

namespace shapeid {
namespace {

namespace fs = std::filesystem;

constexpr size_t kLargeCloud = 100000;

// The RPHSD histogram pass alone (complete, cubic27, M = 100) on 100,000 points, at one SIMD
// level. items/s = point-reference pairs per second.
struct KernelSetup {
  PointCloud cloud = bench::SurfaceCloud(kLargeCloud);
  std::vector<float> rx, ry, rz;
  rphsd_internal::HistogramInput input;
  KernelSetup() {
    const auto refs = Cubic27References();
    rx.assign(32, 0.0f);
    ry.assign(32, 0.0f);
    rz.assign(32, 0.0f);
    for (size_t k = 0; k < refs.size(); ++k) {
      rx[k] = refs[k].x();
      ry[k] = refs[k].y();
      rz[k] = refs[k].z();
    }
    const CloudStats stats = *ValidateCloud(cloud);
    input.xyz = cloud.data();
    input.num_points = cloud.size();
    for (int a = 0; a < 3; ++a) input.center[a] = static_cast<float>(stats.centroid[a]);
    input.inv_scale = static_cast<float>(1.0 / stats.MaxAbsCentered());
    input.ref_x = rx.data();
    input.ref_y = ry.data();
    input.ref_z = rz.data();
    input.num_refs = refs.size();
    input.bins = 100;
    input.bin_scale = static_cast<float>(100 / (2 * std::sqrt(3.0)));
  }
};

const KernelSetup& Kernel() {
  static const auto* const setup = new KernelSetup;
  return *setup;
}

void BM_RphsdKernel(benchmark::State& state) {
  const auto level = static_cast<SimdLevel>(state.range(0));
  if (level > DetectedSimdLevel()) {
    state.SkipWithError("SIMD level not supported by this CPU");
    return;
  }
  const KernelSetup& k = Kernel();
  std::vector<uint32_t> counts(k.input.num_refs * k.input.bins);
  for (auto _ : state) {
    std::fill(counts.begin(), counts.end(), 0u);
    rphsd_internal::AccumulateHistograms(k.input, counts.data(), level);
    benchmark::DoNotOptimize(counts.data());
  }
  state.SetItemsProcessed(state.iterations() * k.input.num_points * k.input.num_refs);
  state.SetLabel(std::string(SimdLevelName(level)));
}
BENCHMARK(BM_RphsdKernel)->Arg(0)->Arg(1)->Arg(2)->Unit(benchmark::kMicrosecond);

#if defined(__x86_64__)
// Machine limit 1: one square root per pair and nothing else (AVX-512 vsqrtps over the same
// number of pairs, results folded so they are not dead).
__attribute__((target("avx512f"), noinline)) float SqrtOnly(size_t pairs) {
  __m512 acc = _mm512_setzero_ps();
  __m512 x = _mm512_set1_ps(1.5f);
  const __m512 step = _mm512_set1_ps(1e-7f);
  for (size_t i = 0; i < pairs; i += 16) {
    acc = _mm512_add_ps(acc, _mm512_sqrt_ps(x));
    x = _mm512_add_ps(x, step);
  }
  return _mm512_reduce_add_ps(acc);
}

void BM_LimitSqrtOnly(benchmark::State& state) {
  if (DetectedSimdLevel() < SimdLevel::kAvx512) {
    state.SkipWithError("needs AVX-512");
    return;
  }
  size_t pairs = kLargeCloud * 27;
  for (auto _ : state) {
    benchmark::DoNotOptimize(pairs);  // the call must not be hoisted out of the loop
    float sum = SqrtOnly(pairs);
    benchmark::DoNotOptimize(sum);
  }
  state.SetItemsProcessed(state.iterations() * pairs);
}
BENCHMARK(BM_LimitSqrtOnly)->Unit(benchmark::kMicrosecond);
#endif

// Machine limit 2: one histogram increment per pair with the bin indices already known
// (precomputed from the real kernel's distances), the same access pattern as the kernel.
void BM_LimitIncrementsOnly(benchmark::State& state) {
  const KernelSetup& k = Kernel();
  const size_t refs = k.input.num_refs;
  const int bins = k.input.bins;
  std::vector<int32_t> slots(k.input.num_points * refs);
  for (size_t i = 0; i < k.input.num_points; ++i) {
    const float* p = k.input.xyz + 3 * i;
    for (size_t r = 0; r < refs; ++r) {
      const float dx = (p[0] - k.input.center[0]) * k.input.inv_scale - k.rx[r];
      const float dy = (p[1] - k.input.center[1]) * k.input.inv_scale - k.ry[r];
      const float dz = (p[2] - k.input.center[2]) * k.input.inv_scale - k.rz[r];
      const int bin =
          static_cast<int>(std::sqrt((dx * dx + dy * dy) + dz * dz) * k.input.bin_scale);
      slots[i * refs + r] = static_cast<int32_t>(r) * bins + std::min(bin, bins - 1);
    }
  }
  std::vector<uint32_t> counts(refs * bins);
  for (auto _ : state) {
    std::fill(counts.begin(), counts.end(), 0u);
    for (int32_t s : slots) ++counts[s];
    benchmark::DoNotOptimize(counts.data());
  }
  state.SetItemsProcessed(state.iterations() * slots.size());
}
BENCHMARK(BM_LimitIncrementsOnly)->Unit(benchmark::kMicrosecond);

// Section 0 validation, the one pass every descriptor makes before its own work.
void BM_ValidateCloud(benchmark::State& state) {
  const PointCloud cloud = bench::SurfaceCloud(kLargeCloud);
  for (auto _ : state) {
    auto stats = ValidateCloud(cloud);
    benchmark::DoNotOptimize(stats);
  }
  state.SetItemsProcessed(state.iterations() * cloud.size());
}
BENCHMARK(BM_ValidateCloud)->Unit(benchmark::kMicrosecond);

// Whole descriptors through the public API (validation, normalization, features).
void DescribeBench(benchmark::State& state, const std::string& spec, size_t points) {
  auto descriptor = CreateDescriptor(spec);
  if (!descriptor.ok()) {
    state.SkipWithError(std::string(descriptor.status().message()).c_str());
    return;
  }
  const PointCloud cloud = bench::SurfaceCloud(points);
  std::vector<float> out;
  for (auto _ : state) {
    const absl::Status status = (*descriptor)->Compute(cloud, &out);
    if (!status.ok()) {
      state.SkipWithError(std::string(status.message()).c_str());
      return;
    }
    benchmark::DoNotOptimize(out.data());
  }
  state.SetItemsProcessed(state.iterations() * points);
  state.SetLabel(std::string(SimdLevelName(ActiveSimdLevel())));
}

BENCHMARK_CAPTURE(DescribeBench, rphsd_complete_cubic27_m100_100k, std::string("rphsd"), 100000)
    ->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(DescribeBench, rphsd_reduced_cross7_m10_100k,
                  std::string("rphsd:refs=cross7,bins=10,variant=reduced"), 100000)
    ->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(DescribeBench, comsd_n50_100k, std::string("comsd:grid=50"), 100000)
    ->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(DescribeBench, cnsd_default_8k, std::string("cnsd"), 8000)
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(DescribeBench, dfsd_default_100k, std::string("dfsd"), 100000)
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(DescribeBench, dfsd_box_100k, std::string("dfsd:frame=box"), 100000)
    ->Unit(benchmark::kMillisecond);
// A million points: the kernel's tables no longer fit any cache in one pass (issue 7's growth).
BENCHMARK_CAPTURE(DescribeBench, dfsd_default_1m, std::string("dfsd"), 1000000)
    ->Unit(benchmark::kMillisecond)
    ->Iterations(3);
// Smoothing reduces a large cloud to 4,096 points first, so it describes far fewer.
BENCHMARK_CAPTURE(DescribeBench, dfsd_smooth_100k, std::string("dfsd:smooth=0.015"), 100000)
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(DescribeBench, dfsd_smooth_1m, std::string("dfsd:smooth=0.015"), 1000000)
    ->Unit(benchmark::kMillisecond);
// Per-cloud time on real ModelNet10 clouds (1,024 points): the first 10 test files of each
// class from ../shared/data, described in turn. Where the data is absent, synthetic
// 1,024-point clouds stand in and the label says so.
const std::vector<PointCloud>& ModelNetClouds(bool* real) {
  static bool found = false;
  static const auto* const clouds = [] {
    auto* list = new std::vector<PointCloud>(bench::ModelNet10TestClouds(
        fs::path(SHAPEID_SOURCE_DIR) / ".." / "shared" / "data" / "modelnet10", 10));
    found = !list->empty();
    for (uint32_t seed = 0; list->empty() || list->size() < 10; ++seed) {
      list->push_back(bench::SurfaceCloud(1024, seed));
    }
    return list;
  }();
  *real = found;
  return *clouds;
}

void ModelNetCloudBench(benchmark::State& state, const std::string& spec) {
  auto descriptor = CreateDescriptor(spec);
  if (!descriptor.ok()) {
    state.SkipWithError(std::string(descriptor.status().message()).c_str());
    return;
  }
  bool real = false;
  const std::vector<PointCloud>& clouds = ModelNetClouds(&real);
  std::vector<float> out;
  size_t next = 0;
  for (auto _ : state) {
    const absl::Status status = (*descriptor)->Compute(clouds[next], &out);
    if (!status.ok()) {
      state.SkipWithError(std::string(status.message()).c_str());
      return;
    }
    benchmark::DoNotOptimize(out.data());
    next = next + 1 == clouds.size() ? 0 : next + 1;
  }
  state.SetItemsProcessed(state.iterations());  // clouds
  state.SetLabel(absl::StrCat(real ? "ModelNet10 x" : "SYNTHETIC (no ../shared/data) x",
                              clouds.size(), " ", SimdLevelName(ActiveSimdLevel())));
}
BENCHMARK_CAPTURE(ModelNetCloudBench, rphsd, std::string("rphsd"))->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(ModelNetCloudBench, rphsd_reduced_cross7_m10,
                  std::string("rphsd:refs=cross7,bins=10,variant=reduced"))
    ->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(ModelNetCloudBench, comsd, std::string("comsd"))->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(ModelNetCloudBench, cnsd, std::string("cnsd"))->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(ModelNetCloudBench, dfsd, std::string("dfsd"))->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(ModelNetCloudBench, dfsd_pca, std::string("dfsd:frame=pca"))
    ->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(ModelNetCloudBench, dfsd_smooth, std::string("dfsd:smooth=0.015"))
    ->Unit(benchmark::kMicrosecond);

// The DFSD kernel alone (one field, G = 12, the default grid) on the same ModelNet10 clouds,
// reading every point (0) or only the blocks within reach (1), at the machine's SIMD level:
// the ratio of the two in one run is the pruning's gain (docs/performance.md, "DFSD's pruned
// kernel"). Both give the same bits (dfsd_kernels_test).
void BM_DfsdKernel(benchmark::State& state) {
  const bool pruned = state.range(0) == 1;
  constexpr int kGrid = 12;
  bool real = false;
  std::vector<dfsd_internal::GeometricInput> inputs;
  for (const PointCloud& cloud : ModelNetClouds(&real)) {
    const dfsd_internal::Points points = dfsd_internal::BoxNormalized(cloud);
    inputs.emplace_back(kGrid, dfsd_internal::PaddedStride(points.size()));
    inputs.back().Fill(points, /*first_chunk=*/true);
  }
  std::vector<float> out(kGrid * kGrid * kGrid);
  const SimdLevel level = ActiveSimdLevel();
  size_t next = 0;
  for (auto _ : state) {
    dfsd_internal::NearestSquaredDistances(inputs[next].Input(pruned, false), out.data(), level);
    benchmark::DoNotOptimize(out.data());
    next = (next + 1) % inputs.size();
  }
  state.SetItemsProcessed(state.iterations());
  state.SetLabel(absl::StrCat(pruned ? "pruned, " : "every point, ",
                              real ? "ModelNet10 x" : "SYNTHETIC (no ../shared/data) x",
                              inputs.size(), ", ", SimdLevelName(level)));
}
BENCHMARK(BM_DfsdKernel)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);

// What a robot's Classify describes: DFSD in the box frame with its pose variants, on
// single-view sensor scans (SensorView: one side, 1 % noise, 300-500 points, random pose) of
// the same ModelNet10 clouds. Issue 13's target: under 0.5 ms per cloud.
void RobotViewBench(benchmark::State& state, const std::string& spec) {
  auto descriptor = CreateDescriptor(spec);
  if (!descriptor.ok()) {
    state.SkipWithError(std::string(descriptor.status().message()).c_str());
    return;
  }
  bool real = false;
  std::vector<PointCloud> views;
  size_t points = 0;
  for (const PointCloud& cloud : ModelNetClouds(&real)) {
    absl::StatusOr<PointCloud> view = SensorView(cloud, SensorViewOptions(), views.size() + 1);
    if (!view.ok()) continue;
    points += view->size();
    views.push_back(std::move(*view));
  }
  std::vector<float> out, variants;
  size_t next = 0, poses = 0;
  for (auto _ : state) {
    const absl::Status status =
        (*descriptor)->ComputeWithPoseVariants(views[next], &out, &variants);
    if (!status.ok()) {
      state.SkipWithError(std::string(status.message()).c_str());
      return;
    }
    poses += 1 + variants.size() / out.size();
    benchmark::DoNotOptimize(variants.data());
    next = next + 1 == views.size() ? 0 : next + 1;
  }
  state.SetItemsProcessed(state.iterations());  // clouds
  state.counters["poses_per_cloud"] =
      static_cast<double>(poses) / static_cast<double>(state.iterations());
  state.SetLabel(absl::StrCat(real ? "ModelNet10 views x" : "SYNTHETIC (no ../shared/data) x",
                              views.size(), ", ", points / std::max<size_t>(1, views.size()),
                              " points on average, ", SimdLevelName(ActiveSimdLevel())));
}
BENCHMARK_CAPTURE(ModelNetCloudBench, dfsd_box, std::string("dfsd:frame=box"))
    ->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(RobotViewBench, dfsd_box, std::string("dfsd:frame=box"))
    ->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(RobotViewBench, dfsd_axes, std::string("dfsd"))->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(RobotViewBench, dfsd_box_smooth, std::string("dfsd:frame=box,smooth=0.015"))
    ->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(ModelNetCloudBench, learned, std::string("learned"))
    ->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(RobotViewBench, learned, std::string("learned"))->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace shapeid

BENCHMARK_MAIN();
