// Issue 7, "Descriptors vs PCL": the time to describe one cloud with shapeid's descriptors and
// with the PCL global descriptors a user would otherwise pick (ESF, GASD, VFH with its normal
// estimation), in the same run, single thread, on real ModelNet10 clouds and on synthetic
// 10^4, 10^5 and 10^6-point surface clouds. Build and run: bench/pcl/README.md. Figures:
// docs/performance.md.
//
// What is timed is what a user pays per new cloud through each library's public API:
// - shapeid: Descriptor::Compute (validation, normalization, features).
// - PCL: a fresh estimator per cloud, setInputCloud, compute. PCL's Feature::initCompute
//   builds a kd-tree over the cloud even for ESF and GASD, which never search it, so that is
//   part of what a PCL user pays; the `_bruteforce` variants hand those two a search object
//   whose set-up is free (pcl::search::BruteForce), leaving the descriptor's own work.
// Not timed: reading files and converting a shapeid PointCloud to pcl::PointCloud<PointXYZ>
// (both done once, before any benchmark runs).
//
// Single thread: only PCL's plain estimators are used, never the *OMP variants, and the
// `threads` counter reports the process's thread count after each benchmark (an OpenMP team,
// once started, would stay and show up there). Run with OMP_NUM_THREADS=1 anyway.

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "bench/bench_clouds.h"
#include "bench/host_info.h"
#include "benchmark/benchmark.h"
#include "core/descriptor_registry.h"
#include "core/io/point_cloud_reader.h"
#include "core/point_cloud.h"
#include "pcl/features/esf.h"
#include "pcl/features/gasd.h"
#include "pcl/features/normal_3d.h"
#include "pcl/features/vfh.h"
#include "pcl/point_cloud.h"
#include "pcl/point_types.h"
#include "pcl/search/brute_force.h"
#include "pcl/search/kdtree.h"

