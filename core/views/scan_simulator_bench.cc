// Scan simulation speed on dense sphere samplings (items/s = input points per second), at the
// default options (160 x 120, distance 3, noise on) and at 640 x 480:
//  - BM_Scan: ScanSimulator::Scan, the surface measured once and buffers reused (many views
//    of one surface);
//  - BM_SimulateScan: one-off scans, which also estimate the sample spacing and allocate.
//   scan_simulator_bench --benchmark_repetitions=3 --benchmark_report_aggregates_only=true

#include <string>
#include <utility>

#include "benchmark/benchmark.h"
#include "core/views/scan_simulator.h"
#include "core/views/test_surfaces.h"

namespace shapeid {
namespace {

ScanOptions Options(const benchmark::State& state) {
  ScanOptions options;
  options.width = static_cast<int>(state.range(1));
  options.height = options.width * 3 / 4;
  return options;
}

void Finish(benchmark::State& state, size_t points_out) {
  state.SetItemsProcessed(state.iterations() * state.range(0));
  state.counters["points_out"] = static_cast<double>(points_out);
}

void BM_Scan(benchmark::State& state) {
  auto simulator =
      ScanSimulator::Create(test_surfaces::SphereSurface(static_cast<size_t>(state.range(0)), 1));
  if (!simulator.ok()) {
    state.SkipWithError(std::string(simulator.status().message()).c_str());
    return;
  }
  ScanOptions options = Options(state);
  size_t points_out = 0;
  for (auto _ : state) {
    ++options.seed;
    auto scan = simulator->Scan(options);
    if (!scan.ok()) {
      state.SkipWithError(std::string(scan.status().message()).c_str());
      return;
    }
    points_out = scan->size();
    benchmark::DoNotOptimize(scan->data());
  }
  Finish(state, points_out);
}

void BM_SimulateScan(benchmark::State& state) {
  const PointCloud sphere = test_surfaces::SphereSurface(static_cast<size_t>(state.range(0)), 1);
  ScanOptions options = Options(state);
  size_t points_out = 0;
  for (auto _ : state) {
    ++options.seed;
    auto scan = SimulateScan(sphere, options);
    if (!scan.ok()) {
      state.SkipWithError(std::string(scan.status().message()).c_str());
      return;
    }
    points_out = scan->size();
    benchmark::DoNotOptimize(scan->data());
  }
  Finish(state, points_out);
}

void Sizes(benchmark::internal::Benchmark* b) {
  b->ArgNames({"points", "width"});
  for (int width : {160, 640}) {
    for (int points : {30000, 100000}) b->Args({points, width});
  }
  b->Unit(benchmark::kMillisecond);
}
BENCHMARK(BM_Scan)->Apply(Sizes);
BENCHMARK(BM_SimulateScan)->Apply(Sizes);

}  // namespace
}  // namespace shapeid

BENCHMARK_MAIN();
