#include "core/views/scene_composer.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "core/views/test_surfaces.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using test_surfaces::BoxSurface;
using test_surfaces::SphereSurface;
using ::testing::HasSubstr;

// Six models: boxes of three proportions (one lying along y, its up given as +y), spheres,
// in units that are not metres.
std::vector<SceneObjectModel> Models() {
  std::vector<SceneObjectModel> models;
  for (uint32_t i = 0; i < 6; ++i) {
    SceneObjectModel m;
    if (i % 2 == 0) {
      m.label = "box";
      m.surface = BoxSurface({5, 5, 5}, {20, 10 + 5.0f * i, 30}, 1500, i + 1);
    } else {
      m.label = "ball";
      m.role = SceneRole::kClutter;
      m.surface = SphereSurface(1200, i + 1, 40);
    }
    if (i == 2) m.up = {0, 1, 0};
    models.push_back(std::move(m));
  }
  return models;
}

// Model points of object `o`, in the table's frame.
std::vector<Eigen::Vector3d> Placed(const SceneObjectModel& model, const ComposedObject& o) {
  std::vector<Eigen::Vector3d> points;
  for (size_t i = 0; i < model.surface.size(); ++i) {
    points.push_back(o.scale * (o.rotation * model.surface.point(i).cast<double>()) +
                     o.translation);
  }
  return points;
}

// The least xy distance between points of a and b, when less than `limit`; else `limit` or
// more.
double FootprintGap(const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b,
                    double limit) {
  const auto near_box = [limit](const std::vector<Eigen::Vector3d>& points,
                                const std::vector<Eigen::Vector3d>& other) {
    Eigen::Vector2d lo = other.front().head<2>(), hi = lo;
    for (const Eigen::Vector3d& p : other)
      lo = lo.cwiseMin(p.head<2>()), hi = hi.cwiseMax(p.head<2>());
    std::vector<Eigen::Vector2d> kept;
    for (const Eigen::Vector3d& p : points) {
      if ((p.head<2>().array() > lo.array() - limit).all() &&
          (p.head<2>().array() < hi.array() + limit).all()) {
        kept.push_back(p.head<2>());
      }
    }
    return kept;
  };
  const std::vector<Eigen::Vector2d> pa = near_box(a, b), pb = near_box(b, a);
  double best = limit * limit;
  for (const Eigen::Vector2d& p : pa) {
    for (const Eigen::Vector2d& q : pb) best = std::min(best, (p - q).squaredNorm());
  }
  return std::sqrt(best);
}

TEST(SceneComposerTest, ObjectsStandOnTheTableAndEveryPointHasItsTruth) {
  const std::vector<SceneObjectModel> models = Models();
  SceneComposerOptions options;
  options.seed = 3;
  const absl::StatusOr<ComposedScene> scene = ComposeScene(models, options);
  ASSERT_TRUE(scene.ok()) << scene.status();
  ASSERT_EQ(scene->objects.size(), 6u);
  ASSERT_EQ(scene->truth.size(), scene->frame.size());
  EXPECT_GT(scene->frame.size(), 2000u);
  std::vector<size_t> counts(7);
  for (const uint16_t t : scene->truth) ++counts[t];
  EXPECT_GT(counts[0], scene->frame.size() / 3);  // the table
  const Eigen::Isometry3d to_table = scene->camera_to_table;
  for (size_t k = 0; k < scene->objects.size(); ++k) {
    const ComposedObject& o = scene->objects[k];
    EXPECT_EQ(o.model, k);
    EXPECT_EQ(o.label, models[k].label);
    EXPECT_EQ(o.role, models[k].role);
    EXPECT_EQ(o.points, counts[k + 1]);
    EXPECT_GT(o.points, 50u) << k;
    EXPECT_TRUE(o.separated) << k;
    const double largest = o.size.maxCoeff();
    EXPECT_GE(largest, options.min_size - 1e-6);
    EXPECT_LE(largest, options.max_size + 1e-6);
    const std::vector<Eigen::Vector3d> placed = Placed(models[k], o);
    double low = std::numeric_limits<double>::infinity();
    for (const Eigen::Vector3d& p : placed) {
      low = std::min(low, p.z());
      EXPECT_LE(std::abs(p.x()), 0.5 * options.table_width - options.edge_margin + 1e-6);
      EXPECT_LE(std::abs(p.y()), 0.5 * options.table_depth - options.edge_margin + 1e-6);
    }
    EXPECT_NEAR(low, 0, 1e-6) << k;
  }
  // The model box stood up along its +y (40 units) has that height; the others keep their z.
  EXPECT_NEAR(scene->objects[2].size.z(), 40 * scene->objects[2].scale, 1e-6);
  EXPECT_NEAR(scene->objects[0].size.z(), 60 * scene->objects[0].scale, 1e-6);
  // Each point back in the table frame: table points on z = 0, object points within their
  // object's placed box, both within the noise (2 mm; 5 sigma).
  std::vector<Eigen::Vector3d> lo(6, Eigen::Vector3d::Constant(1e9)), hi(6, -lo[0]);
  for (size_t k = 0; k < 6; ++k) {
    for (const Eigen::Vector3d& p : Placed(models[k], scene->objects[k])) {
      lo[k] = lo[k].cwiseMin(p), hi[k] = hi[k].cwiseMax(p);
    }
  }
  for (size_t i = 0; i < scene->frame.size(); ++i) {
    const Eigen::Vector3d p = to_table * scene->frame.point(i).cast<double>();
    if (scene->truth[i] == 0) {
      ASSERT_LT(std::abs(p.z()), 0.01) << i;
    } else {
      const size_t k = scene->truth[i] - 1u;
      ASSERT_TRUE((p.array() > lo[k].array() - 0.01).all() &&
                  (p.array() < hi[k].array() + 0.01).all())
          << i;
    }
  }
  // The camera looks down at the table from 30 to 60 degrees.
  const Eigen::Vector3d forward = to_table.linear().col(2);
  const double elevation = std::asin(-forward.z()) * 180 / 3.14159265358979323846;
  EXPECT_GE(elevation, 30);
  EXPECT_LE(elevation, 60);
}

