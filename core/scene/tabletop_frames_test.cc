// The synthetic frames of core/testing/tabletop_frames.h (used by the scene tests and the PCL
// bench), and SegmentScene on them: a small, fast slice of bench/pcl/scene_segmentation_bench.

#include "core/testing/tabletop_frames.h"

#include <cmath>
#include <cstring>
#include <vector>

#include "core/scene/scene_segmentation.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using testing_frames::MakeTabletopFrame;
using testing_frames::TabletopFrame;
using testing_frames::TabletopFrameOptions;

TEST(TabletopFramesTest, OnePointPerPixelWithItsTruth) {
  TabletopFrameOptions options;
  options.width = 320;
  options.height = 240;
  const TabletopFrame frame = MakeTabletopFrame(options);
  ASSERT_EQ(frame.cloud.size(), frame.width * frame.height);
  ASSERT_EQ(frame.truth.size(), frame.cloud.size());
  size_t object_points = 0;
  for (size_t i = 0; i < frame.cloud.size(); ++i) {
    // NaN exactly where the ray met nothing.
    EXPECT_EQ(!frame.cloud.point(i).allFinite(), frame.truth[i] == testing_frames::kNothing);
    if (frame.truth[i] == testing_frames::kTable) {  // on the table plane, within the noise
      const Eigen::Vector4f& t = frame.table_plane;
      EXPECT_LT(std::fabs(t.head<3>().dot(frame.cloud.point(i)) + t[3]), 0.01f);
    }
    if (frame.truth[i] >= 0) ++object_points;
  }
  size_t listed = 0;
  for (const auto& object : frame.objects) listed += object.points;
  EXPECT_EQ(listed, object_points);
  EXPECT_GT(frame.count(testing_frames::kTable), frame.cloud.size() / 3);
  EXPECT_EQ(frame.objects.size(), static_cast<size_t>(options.objects));
  // Seeded: the same options, the same bits (NaN included, so bytes are compared).
  const TabletopFrame again = MakeTabletopFrame(options);
  ASSERT_EQ(again.cloud.size(), frame.cloud.size());
  EXPECT_EQ(std::memcmp(again.cloud.data(), frame.cloud.data(), 12 * frame.cloud.size()), 0);
}

// Every separated object with 100 points or more is found: one cluster holds at least half
// of its points and is mostly this object (the "found"), on frames of three seeds.
TEST(TabletopFramesTest, SegmentSceneFindsEverySeparatedObject) {
  for (const uint64_t seed : {21u, 22u, 23u}) {
    TabletopFrameOptions options;
    options.width = 320;
    options.height = 240;
    options.objects = 6;
    options.seed = seed;
    const TabletopFrame frame = MakeTabletopFrame(options);
    SceneSegmentationOptions segmentation;
    segmentation.max_planes = 2;
    segmentation.min_cluster_points = 50;
    const absl::StatusOr<SceneSegmentation> s = SegmentScene(frame.cloud, segmentation);
    ASSERT_TRUE(s.ok()) << s.status();
    ASSERT_EQ(s->planes.size(), 2u);
    EXPECT_GT(std::fabs(s->planes[0].coefficients.head<3>().dot(frame.table_plane.head<3>())),
              std::cos(0.1 * M_PI / 180));
    const testing_frames::ClusterScore score =
        testing_frames::ScoreClusters(frame, s->clusters, /*min_points=*/100);
    EXPECT_GT(score.visible, 0) << "seed " << seed;
    EXPECT_EQ(score.alone, score.visible) << "seed " << seed;  // each found, and alone
  }
}

}  // namespace
}  // namespace shapeid
