// Issue 29: shapeid's SegmentScene against PCL's tabletop chain, on the same synthetic
// 640 x 480 depth frames (about 295,000 finite points: a table, a floor behind it, 3 to 10
// objects, separated or touching; core/testing/tabletop_frames.h), single thread, in one run,
// then whether the two found the same planes and clusters and the objects that are there.
// Build and run: bench/pcl/README.md.
//
// What is timed, per frame, from the organized frame with its NaN pixels to clusters given
// as indices into that frame:
// - shapeid: SegmentScene (it skips NaNs itself).
// - PCL, as its tutorials chain it: removeNaNFromPointCloud; per plane SACSegmentation
//   (SACMODEL_PLANE, SAC_RANSAC, optimized coefficients) and ExtractIndices (negative) for the
//   rest; EuclideanClusterExtraction with a fresh search::KdTree. Keeping each remaining
//   point's frame index (one pass per plane) is timed too: shapeid returns frame indices.
// Both use the same settings (kOptions), including the rule that stops plane removal: a
// plane must hold min_plane_share of the finite points.
// The `clusters_only` rows time the clustering alone, on the points PCL's planes left. The
// `recognize_scene` and `chain_then_classify` rows add classifying every object found against
// one gallery: issue 29's whole speed goal (a frame in, every object labeled).
// Not timed: making the frames and converting them to pcl::PointCloud (once, at start-up).

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "bench/host_info.h"
#include "bench/tabletop_gallery.h"
#include "benchmark/benchmark.h"
#include "core/point_cloud.h"
#include "core/scene/scene_recognition.h"
#include "core/scene/scene_segmentation.h"
#include "core/testing/tabletop_frames.h"
#include "pcl/ModelCoefficients.h"
#include "pcl/PointIndices.h"
#include "pcl/filters/extract_indices.h"
#include "pcl/filters/filter.h"
#include "pcl/point_cloud.h"
#include "pcl/point_types.h"
#include "pcl/sample_consensus/method_types.h"
#include "pcl/sample_consensus/model_types.h"
#include "pcl/search/kdtree.h"
#include "pcl/segmentation/extract_clusters.h"
#include "pcl/segmentation/sac_segmentation.h"