namespace shapeid {
namespace {

namespace fs = std::filesystem;

using PclCloud = pcl::PointCloud<pcl::PointXYZ>;

// The inputs of one benchmark row, in both libraries' types. `points` == kModelNet10 means
// the real clouds; any other value, one synthetic surface cloud of that many points.
constexpr size_t kModelNet10 = 0;
const size_t kInputSizes[] = {kModelNet10, 10000, 100000, 1000000};

// What a PCL user computes normals with for VFH: the k nearest neighbors, k = 10, through a
// kd-tree. A fixed radius, PCL's other option, must be tuned to each cloud's density, and on a
// denser cloud of the same object gathers ever more neighbors (quadratic growth); k-nearest
// needs no tuning across the 1,024 to 10^6-point inputs here.
constexpr int kNormalNeighbors = 10;

struct Inputs {
  std::vector<PointCloud> clouds;
  std::vector<PclCloud::ConstPtr> pcl_clouds;  // the same points, converted once
  std::string label;
};

PclCloud::ConstPtr ToPcl(const PointCloud& cloud) {
  auto out = std::make_shared<PclCloud>();
  out->resize(cloud.size());
  for (size_t i = 0; i < cloud.size(); ++i) {
    const float* p = cloud.data() + 3 * i;
    (*out)[i] = pcl::PointXYZ(p[0], p[1], p[2]);
  }
  out->width = static_cast<uint32_t>(cloud.size());
  out->height = 1;
  out->is_dense = true;
  return out;
}

// Built on first use and kept: the 10^6-point clouds take a moment, and every benchmark on
// one input must see the very same points. Benchmarks run one at a time, so no lock.
const Inputs& GetInputs(size_t points) {
  static auto* const cache = new std::map<size_t, Inputs>;
  auto [it, inserted] = cache->try_emplace(points);
  Inputs& inputs = it->second;
  if (!inserted) return inputs;
  if (points == kModelNet10) {
    inputs.clouds = bench::ModelNet10TestClouds(
        fs::path(SHAPEID_SOURCE_DIR) / ".." / "shared" / "data" / "modelnet10", 10);
    size_t total = 0;
    for (const PointCloud& cloud : inputs.clouds) total += cloud.size();
    inputs.label = absl::StrCat("ModelNet10 x", inputs.clouds.size(), ", ",
                                total / std::max<size_t>(1, inputs.clouds.size()), " points");
  } else {
    inputs.clouds.push_back(bench::SurfaceCloud(points));
    inputs.label = absl::StrCat("synthetic surface, ", points, " points");
  }
  for (const PointCloud& cloud : inputs.clouds) inputs.pcl_clouds.push_back(ToPcl(cloud));
  return inputs;
}

// Labels and counters shared by every row: items = clouds, so items_per_second is clouds/s.
void Finish(benchmark::State& state, const Inputs& inputs, const std::string& note) {
  size_t points = 0;
  for (const PointCloud& cloud : inputs.clouds) points += cloud.size();
  state.SetItemsProcessed(state.iterations());
  state.counters["points"] =
      static_cast<double>(points) / static_cast<double>(inputs.clouds.size());
  state.counters["threads"] = bench::ProcessThreads();
  state.SetLabel(note.empty() ? inputs.label : absl::StrCat(inputs.label, "; ", note));
}

void ShapeidBench(benchmark::State& state, const std::string& spec, size_t points,
                  const std::string& note) {
  const Inputs& inputs = GetInputs(points);
  if (inputs.clouds.empty()) {
    state.SkipWithError("no ModelNet10 clouds under ../shared/data/modelnet10");
    return;
  }
  auto descriptor = CreateDescriptor(spec);
  if (!descriptor.ok()) {
    state.SkipWithError(std::string(descriptor.status().message()).c_str());
    return;
  }
  std::vector<float> out;
  size_t next = 0;
  for (auto _ : state) {
    const absl::Status status = (*descriptor)->Compute(inputs.clouds[next], &out);
    if (!status.ok()) {
      state.SkipWithError(std::string(status.message()).c_str());
      return;
    }
    benchmark::DoNotOptimize(out.data());
    next = next + 1 == inputs.clouds.size() ? 0 : next + 1;
  }
  Finish(state, inputs, note);
}

// One PCL descriptor of one cloud, from a fresh estimator, as a user describing a new cloud
// would call it. Returns false when PCL produced no descriptor.
using PclMethod = bool (*)(const PclCloud::ConstPtr& cloud);

bool PclEsf(const PclCloud::ConstPtr& cloud) {
  pcl::ESFEstimation<pcl::PointXYZ, pcl::ESFSignature640> esf;
  esf.setInputCloud(cloud);
  pcl::PointCloud<pcl::ESFSignature640> out;
  esf.compute(out);
  benchmark::DoNotOptimize(out.data());
  return out.size() == 1;
}

bool PclEsfBruteForce(const PclCloud::ConstPtr& cloud) {
  pcl::ESFEstimation<pcl::PointXYZ, pcl::ESFSignature640> esf;
  esf.setSearchMethod(std::make_shared<pcl::search::BruteForce<pcl::PointXYZ>>());
  esf.setInputCloud(cloud);
  pcl::PointCloud<pcl::ESFSignature640> out;
  esf.compute(out);
  benchmark::DoNotOptimize(out.data());
  return out.size() == 1;
}

bool PclGasd(const PclCloud::ConstPtr& cloud) {
  pcl::GASDEstimation<pcl::PointXYZ, pcl::GASDSignature512> gasd;
  gasd.setInputCloud(cloud);
  pcl::PointCloud<pcl::GASDSignature512> out;
  gasd.compute(out);
  benchmark::DoNotOptimize(out.data());
  return out.size() == 1;
}

bool PclGasdBruteForce(const PclCloud::ConstPtr& cloud) {
  pcl::GASDEstimation<pcl::PointXYZ, pcl::GASDSignature512> gasd;
  gasd.setSearchMethod(std::make_shared<pcl::search::BruteForce<pcl::PointXYZ>>());
  gasd.setInputCloud(cloud);
  pcl::PointCloud<pcl::GASDSignature512> out;
  gasd.compute(out);
  benchmark::DoNotOptimize(out.data());
  return out.size() == 1;
}

// VFH's input, alone: a kd-tree over the cloud and a normal per point.
bool PclNormals(const PclCloud::ConstPtr& cloud, pcl::search::KdTree<pcl::PointXYZ>::Ptr* tree,
                pcl::PointCloud<pcl::Normal>::Ptr* normals) {
  *tree = std::make_shared<pcl::search::KdTree<pcl::PointXYZ>>();
  *normals = std::make_shared<pcl::PointCloud<pcl::Normal>>();
  pcl::NormalEstimation<pcl::PointXYZ, pcl::Normal> estimation;
  estimation.setInputCloud(cloud);
  estimation.setSearchMethod(*tree);
  estimation.setKSearch(kNormalNeighbors);
  estimation.compute(**normals);
  return (*normals)->size() == cloud->size();
}

bool PclNormalsOnly(const PclCloud::ConstPtr& cloud) {
  pcl::search::KdTree<pcl::PointXYZ>::Ptr tree;
  pcl::PointCloud<pcl::Normal>::Ptr normals;
  const bool ok = PclNormals(cloud, &tree, &normals);
  benchmark::DoNotOptimize(normals->data());
  return ok;
}

// Normals then VFH, sharing the kd-tree as PCL's VFH example does (VFH finds the tree already
// built over its input and does not rebuild it).
bool PclVfhWithNormals(const PclCloud::ConstPtr& cloud) {
  pcl::search::KdTree<pcl::PointXYZ>::Ptr tree;
  pcl::PointCloud<pcl::Normal>::Ptr normals;
  if (!PclNormals(cloud, &tree, &normals)) return false;
  pcl::VFHEstimation<pcl::PointXYZ, pcl::Normal, pcl::VFHSignature308> vfh;
  vfh.setInputCloud(cloud);
  vfh.setInputNormals(normals);
  vfh.setSearchMethod(tree);
  pcl::PointCloud<pcl::VFHSignature308> out;
  vfh.compute(out);
  benchmark::DoNotOptimize(out.data());
  return out.size() == 1;
}

void PclBench(benchmark::State& state, PclMethod method, size_t points, const std::string& note) {
  const Inputs& inputs = GetInputs(points);
  if (inputs.clouds.empty()) {
    state.SkipWithError("no ModelNet10 clouds under ../shared/data/modelnet10");
    return;
  }
  size_t next = 0;
  for (auto _ : state) {
    if (!method(inputs.pcl_clouds[next])) {
      state.SkipWithError("PCL computed no descriptor (see its error above)");
      return;
    }
    next = next + 1 == inputs.pcl_clouds.size() ? 0 : next + 1;
  }
  Finish(state, inputs, note);
}

std::string InputName(size_t points) {
  return points == kModelNet10 ? "modelnet10" : absl::StrCat(points);
}

void RegisterAll() {
  struct ShapeidRow {
    const char* name;
    const char* spec;
    const char* note;
  };
  const ShapeidRow shapeid_rows[] = {
      {"shapeid_rphsd", "rphsd", "complete, cubic27, M=100"},
      {"shapeid_comsd", "comsd", ""},
      {"shapeid_cnsd", "cnsd", "subsamples to 8000 points"},
      {"shapeid_dfsd", "dfsd", "the default descriptor"},
  };
  struct PclRow {
    const char* name;
    PclMethod method;
    const char* note;
  };
  const PclRow pcl_rows[] = {
      {"pcl_esf", PclEsf, "builds a kd-tree"},
      {"pcl_esf_bruteforce", PclEsfBruteForce, "no kd-tree"},
      {"pcl_gasd", PclGasd, "builds a kd-tree"},
      {"pcl_gasd_bruteforce", PclGasdBruteForce, "no kd-tree"},
      {"pcl_normals_k10", PclNormalsOnly, "kd-tree + normals, k=10"},
      {"pcl_vfh_with_normals_k10", PclVfhWithNormals, "kd-tree + normals k=10 + VFH"},
  };
  for (size_t points : kInputSizes) {
    const std::string input = InputName(points);
    for (const ShapeidRow& row : shapeid_rows) {
      benchmark::RegisterBenchmark(absl::StrCat(row.name, "/", input).c_str(), ShapeidBench,
                                   std::string(row.spec), points, std::string(row.note))
          ->Unit(benchmark::kMicrosecond);
    }
    for (const PclRow& row : pcl_rows) {
      benchmark::RegisterBenchmark(absl::StrCat(row.name, "/", input).c_str(), PclBench, row.method,
                                   points, std::string(row.note))
          ->Unit(benchmark::kMicrosecond);
    }
  }
}

}  // namespace
}  // namespace shapeid

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  shapeid::RegisterAll();
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
