#ifndef SHAPEID_CLIENT_CLI_SCENE_COMMAND_H_
#define SHAPEID_CLIENT_CLI_SCENE_COMMAND_H_

// `shapeid scene`: the objects of sensor frames (a table or floor with things on it), each
// classified against a gallery by the server's RecognizeScene; optionally the frame written
// back colored by label (PLY or PCD) or drawn as a PNG.

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "CLI/CLI.hpp"
#include "absl/types/span.h"
#include "client/cli/cli_common.h"
#include "core/io/read_options.h"

namespace shapeid {

struct SceneCommandOptions {
  std::string gallery;
  // k, exact, segmentation parameters (unset: the server's defaults); main.cc fills the
  // sensor frame; return_indices is set here when a colored output needs them.
  Client::SceneOptions call;
  std::string region;  // --region x0,y0,z0,x1,y1,z1 as typed; empty: the whole frame
  // How files become frames. Non-finite points are kept unless read.drop_non_finite, so that
  // indices and colors are the file's points; coordinates are never recentered (answers are
  // in the file's coordinates).
  ReadOptions read;
  bool skip_unsupported = false;
  bool indices = false;  // json: each object's point indices
  std::string colored;   // write the frame colored by label here: .ply or .pcd (one frame)
  std::string picture;   // draw the colored frame here: .png (one frame)
  std::vector<std::string> frames;
};

// The scene-specific flags (segmentation, region, k, outputs, FRAME); main.cc adds the read
// and sensor-frame flags the other commands share.
void AddSceneFlags(CLI::App* command, SceneCommandOptions* options);

// Recognizes every frame in order, writing its objects to context.out (table, JSON Lines or
// CSV) and one line per failed frame to context.err. Returns kExitOk, kExitSomeInputsFailed,
// kExitUsage (bad region, outputs, paths), or the server's exit code when it refuses the
// whole command (unknown or empty gallery, bad parameter) or is unreachable.
int RunScene(const SceneCommandOptions& options, const CliContext& context);

// What a point of the frame became, as a palette index of kScenePalette.
inline constexpr uint8_t kSceneBackground = 0;  // pictures only: white
inline constexpr uint8_t kSceneViewFrame = 1;   // pictures only: each view's border
inline constexpr uint8_t kScenePlane = 2;       // on a removed plane: grey
inline constexpr uint8_t kSceneUnassigned = 3;  // non-finite, outside the region, noise: dark
inline constexpr uint8_t kSceneUnknown = 4;     // an object labeled unknown: magenta
inline constexpr uint8_t kSceneFirstLabel = 5;  // labels' colors from here
inline constexpr int kSceneLabelColors = 9;
extern const std::array<std::array<uint8_t, 3>, kSceneFirstLabel + kSceneLabelColors> kScenePalette;

// The palette index of `label`: kSceneUnknown for "unknown", else one of the label colors
// chosen by the label's CRC-32, so that a label keeps its color across frames, galleries
// and runs (two labels may share one).
uint8_t SceneLabelColor(const std::string& label);

// One palette index per point of `frame` (as sent; scene answered with return_indices): its
// object's label color; kScenePlane for a finite point within `plane_distance` of a removed
// plane (the answer gives planes' coefficients, not their points) and inside `region` when
// one is given; kSceneUnassigned otherwise.
std::vector<uint8_t> SceneColors(const PointCloud& frame, const v1::RecognizeSceneResponse& scene,
                                 double plane_distance, const v1::AxisAlignedBox* region);

// The frame with its points' colors (palette indices of kScenePalette) as a binary PLY or
// PCD (core/io/colored_cloud_writer.h), chosen by `path`'s extension, written atomically.
// Every point is written, non-finite ones too.
absl::Status WriteColoredFrame(const std::string& path, const PointCloud& frame,
                               absl::Span<const uint8_t> colors);

}  // namespace shapeid

#endif  // SHAPEID_CLIENT_CLI_SCENE_COMMAND_H_