namespace shapeid {
namespace {

namespace tf = testing_frames;
using PclCloud = pcl::PointCloud<pcl::PointXYZ>;
using Clusters = std::vector<std::vector<uint32_t>>;
constexpr double kPi = 3.14159265358979323846;

// PCL's tutorial settings, and SegmentScene's equivalents: a table and a floor.
SceneSegmentationOptions Options() {
  SceneSegmentationOptions o;
  o.max_planes = 2;
  o.plane_distance = 0.01f;
  o.plane_iterations = 1000;
  o.cluster_tolerance = 0.02f;
  o.min_cluster_points = 100;
  o.max_cluster_points = 1'000'000;
  return o;
}
const SceneSegmentationOptions kOptions = Options();

struct Frame {
  std::string name;
  tf::TabletopFrame frame;
  PclCloud::Ptr pcl;                 // the same points, organized, NaNs kept
  PointCloud rest;                   // the points PCL's planes left, for the clusters_only rows
  PclCloud::Ptr pcl_rest;            // the same
  std::vector<uint32_t> rest_index;  // their frame indices
};

struct FrameSet {
  std::string name;
  std::vector<Frame> frames;
};

std::vector<FrameSet>& Sets() {
  static auto* const sets = new std::vector<FrameSet>;
  return *sets;
}

PclCloud::Ptr ToPcl(const tf::TabletopFrame& frame) {
  auto out = std::make_shared<PclCloud>();
  out->resize(frame.cloud.size());
  for (size_t i = 0; i < frame.cloud.size(); ++i) {
    const auto p = frame.cloud.point(i);
    (*out)[i] = pcl::PointXYZ(p.x(), p.y(), p.z());
  }
  out->width = static_cast<uint32_t>(frame.width);
  out->height = static_cast<uint32_t>(frame.height);
  out->is_dense = false;
  return out;
}

struct PclResult {
  std::vector<Eigen::Vector4f> planes;  // unit normal, d >= 0 (as SegmentScene's)
  std::vector<size_t> plane_points;
  Clusters clusters;              // frame indices
  std::vector<uint32_t> rest;     // frame indices of the points left for clustering
  double seconds[3] = {0, 0, 0};  // NaN removal, planes, clusters
};

// PCL's clusters of the points its planes left, as indices into them. `sorted`: the kd-tree's
// default, radius-search results sorted by distance, which clustering does not need.
std::vector<pcl::PointIndices> PclClusters(const PclCloud::ConstPtr& cloud, bool sorted) {
  std::vector<pcl::PointIndices> found;
  pcl::EuclideanClusterExtraction<pcl::PointXYZ> clustering;
  clustering.setClusterTolerance(kOptions.cluster_tolerance);
  clustering.setMinClusterSize(static_cast<pcl::uindex_t>(kOptions.min_cluster_points));
  clustering.setMaxClusterSize(static_cast<pcl::uindex_t>(kOptions.max_cluster_points));
  clustering.setSearchMethod(std::make_shared<pcl::search::KdTree<pcl::PointXYZ>>(sorted));
  clustering.setInputCloud(cloud);
  clustering.extract(found);
  return found;
}

// PCL's chain on one organized frame. The clusters' indices are mapped back to the frame.
PclResult PclChain(const PclCloud::ConstPtr& frame, bool keep_rest) {
  using Clock = std::chrono::steady_clock;
  PclResult result;
  const auto t0 = Clock::now();
  auto cloud = std::make_shared<PclCloud>();
  pcl::Indices kept;  // frame index of each point of `cloud`
  pcl::removeNaNFromPointCloud(*frame, *cloud, kept);
  const auto t1 = Clock::now();

  const size_t min_plane_points =
      std::max<size_t>(3, static_cast<size_t>(std::ceil(kOptions.min_plane_share * cloud->size())));
  pcl::SACSegmentation<pcl::PointXYZ> sac;
  sac.setOptimizeCoefficients(true);
  sac.setModelType(pcl::SACMODEL_PLANE);
  sac.setMethodType(pcl::SAC_RANSAC);
  sac.setMaxIterations(kOptions.plane_iterations);
  sac.setDistanceThreshold(kOptions.plane_distance);
  pcl::ExtractIndices<pcl::PointXYZ> extract;
  auto inliers = std::make_shared<pcl::PointIndices>();
  pcl::ModelCoefficients coefficients;
  std::vector<char> on_plane;
  for (int p = 0; p < kOptions.max_planes && cloud->size() >= min_plane_points; ++p) {
    sac.setInputCloud(cloud);
    sac.segment(*inliers, coefficients);
    if (inliers->indices.size() < min_plane_points) break;
    Eigen::Vector4f plane(coefficients.values[0], coefficients.values[1], coefficients.values[2],
                          coefficients.values[3]);
    plane /= plane.head<3>().norm();
    result.planes.push_back(plane[3] < 0 ? Eigen::Vector4f(-plane) : plane);
    result.plane_points.push_back(inliers->indices.size());
    auto rest = std::make_shared<PclCloud>();
    extract.setInputCloud(cloud);
    extract.setIndices(inliers);
    extract.setNegative(true);
    extract.filter(*rest);
    // ExtractIndices keeps the other points in their order.
    on_plane.assign(cloud->size(), 0);
    for (const auto i : inliers->indices) on_plane[static_cast<size_t>(i)] = 1;
    size_t n = 0;
    for (size_t i = 0; i < kept.size(); ++i) {
      if (!on_plane[i]) kept[n++] = kept[i];
    }
    kept.resize(n);
    cloud = rest;
  }
  const auto t2 = Clock::now();

  const std::vector<pcl::PointIndices> found = PclClusters(cloud, true);
  result.clusters.reserve(found.size());
  for (const pcl::PointIndices& c : found) {
    std::vector<uint32_t>& out = result.clusters.emplace_back();
    out.reserve(c.indices.size());
    for (const auto i : c.indices)
      out.push_back(static_cast<uint32_t>(kept[static_cast<size_t>(i)]));
  }
  const auto t3 = Clock::now();
  result.seconds[0] = std::chrono::duration<double>(t1 - t0).count();
  result.seconds[1] = std::chrono::duration<double>(t2 - t1).count();
  result.seconds[2] = std::chrono::duration<double>(t3 - t2).count();
  if (keep_rest) result.rest.assign(kept.begin(), kept.end());
  return result;
}

// Shared counters: per_frame is the time of one frame (an iteration segments every frame of
// the set), points the mean points segmented per frame.
void Finish(benchmark::State& state, const FrameSet& set, size_t points) {
  const double frames = static_cast<double>(set.frames.size());
  state.SetItemsProcessed(state.iterations() * static_cast<int64_t>(set.frames.size()));
  state.counters["per_frame"] = benchmark::Counter(
      frames, benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
  state.counters["points"] = static_cast<double>(points) / frames;
  state.counters["threads"] = bench::ProcessThreads();
  state.SetLabel(absl::StrCat(set.frames.size(), " frames, ", set.name));
}

void BM_Shapeid(benchmark::State& state, const FrameSet* set) {
  size_t points = 0;
  for (const Frame& f : set->frames) points += f.frame.cloud.size();
  for (auto _ : state) {
    for (const Frame& f : set->frames) {
      absl::StatusOr<SceneSegmentation> s = SegmentScene(f.frame.cloud, kOptions);
      if (!s.ok()) {
        state.SkipWithError(std::string(s.status().message()).c_str());
        return;
      }
      benchmark::DoNotOptimize(s->clusters.data());
    }
  }
  Finish(state, *set, points);
}

void BM_Pcl(benchmark::State& state, const FrameSet* set) {
  size_t points = 0;
  for (const Frame& f : set->frames) points += f.frame.cloud.size();
  double stage[3] = {0, 0, 0};
  for (auto _ : state) {
    for (const Frame& f : set->frames) {
      const PclResult r = PclChain(f.pcl, false);
      benchmark::DoNotOptimize(r.clusters.data());
      for (int k = 0; k < 3; ++k) stage[k] += r.seconds[k];
    }
  }
  Finish(state, *set, points);
  // Where PCL's time goes, seconds per frame.
  const double frames = static_cast<double>(state.iterations()) * set->frames.size();
  state.counters["nan_s"] = stage[0] / frames;
  state.counters["planes_s"] = stage[1] / frames;
  state.counters["clusters_s"] = stage[2] / frames;
}

// The whole of issue 29's speed goal, a frame segmented and every object classified, against
// the same gallery (bench/tabletop_gallery.h, DFSD): shapeid's RecognizeScene, and PCL's chain
// followed by the same classification of PCL's clusters (ClassifySceneObjects, turned by
// PCL's first plane as RecognizeScene turns by its own).
const GallerySnapshot& TimingGallery() {
  static const std::shared_ptr<const GallerySnapshot> snapshot =
      bench::TabletopPrimitivesGallery("dfsd")->Snapshot();
  return *snapshot;
}

SceneRecognitionOptions RecognitionOptions() {
  SceneRecognitionOptions options;
  options.segmentation = kOptions;
  return options;
}

void RecognitionCounters(benchmark::State& state, const FrameSet& set, double classify_seconds,
                         size_t objects) {
  const double frames = static_cast<double>(state.iterations()) * set.frames.size();
  state.counters["classify_ms"] = 1e3 * classify_seconds / frames;
  state.counters["objects"] = static_cast<double>(objects) / set.frames.size();
}

// Times `recognize` (frame -> SceneRecognition) over every frame of the set.
template <typename Recognize>
void TimeRecognition(benchmark::State& state, const FrameSet& set, Recognize recognize) {
  size_t points = 0;
  for (const Frame& f : set.frames) points += f.frame.cloud.size();
  double classify = 0;
  size_t objects = 0;
  for (auto _ : state) {
    objects = 0;
    for (const Frame& f : set.frames) {
      absl::StatusOr<SceneRecognition> scene = recognize(f);
      if (!scene.ok()) {
        state.SkipWithError(std::string(scene.status().message()).c_str());
        return;
      }
      classify += absl::ToDoubleSeconds(scene->classify_time);
      objects += scene->objects.size();
    }
  }
  Finish(state, set, points);
  RecognitionCounters(state, set, classify, objects);
}

void BM_ShapeidRecognize(benchmark::State& state, const FrameSet* set) {
  const GallerySnapshot& gallery = TimingGallery();
  const SceneRecognitionOptions options = RecognitionOptions();
  TimeRecognition(state, *set,
                  [&](const Frame& f) { return RecognizeScene(gallery, f.frame.cloud, options); });
}

void BM_PclChainThenClassify(benchmark::State& state, const FrameSet* set) {
  const GallerySnapshot& gallery = TimingGallery();
  const SceneRecognitionOptions options = RecognitionOptions();
  TimeRecognition(state, *set, [&](const Frame& f) {
    PclResult r = PclChain(f.pcl, false);
    SceneSegmentation segmentation;
    for (size_t p = 0; p < r.planes.size(); ++p) {
      segmentation.planes.push_back({r.planes[p], r.plane_points[p]});
    }
    segmentation.clusters = std::move(r.clusters);
    return ClassifySceneObjects(gallery, f.frame.cloud, std::move(segmentation), options);
  });
}

// Clustering alone, on the points PCL's planes left (dense, no NaN, no plane to find).
void BM_ShapeidClustersOnly(benchmark::State& state, const FrameSet* set) {
  SceneSegmentationOptions options = kOptions;
  options.max_planes = 0;
  size_t points = 0;
  for (const Frame& f : set->frames) points += f.rest.size();
  for (auto _ : state) {
    for (const Frame& f : set->frames) {
      absl::StatusOr<SceneSegmentation> s = SegmentScene(f.rest, options);
      if (!s.ok()) {
        state.SkipWithError(std::string(s.status().message()).c_str());
        return;
      }
      benchmark::DoNotOptimize(s->clusters.data());
    }
  }
  Finish(state, *set, points);
}

void BM_PclClustersOnly(benchmark::State& state, const FrameSet* set, bool sorted) {
  size_t points = 0;
  for (const Frame& f : set->frames) points += f.rest.size();
  for (auto _ : state) {
    for (const Frame& f : set->frames) {
      const std::vector<pcl::PointIndices> found = PclClusters(f.pcl_rest, sorted);
      benchmark::DoNotOptimize(found.data());
    }
  }
  Finish(state, *set, points);
}

// ---- Start-up: the frames, and checks that they are what the figures claim. ----

[[noreturn]] void Fail(const std::string& what) {
  std::fprintf(stderr, "scene_segmentation_bench: bad frame: %s\n", what.c_str());
  std::exit(1);
}

void Check(const Frame& f, int objects) {
  const tf::TabletopFrame& t = f.frame;
  const auto fail = [&](const std::string& what) { Fail(absl::StrCat(f.name, ": ", what)); };
  if (t.cloud.size() != 640u * 480u || t.width * t.height != t.cloud.size()) {
    fail(absl::StrCat(t.cloud.size(), " points, not 640 x 480"));
  }
  if (t.truth.size() != t.cloud.size()) fail("one truth id per point");
  size_t nan = 0;
  for (size_t i = 0; i < t.cloud.size(); ++i) {
    const bool finite = t.cloud.point(i).allFinite();
    nan += finite ? 0 : 1;
    if (finite != (t.truth[i] != tf::kNothing))
      fail(absl::StrCat("point ", i, ": NaN iff nothing"));
  }
  const size_t finite = t.cloud.size() - nan;
  if (finite < 280'000 || finite > 307'200) fail(absl::StrCat(finite, " finite points"));
  if (t.count(tf::kTable) < 100'000 || t.count(tf::kFloor) < 50'000) {
    fail(absl::StrCat(t.count(tf::kTable), " table and ", t.count(tf::kFloor), " floor points"));
  }
  if (t.objects.size() != static_cast<size_t>(objects)) {
    fail(absl::StrCat(t.objects.size(), " objects placed of ", objects));
  }
  size_t on_objects = 0;
  for (size_t k = 0; k < t.objects.size(); ++k) {
    if (t.objects[k].points != t.count(static_cast<int32_t>(k))) fail("object point counts");
    on_objects += t.objects[k].points;
  }
  if (finite != t.count(tf::kTable) + t.count(tf::kFloor) + on_objects) {
    fail("truth ids other than table, floor, nothing and the objects");
  }
}

void MakeFrames() {
  const int kObjects[] = {3, 5, 8, 10};
  for (const bool touching : {false, true}) {
    FrameSet& set = Sets().emplace_back();
    set.name = touching ? "touching" : "separated";
    for (size_t i = 0; i < std::size(kObjects); ++i) {
      tf::TabletopFrameOptions options;
      options.objects = kObjects[i];
      options.touching = touching;
      options.seed = 100 + i + (touching ? 10 : 0);
      Frame& f = set.frames.emplace_back();
      f.name = absl::StrCat(set.name, "/", kObjects[i], "/seed", options.seed);
      f.frame = tf::MakeTabletopFrame(options);
      Check(f, kObjects[i]);
      f.pcl = ToPcl(f.frame);
      f.rest_index = PclChain(f.pcl, true).rest;
      f.pcl_rest = std::make_shared<PclCloud>();
      for (const uint32_t index : f.rest_index) {
        f.rest.Add(f.frame.cloud.point(index));
        f.pcl_rest->push_back((*f.pcl)[index]);
      }
    }
  }
}

// ---- After the timings: do the two agree, with each other and with the truth? ----

std::string Fixed(double value, int decimals) {
  char text[32];
  std::snprintf(text, sizeof text, "%.*f", decimals, value);
  return text;
}

double Iou(const std::vector<uint32_t>& a, const std::vector<uint32_t>& b) {
  std::vector<uint32_t> common;
  std::set_intersection(a.begin(), a.end(), b.begin(), b.end(), std::back_inserter(common));
  return static_cast<double>(common.size()) /
         static_cast<double>(a.size() + b.size() - common.size());
}

// Clusters of `a` identical to one of `b` (both with ascending indices), and the lowest IoU
// of the others' best match in `b` (1 when all are identical).
std::pair<int, double> Match(const Clusters& a, const Clusters& b) {
  int same = 0;
  double worst = 1;
  for (const auto& c : a) {
    double best = 0;
    for (const auto& d : b) best = std::max(best, c == d ? 2.0 : Iou(c, d));
    if (best > 1) {
      ++same;
    } else {
      worst = std::min(worst, best);
    }
  }
  return {same, worst};
}

Clusters Sorted(Clusters clusters) {
  for (auto& c : clusters) std::sort(c.begin(), c.end());
  return clusters;
}

// Each plane's angle to the true plane (table or floor) nearest to it, degrees.
std::string PlaneErrors(const tf::TabletopFrame& t, const std::vector<Eigen::Vector4f>& planes) {
  std::string out;
  for (const Eigen::Vector4f& plane : planes) {
    const bool table =
        std::abs(plane[3] - t.table_plane[3]) < std::abs(plane[3] - t.floor_plane[3]);
    const Eigen::Vector4f& truth = table ? t.table_plane : t.floor_plane;
    const double cosine = std::min(1.0f, std::abs(plane.head<3>().dot(truth.head<3>())));
    absl::StrAppend(&out, out.empty() ? "" : ",", table ? "t" : "f",
                    Fixed(std::acos(cosine) * 180 / kPi, 2));
  }
  return out;
}

void PrintAgreement() {
  std::printf(
      "\nAgreement (outside the timings). s = shapeid SegmentScene, p = PCL's chain.\n"
      "plane err: each plane's normal against the true table (t) or floor (f), degrees; "
      "s~p: the two libraries' normals of plane 1 and 2, degrees; plane pts: points removed "
      "with the planes; same: clusters with identical index sets (frame indices); worst: the "
      "lowest best-match IoU of a shapeid cluster PCL has not identically; rest same: the same "
      "on identical input (the points PCL's planes left), i.e. clustering alone; visible: "
      "objects with >= 100 points; found: >= 50 %% of an object's points in one cluster; "
      "alone: that cluster is >= 50 %% this object; other: clusters mostly no one object.\n\n");
  std::printf("%-24s %-14s %-14s %-11s %-13s %-7s %-5s %-6s %-10s %-7s %-9s %-9s %-9s\n", "frame",
              "plane err s", "plane err p", "s~p", "plane pts s/p", "clus", "same", "worst",
              "rest same", "visible", "found", "alone", "other");
  for (const FrameSet& set : Sets()) {
    for (const Frame& f : set.frames) {
      const absl::StatusOr<SceneSegmentation> s = SegmentScene(f.frame.cloud, kOptions);
      if (!s.ok()) Fail(std::string(s.status().message()));
      const PclResult p = PclChain(f.pcl, false);
      std::vector<Eigen::Vector4f> s_planes;
      size_t s_plane = 0, p_plane = 0;
      for (const ScenePlane& plane : s->planes) {
        s_planes.push_back(plane.coefficients);
        s_plane += plane.points;
      }
      for (const size_t n : p.plane_points) p_plane += n;
      std::string between;
      for (size_t i = 0; i < std::min(s_planes.size(), p.planes.size()); ++i) {
        const double cosine =
            std::min(1.0f, std::abs(s_planes[i].head<3>().dot(p.planes[i].head<3>())));
        absl::StrAppend(&between, i ? "," : "", Fixed(std::acos(cosine) * 180 / kPi, 2));
      }
      const Clusters pcl_clusters = Sorted(p.clusters);
      const auto [same, worst] = Match(s->clusters, pcl_clusters);
      // Clustering alone, on the same input.
      SceneSegmentationOptions rest_options = kOptions;
      rest_options.max_planes = 0;
      const absl::StatusOr<SceneSegmentation> s_rest = SegmentScene(f.rest, rest_options);
      if (!s_rest.ok()) Fail(std::string(s_rest.status().message()));
      Clusters p_rest;
      for (const pcl::PointIndices& c : PclClusters(f.pcl_rest, true)) {
        p_rest.emplace_back(c.indices.begin(), c.indices.end());
      }
      const int rest_same = Match(s_rest->clusters, Sorted(p_rest)).first;
      const tf::ClusterScore ts = tf::ScoreClusters(f.frame, s->clusters,
                                                    kOptions.min_cluster_points),
                             tp = tf::ScoreClusters(f.frame, p.clusters,
                                                    kOptions.min_cluster_points);
      const auto pair = [](auto a, auto b) { return absl::StrCat(a, "/", b); };
      std::printf("%-24s %-14s %-14s %-11s %-13s %-7s %-5d %-6s %-10s %-7d %-9s %-9s %-9s\n",
                  f.name.c_str(), PlaneErrors(f.frame, s_planes).c_str(),
                  PlaneErrors(f.frame, p.planes).c_str(), between.c_str(),
                  pair(s_plane, p_plane).c_str(),
                  pair(s->clusters.size(), p.clusters.size()).c_str(), same,
                  same == static_cast<int>(s->clusters.size()) ? "-" : Fixed(worst, 3).c_str(),
                  pair(rest_same, pair(s_rest->clusters.size(), p_rest.size())).c_str(), ts.visible,
                  pair(ts.found, tp.found).c_str(), pair(ts.alone, tp.alone).c_str(),
                  pair(ts.other, tp.other).c_str());
    }
  }
}

}  // namespace
}  // namespace shapeid

int main(int argc, char** argv) {
  using namespace shapeid;
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  MakeFrames();
  for (const FrameSet& set : Sets()) {
    benchmark::RegisterBenchmark(("shapeid_segment_scene/" + set.name).c_str(), BM_Shapeid, &set)
        ->Threads(1)
        ->Unit(benchmark::kMillisecond);
    benchmark::RegisterBenchmark(("pcl_chain/" + set.name).c_str(), BM_Pcl, &set)
        ->Unit(benchmark::kMillisecond);
  }
  for (const FrameSet& set : Sets()) {
    benchmark::RegisterBenchmark(("shapeid_recognize_scene/" + set.name).c_str(),
                                 BM_ShapeidRecognize, &set)
        ->Unit(benchmark::kMillisecond);
    benchmark::RegisterBenchmark(("pcl_chain_then_classify/" + set.name).c_str(),
                                 BM_PclChainThenClassify, &set)
        ->Unit(benchmark::kMillisecond);
  }
  for (const FrameSet& set : Sets()) {
    benchmark::RegisterBenchmark(("shapeid_clusters_only/" + set.name).c_str(),
                                 BM_ShapeidClustersOnly, &set)
        ->Unit(benchmark::kMillisecond);
    benchmark::RegisterBenchmark(("pcl_clusters_only/" + set.name).c_str(), BM_PclClustersOnly,
                                 &set, true)
        ->Unit(benchmark::kMillisecond);
    benchmark::RegisterBenchmark(("pcl_clusters_only_unsorted_kdtree/" + set.name).c_str(),
                                 BM_PclClustersOnly, &set, false)
        ->Unit(benchmark::kMillisecond);
  }
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  PrintAgreement();
  return 0;
}
