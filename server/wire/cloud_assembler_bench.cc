// How fast the server turns a cloud's chunks into float32 points in each layout (Google
// Benchmark): packed float32 (a copy) is the baseline; a PointCloud2's 16-byte x y z
// intensity, float64 big-endian, dropping non-finite points and applying a sensor frame
// run beside it on the same 1,000,000 points, in 64 KiB chunks as gRPC delivers them.
// docs/performance.md quotes the figures.

#include <algorithm>
#include <cstring>
#include <string>
#include <vector>

#include "benchmark/benchmark.h"
#include "server/wire/cloud_assembler.h"

namespace shapeid {
namespace {

constexpr size_t kPoints = 1'000'000;
constexpr size_t kChunkBytes = 64 << 10;

float Coordinate(size_t i, int axis) { return static_cast<float>((i * 7 + axis * 13) % 1000); }

// The points of `kPoints` in `layout` (little-endian host; big-endian layouts byte-swapped).
std::string Bytes(const PointLayout& layout) {
  std::string out(kPoints * layout.point_step, '\0');
  for (size_t i = 0; i < kPoints; ++i) {
    for (int a = 0; a < 3; ++a) {
      char bytes[8];
      size_t size = 4;
      if (layout.xyz[a].type == PointLayout::Type::kFloat64) {
        const double v = Coordinate(i, a);
        std::memcpy(bytes, &v, 8);
        size = 8;
      } else {
        const float v = Coordinate(i, a);
        std::memcpy(bytes, &v, 4);
      }
      if (layout.big_endian) std::reverse(bytes, bytes + size);
      std::memcpy(out.data() + i * layout.point_step + layout.xyz[a].offset, bytes, size);
    }
  }
  return out;
}

void Assemble(benchmark::State& state, const WireCloudFormat& format) {
  const std::string bytes = Bytes(format.layout);
  // Chunks of whole points, as the clients cut them.
  const size_t chunk = kChunkBytes / format.layout.point_step * format.layout.point_step;
  CloudAssembler assembler(kPoints);
  for (auto _ : state) {
    if (!assembler.Start(kPoints, format).ok()) state.SkipWithError("Start");
    for (size_t at = 0; at < bytes.size(); at += chunk) {
      if (!assembler.Append(absl::string_view(bytes).substr(at, chunk)).ok()) {
        state.SkipWithError("Append");
      }
    }
    auto cloud = assembler.Finish();
    if (!cloud.ok() || cloud->size() != kPoints) state.SkipWithError("Finish");
    benchmark::DoNotOptimize(cloud->data());
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations() * kPoints));
  state.SetBytesProcessed(static_cast<int64_t>(state.iterations() * bytes.size()));
}

WireCloudFormat WithLayout(uint32_t step, PointLayout::Type type, bool big_endian) {
  WireCloudFormat format;
  format.layout.point_step = step;
  const uint32_t size = type == PointLayout::Type::kFloat64 ? 8 : 4;
  for (uint32_t a = 0; a < 3; ++a) format.layout.xyz[a] = {a * size, type};
  format.layout.big_endian = big_endian;
  return format;
}

void BM_PackedFloat32(benchmark::State& state) { Assemble(state, WireCloudFormat()); }
void BM_PointCloud2XyzIntensity(benchmark::State& state) {
  Assemble(state, WithLayout(16, PointLayout::Type::kFloat32, false));
}
void BM_Float64BigEndian(benchmark::State& state) {
  Assemble(state, WithLayout(32, PointLayout::Type::kFloat64, true));
}
void BM_PointCloud2DropNonFinite(benchmark::State& state) {
  WireCloudFormat format = WithLayout(16, PointLayout::Type::kFloat32, false);
  format.layout.drop_nonfinite = true;
  Assemble(state, format);
}
void BM_PointCloud2WithFrame(benchmark::State& state) {
  WireCloudFormat format = WithLayout(16, PointLayout::Type::kFloat32, false);
  format.frame = *RotationTakingUpTo(std::vector<double>{0, -1, 0}, {0, 0, 1});
  Assemble(state, format);
}

BENCHMARK(BM_PackedFloat32)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_PointCloud2XyzIntensity)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Float64BigEndian)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_PointCloud2DropNonFinite)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_PointCloud2WithFrame)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace shapeid

BENCHMARK_MAIN();
