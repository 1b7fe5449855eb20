// Issue 29's speed goal: a 300,000-point frame segmented and all its objects classified in
// under 100 ms on one core. RecognizeScene (core/scene/scene_recognition.h) on ray-cast
// tabletop frames (core/testing/tabletop_frames.h, 640 x 480, 3-10 objects), one thread,
// with the segmentation and the classification reported apart (bench/tabletop_gallery.h: a
// timing gallery, not an accuracy figure). PCL's chain beside the whole call:
// bench/pcl/scene_segmentation_bench. Figures: docs/performance.md.
//   build/release/bench/scene_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only

#include <map>
#include <memory>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "bench/tabletop_gallery.h"
#include "benchmark/benchmark.h"
#include "core/gallery/gallery.h"
#include "core/scene/scene_recognition.h"
#include "core/testing/tabletop_frames.h"

namespace shapeid {
namespace {

using testing_frames::MakeTabletopFrame;
using testing_frames::TabletopFrame;
using testing_frames::TabletopFrameOptions;

void BM_RecognizeScene(benchmark::State& state, const std::string& spec) {
  static std::map<std::string, std::shared_ptr<Gallery>>& galleries =
      *new std::map<std::string, std::shared_ptr<Gallery>>();  // built once per spec
  std::shared_ptr<Gallery>& gallery = galleries[spec];
  if (gallery == nullptr) gallery = bench::TabletopPrimitivesGallery(spec);
  const int objects = static_cast<int>(state.range(0));
  TabletopFrameOptions frame_options;
  frame_options.objects = objects;
  frame_options.seed = 100 + static_cast<uint64_t>(objects);
  const TabletopFrame frame = MakeTabletopFrame(frame_options);
  SceneRecognitionOptions options;
  options.segmentation.max_planes = 2;  // the table and the floor
  const auto snapshot = gallery->Snapshot();
  absl::Duration segment, classify;
  size_t found = 0, object_points = 0;
  for (auto _ : state) {
    absl::StatusOr<SceneRecognition> scene = RecognizeScene(*snapshot, frame.cloud, options);
    if (!scene.ok()) {
      state.SkipWithError(std::string(scene.status().message()).c_str());
      return;
    }
    segment += scene->segment_time;
    classify += scene->classify_time;
    found = scene->objects.size();
    object_points = 0;
    for (const RecognizedObject& object : scene->objects) object_points += object.indices.size();
  }
  const double n = static_cast<double>(state.iterations());
  state.counters["segment_ms"] = absl::ToDoubleMilliseconds(segment) / n;
  state.counters["classify_ms"] = absl::ToDoubleMilliseconds(classify) / n;
  state.counters["objects_found"] = static_cast<double>(found);
  state.counters["object_points"] = static_cast<double>(object_points);
  state.counters["points"] = static_cast<double>(frame.cloud.size());
  state.SetLabel(absl::StrCat(spec, ", ", frame.objects.size(), " objects placed"));
}
BENCHMARK_CAPTURE(BM_RecognizeScene, dfsd, std::string("dfsd"))
    ->Arg(3)
    ->Arg(5)
    ->Arg(10)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_CAPTURE(BM_RecognizeScene, rphsd, std::string("rphsd"))
    ->Arg(3)
    ->Arg(5)
    ->Arg(10)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace
}  // namespace shapeid

BENCHMARK_MAIN();
