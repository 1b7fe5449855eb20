// Issue 25: every descriptor's EstimateCost beside what ComputeWithPoseVariants really takes:
// the median CPU time of several runs and the peak heap (counted by core/descriptors/
// heap_meter.h, which this program links), for each kind at its defaults and a few other
// settings, from 1,000 to 10,000,000 points. Prints a Markdown table for docs/performance.md.
// Run from a release build on a quiet machine:
//   build/release/bench/describe_cost_bench [--runs 5] [--runs_large 3] [--max_points 10000000]
//                                           [--specs dfsd,rphsd:bins=1000]

#include <time.h>

#include <algorithm>
#include <cstdio>
#include <string>
#include <vector>

#include "CLI/CLI.hpp"
#include "absl/strings/str_split.h"
#include "absl/time/time.h"
#include "bench/bench_clouds.h"
#include "core/descriptor_registry.h"
#include "core/descriptors/heap_meter.h"
#include "core/simd.h"

namespace shapeid {
namespace {

const std::vector<std::string> kDefaultSpecs = {
    "rphsd",
    "rphsd:refs=cross7",
    "rphsd:refs=fibonacci:255,bins=1000",
    "comsd",
    "comsd:grid=20",
    "comsd:grid=128",
    "cnsd",
    "cnsd:max_points=2000",
    "cnsd:downsample=random",
    "cnsd:t_step=0.01",
    "dfsd",
    "dfsd:frame=upright",
    "dfsd:frame=pca",
    "dfsd:frame=axes",
    "dfsd:grid=16,order=10",
    "dfsd:grid=8,fields=isotropic",
    "dfsd:smooth=0.015",
    "learned",
};

// CPU time of this thread: the estimate is for one core, and a shared machine's other work
// inflates wall time but not this.
double ThreadSeconds() {
  timespec t;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

constexpr double kMiB = 1024.0 * 1024.0;

int Run(int argc, char** argv) {
  CLI::App app("describe_cost_bench: EstimateCost against measured time and peak heap");
  int runs = 5, runs_large = 3;
  size_t max_points = 10000000;
  std::string specs_text;
  app.add_option("--runs", runs, "runs per measurement up to 10^5 points (median)");
  app.add_option("--runs_large", runs_large, "runs from 10^6 points");
  app.add_option("--max_points", max_points, "largest cloud (powers of 10 from 1,000)");
  app.add_option("--specs", specs_text, "comma-separated specs (default: a set for each kind)");
  CLI11_PARSE(app, argc, argv);
  std::vector<std::string> specs = kDefaultSpecs;
  if (!specs_text.empty()) specs = absl::StrSplit(specs_text, ',', absl::SkipEmpty());
  if (!heap_meter::Available()) std::fprintf(stderr, "heap meter unavailable: peaks show 0\n");

  std::printf("SIMD level: %s\n\n", std::string(SimdLevelName(ActiveSimdLevel())).c_str());
  std::printf(
      "| spec | points | est. ms | CPU ms (median) | est./CPU | wall ms | est. MiB | "
      "peak MiB | peak/est. |\n|---|--:|--:|--:|--:|--:|--:|--:|--:|\n");
  for (size_t n = 1000; n <= max_points; n *= 10) {
    const PointCloud cloud = bench::SurfaceCloud(n);
    for (const std::string& text : specs) {
      auto descriptor = CreateDescriptor(text);
      if (!descriptor.ok()) {
        std::fprintf(stderr, "%s: %s\n", text.c_str(), descriptor.status().ToString().c_str());
        return 2;
      }
      const DescribeCost estimate = (*descriptor)->EstimateCost(n);
      std::vector<double> cpu, wall;
      int64_t peak = 0;
      const int count = n >= 1000000 ? runs_large : runs;
      for (int r = 0; r < count; ++r) {
        std::vector<float> out, variants;
        heap_meter::Start();
        const absl::Time start = absl::Now();
        const double cpu_start = ThreadSeconds();
        const absl::Status status = (*descriptor)->ComputeWithPoseVariants(cloud, &out, &variants);
        cpu.push_back(ThreadSeconds() - cpu_start);
        wall.push_back(absl::ToDoubleSeconds(absl::Now() - start));
        peak = std::max(peak, heap_meter::Stop());
        if (!status.ok()) {
          std::fprintf(stderr, "%s: %s\n", text.c_str(), status.ToString().c_str());
          return 1;
        }
      }
      const double est_ms = absl::ToDoubleMilliseconds(estimate.cpu);
      const double cpu_ms = 1e3 * Median(cpu);
      const double est_mib = static_cast<double>(estimate.working_bytes) / kMiB;
      const double peak_mib = static_cast<double>(peak) / kMiB;
      std::printf("| %s | %zu | %.3g | %.3g | %.2f | %.3g | %.3g | %.3g | %.2f |\n", text.c_str(),
                  n, est_ms, cpu_ms, est_ms / cpu_ms, 1e3 * Median(wall), est_mib, peak_mib,
                  peak_mib / est_mib);
      std::fflush(stdout);
    }
  }
  return 0;
}

}  // namespace
}  // namespace shapeid

int main(int argc, char** argv) { return shapeid::Run(argc, argv); }
