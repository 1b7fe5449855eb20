#include "core/views/augment.h"

#include <cstring>

#include "core/views/test_surfaces.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;

bool SameBits(const PointCloud& a, const PointCloud& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * 3 * sizeof(float)) == 0;
}

TEST(AugmentTest, OffGivesNoViews) {
  const PointCloud box = test_surfaces::BoxSurface({0, 0, 0}, {1, 0.5, 2}, 2000, 1);
  const AugmentOptions off;
  EXPECT_FALSE(off.enabled());
  EXPECT_EQ(AugmentOptionsToString(off), "off");
  const auto views = AugmentedViews(box, off, 1);
  ASSERT_TRUE(views.ok());
  EXPECT_TRUE(views->empty());
}

TEST(AugmentTest, ViewsAreSeededPerCloudAndDeterministic) {
  const PointCloud box = test_surfaces::BoxSurface({0, 0, 0}, {1, 0.5, 2}, 2000, 1);
  AugmentOptions options;
  options.views = 6;
  const auto a = AugmentedViews(box, options, 42);
  const auto b = AugmentedViews(box, options, 42);
  const auto other_cloud = AugmentedViews(box, options, 43);
  ASSERT_TRUE(a.ok() && b.ok() && other_cloud.ok());
  ASSERT_EQ(a->size(), 6u);
  for (size_t i = 0; i < a->size(); ++i) {
    EXPECT_TRUE(SameBits((*a)[i], (*b)[i])) << i;
    EXPECT_FALSE(SameBits((*a)[i], (*other_cloud)[i])) << i;
    EXPECT_GE((*a)[i].size(), 300u);
    EXPECT_LE((*a)[i].size(), 500u);
    if (i > 0) {
      EXPECT_FALSE(SameBits((*a)[i], (*a)[i - 1])) << "views " << i - 1 << ", " << i;
    }
  }
  // The gallery seed changes every view too.
  options.seed = 2;
  const auto reseeded = AugmentedViews(box, options, 42);
  ASSERT_TRUE(reseeded.ok());
  EXPECT_FALSE(SameBits((*a)[0], (*reseeded)[0]));
  EXPECT_EQ(AugmentOptionsToString(options), "views=6,noise=0.01,points=300-500,pose=fixed,seed=2");
}

TEST(AugmentTest, FixedPoseViewsStayInTheCloudsFrame) {
  // No random pose: every view is a subset of the cloud plus noise, so it stays inside the
  // (slightly grown) box of the original.
  const PointCloud box = test_surfaces::BoxSurface({5, 0, 0}, {1, 0.5, 2}, 2000, 1);
  AugmentOptions options;
  options.views = 4;
  options.sensor.noise_fraction = 0;
  const absl::StatusOr<std::vector<PointCloud>> views = AugmentedViews(box, options, 7);
  ASSERT_TRUE(views.ok()) << views.status();
  ASSERT_EQ(views->size(), 4u);
  for (const PointCloud& view : *views) {
    for (size_t i = 0; i < view.size(); ++i) {
      EXPECT_NEAR(view.point(i).x(), 5.0, 1.0 + 1e-5);
      EXPECT_NEAR(view.point(i).z(), 0.0, 2.0 + 1e-5);
    }
  }
}

TEST(AugmentTest, VariedMixTakesTurnsBetweenVisibilityModels) {
  const PointCloud box = test_surfaces::BoxSurface({0, 0, 0}, {1, 0.5, 2}, 2000, 1);
  AugmentOptions camera;
  camera.views = 6;
  AugmentOptions varied = camera;
  varied.mix = ViewMix::kVaried;
  const auto a = AugmentedViews(box, camera, 42);
  const auto b = AugmentedViews(box, varied, 42);
  const auto b_again = AugmentedViews(box, varied, 42);
  ASSERT_TRUE(a.ok() && b.ok() && b_again.ok());
  ASSERT_EQ(b->size(), 6u);
  for (size_t i = 0; i < b->size(); ++i) {
    EXPECT_TRUE(SameBits((*b)[i], (*b_again)[i])) << i;
    EXPECT_GE((*b)[i].size(), 300u);
    EXPECT_LE((*b)[i].size(), 500u);
    // Views 1, 2, 4, 5 are cut or occluded, and their noise is redrawn: unlike the camera's.
    if (i % 3 != 0) {
      EXPECT_FALSE(SameBits((*a)[i], (*b)[i])) << i;
    }
  }
  EXPECT_EQ(AugmentOptionsToString(varied),
            "views=6,noise=0.01,points=300-500,pose=fixed,seed=1,mix=varied");
  const auto parsed = ParseAugmentOptions(AugmentOptionsToString(varied));
  ASSERT_TRUE(parsed.ok()) << parsed.status();
  EXPECT_EQ(parsed->mix, ViewMix::kVaried);
  EXPECT_EQ(ParseAugmentOptions("views=6")->mix, ViewMix::kCamera);  // stored before mix existed
  EXPECT_THAT(ParseAugmentOptions("views=6,mix=blurry").status().message(),
              HasSubstr("mix=camera|varied"));
}

TEST(AugmentTest, TextFormRoundTrips) {
  AugmentOptions options;
  options.views = 12;
  options.sensor.noise_fraction = 0.005;
  options.sensor.min_points = 200;
  options.sensor.max_points = 800;
  options.sensor.random_pose = true;
  options.seed = 77;
  const std::string text = AugmentOptionsToString(options);
  EXPECT_EQ(text, "views=12,noise=0.005,points=200-800,pose=random,seed=77");
  const auto parsed = ParseAugmentOptions(text);
  ASSERT_TRUE(parsed.ok()) << parsed.status();
  EXPECT_EQ(AugmentOptionsToString(*parsed), text);
  EXPECT_FALSE(ParseAugmentOptions("off")->enabled());
  EXPECT_EQ(ParseAugmentOptions("views=3")->sensor.max_points, 500u);  // defaults fill in
  for (const char* bad : {"views=x", "color=red", "points=5", "pose=sideways", "views=99"}) {
    EXPECT_EQ(ParseAugmentOptions(bad).status().code(), absl::StatusCode::kInvalidArgument) << bad;
  }
}

TEST(AugmentTest, RejectsOptionsOutOfRange) {
  const PointCloud box = test_surfaces::BoxSurface({0, 0, 0}, {1, 0.5, 2}, 500, 1);
  AugmentOptions options;
  options.views = AugmentOptions::kMaxViews + 1;
  EXPECT_THAT(ValidateAugmentOptions(options).message(), HasSubstr("views 65 is outside [0, 64]"));
  options.views = 2;
  options.sensor.min_points = 2;
  EXPECT_THAT(ValidateAugmentOptions(options).message(), HasSubstr("3 <= min <= max"));
  options.sensor.min_points = 300;
  options.sensor.noise_fraction = 2;
  EXPECT_THAT(AugmentedViews(box, options, 1).status().message(), HasSubstr("noise 2"));
  options.sensor.noise_fraction = 0.01;
  options.sensor.view.min_up = 0.5;
  options.sensor.view.max_up = 0.2;
  EXPECT_THAT(ValidateAugmentOptions(options).message(), HasSubstr("viewpoint band"));
}

}  // namespace
}  // namespace shapeid
