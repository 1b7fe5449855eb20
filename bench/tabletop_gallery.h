#ifndef SHAPEID_BENCH_TABLETOP_GALLERY_H_
#define SHAPEID_BENCH_TABLETOP_GALLERY_H_

// A gallery for timing scene recognition on core/testing/tabletop_frames.h's frames: each
// object of 12 frames seeded 1000 on (other seeds than the benches' frames), labeled with its
// kind. It comes from the same ray-caster as the frames, so it serves timings, never accuracy.

#include <cstdint>
#include <cstdlib>
#include <memory>
#include <string>

#include "core/gallery/gallery.h"
#include "core/testing/tabletop_frames.h"

namespace shapeid::bench {

inline constexpr const char* kTabletopKindNames[] = {"sphere", "box", "cylinder"};

inline std::shared_ptr<Gallery> TabletopPrimitivesGallery(const std::string& spec) {
  GalleryOptions options;
  options.descriptor_spec = spec;
  std::shared_ptr<Gallery> gallery = Gallery::Create("primitives", options, {}, nullptr).value();
  TrainBatch batch = gallery->NewBatch();
  uint64_t id = 1;
  for (uint64_t seed = 1000; seed < 1012; ++seed) {
    testing_frames::TabletopFrameOptions frame_options;
    frame_options.seed = seed;
    frame_options.objects = 6;
    const testing_frames::TabletopFrame frame = testing_frames::MakeTabletopFrame(frame_options);
    for (size_t o = 0; o < frame.objects.size(); ++o) {
      if (frame.objects[o].points < 200) continue;
      PointCloud cloud;
      for (size_t i = 0; i < frame.cloud.size(); ++i) {
        if (frame.truth[i] == static_cast<int32_t>(o)) cloud.Add(frame.cloud.point(i));
      }
      const std::string label = kTabletopKindNames[static_cast<int>(frame.objects[o].kind)];
      if (!batch.AddSample(id++, label, cloud).ok()) std::abort();
    }
  }
  if (!batch.Commit().ok()) std::abort();
  return gallery;
}

}  // namespace shapeid::bench

#endif  // SHAPEID_BENCH_TABLETOP_GALLERY_H_
