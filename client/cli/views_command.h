#ifndef SHAPEID_CLIENT_CLI_VIEWS_COMMAND_H_
#define SHAPEID_CLIENT_CLI_VIEWS_COMMAND_H_

// `shapeid views`: turns 3D models into the clouds a robot's depth sensor would see of them,
// as a labeled dataset for train / classify / eval:
//   OUT/<model>/train/view-00.pcd ...   (views from one set of directions)
//   OUT/<model>/test/view-00.pcd ...    (views from directions between those, other noise)
// The label is the model's file name without extension. With --scenes N it also composes N
// tabletop frames of the models (core/views/scene_composer.h) with each point's truth:
//   OUT/scenes/0000.pcd, 0000.objects.csv, 0000.truth.u16 ...  (docs/scenes.md)

#include <cstdint>
#include <string>
#include <vector>

#include "CLI/CLI.hpp"
#include "client/cli/cli_common.h"

namespace shapeid {

struct ViewsOptions {
  std::vector<std::string> models;  // mesh or cloud files (.off .obj .ply .pcd ...)
  std::string out;                  // output folder, created if missing
  int train_views = 12;
  int test_views = 6;
  // Sensor band: viewpoints between these elevations above the horizontal plane, as a
  // robot's sensor looks slightly down at objects on the floor or a table.
  double min_elevation = 10;
  double max_elevation = 50;
  std::string up = "y";        // the models' up axis: x, y or z (OBJ and games: y; ModelNet: z)
  double depth_noise = 0.005;  // ray noise, in object radii (a depth camera: about 0.5-1 %)
  int width = 160;             // depth image size: points per view grow with it
  int height = 120;
  size_t max_points = 0;          // subsample each view to at most this many points (0: all)
  size_t surface_points = 60000;  // dense surface sampling the sensor sees
  uint64_t seed = 1;
  // Tabletop frames: how many, objects per frame (drawn from the models), the chance that an
  // object leans on another, and models placed as clutter (in no gallery: role `clutter`,
  // one per frame while they last).
  int scenes = 0;
  int scene_objects = 5;
  double touching = 0.3;
  std::vector<std::string> clutter;
};

void AddViewsFlags(CLI::App* command, ViewsOptions* options);

// Exit 0, 1 when some model failed (reported, the others written), 2 for bad options.
int RunViews(const ViewsOptions& options, const CliContext& context);

}  // namespace shapeid

#endif  // SHAPEID_CLIENT_CLI_VIEWS_COMMAND_H_