TEST(SceneComposerTest, SeparatedObjectsKeepTheirGapAndLeaningOnesTouch) {
  const std::vector<SceneObjectModel> models = Models();
  for (const double touch : {0.0, 1.0}) {
    SceneComposerOptions options;
    options.touch_probability = touch;
    options.seed = 5;
    const absl::StatusOr<ComposedScene> scene = ComposeScene(models, options);
    ASSERT_TRUE(scene.ok()) << scene.status();
    ASSERT_EQ(scene->objects.size(), 6u);
    int separated = 0;
    for (size_t i = 0; i < 6; ++i) {
      const std::vector<Eigen::Vector3d> a = Placed(models[i], scene->objects[i]);
      double nearest = std::numeric_limits<double>::infinity();
      for (size_t j = 0; j < 6; ++j) {
        if (j != i)
          nearest = std::min(
              nearest, FootprintGap(a, Placed(models[j], scene->objects[j]), 2 * options.min_gap));
      }
      EXPECT_EQ(scene->objects[i].separated, nearest >= options.min_gap) << touch << " " << i;
      if (touch == 0) {
        EXPECT_GE(nearest, options.min_gap) << i;
      } else {
        EXPECT_LE(nearest, options.max_contact_gap + 1e-9) << i;
        EXPECT_GE(nearest, 0.3 * options.max_contact_gap - 1e-9) << i;
      }
      separated += scene->objects[i].separated ? 1 : 0;
    }
    EXPECT_EQ(separated, touch == 0 ? 6 : 0);
  }
}

TEST(SceneComposerTest, TheSameSeedGivesTheSameBits) {
  const std::vector<SceneObjectModel> models = Models();
  SceneComposerOptions options;
  options.touch_probability = 0.5;
  options.seed = 9;
  const absl::StatusOr<ComposedScene> a = ComposeScene(models, options);
  const absl::StatusOr<ComposedScene> b = ComposeScene(models, options);
  options.seed = 10;
  const absl::StatusOr<ComposedScene> c = ComposeScene(models, options);
  ASSERT_TRUE(a.ok() && b.ok() && c.ok());
  EXPECT_EQ(a->frame.xyz(), b->frame.xyz());
  EXPECT_EQ(a->truth, b->truth);
  EXPECT_NE(a->frame.xyz(), c->frame.xyz());
}

TEST(SceneComposerTest, ACrowdedTableTakesTheObjectsThatFit) {
  std::vector<SceneObjectModel> models(20, Models()[0]);
  SceneComposerOptions options;
  options.table_width = 0.5;
  options.table_depth = 0.5;
  const absl::StatusOr<ComposedScene> scene = ComposeScene(models, options);
  ASSERT_TRUE(scene.ok()) << scene.status();
  EXPECT_GE(scene->objects.size(), 1u);
  EXPECT_LT(scene->objects.size(), 10u);
}

TEST(SceneComposerTest, BadInputIsRejectedWithItsReason) {
  const std::vector<SceneObjectModel> models = Models();
  const auto error = [&](SceneComposerOptions options) {
    return ComposeScene(models, options).status();
  };
  SceneComposerOptions o;
  o.min_size = 0.4;  // above max_size
  EXPECT_THAT(error(o).message(), HasSubstr("object sizes"));
  o = {};
  o.touch_probability = 1.5;
  EXPECT_THAT(error(o).message(), HasSubstr("touch probability"));
  o = {};
  o.max_contact_gap = 0.06;
  EXPECT_THAT(error(o).message(), HasSubstr("gaps"));
  o = {};
  o.max_elevation_degrees = 90;
  EXPECT_THAT(error(o).message(), HasSubstr("elevation"));
  o = {};
  o.depth_noise = -1;
  EXPECT_THAT(error(o).message(), HasSubstr("depth noise"));
  o = {};
  o.table_width = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THAT(error(o).message(), HasSubstr("table"));
  o = {};
  o.table_spacing = 1e-5;
  EXPECT_THAT(error(o).message(), HasSubstr("at most"));
  o = {};
  o.distance = 0.5;
  EXPECT_EQ(error(o).code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(ComposeScene({}, {}).status().code(), absl::StatusCode::kInvalidArgument);
  std::vector<SceneObjectModel> bad = models;
  bad[1].up = {0, 0, 0};
  EXPECT_THAT(ComposeScene(bad, {}).status().message(), HasSubstr("up must be"));
  bad = models;
  bad[1].surface = PointCloud();
  EXPECT_THAT(ComposeScene(bad, {}).status().message(), HasSubstr("scene model 1"));
}

}  // namespace
}  // namespace shapeid
