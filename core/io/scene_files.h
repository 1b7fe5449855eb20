#ifndef SHAPEID_CORE_IO_SCENE_FILES_H_
#define SHAPEID_CORE_IO_SCENE_FILES_H_

// Scene sets on disk: sensor frames with the truth of every point, for scene-recognition
// tests and benchmarks, whatever made them (`shapeid views --scenes`, the project's
// simulator; bench/independent_scenes.py, an independent one). In a folder:
//   NNNN.pcd          the frame (any rigid frame; NaN points kept)
//   NNNN.objects.csv  `object,label,role,source`, one row per object, object = 1..n,
//                     role `gallery` (its class is in the gallery) or `clutter` (in none)
//   NNNN.truth.u16    little-endian uint16 per point of the frame, in order: 0 no object
//                     (support, background, missing), i the object of row i
// docs/scenes.md describes the format.

#include <cstdint>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "core/point_cloud.h"

namespace shapeid {

struct SceneFileObject {
  std::string label;     // no comma: the csv's fields are not quoted
  bool clutter = false;  // role `clutter`: must be answered unknown
  std::string source;
};

struct SceneFile {
  std::string name;  // NNNN
  PointCloud frame;  // as stored: not recentered, NaN points kept
  std::vector<uint16_t> truth;
  std::vector<SceneFileObject> objects;  // objects[i - 1] is truth id i
};

// The frame names NNNN of `dir` (those with a .pcd), sorted.
std::vector<std::string> ListSceneFiles(const std::string& dir);

// Reads frame `name` of `dir`. InvalidArgument for a malformed csv, a truth file whose length
// is not 2 bytes per point or an id above the objects' count; the readers' errors otherwise.
absl::StatusOr<SceneFile> ReadSceneFile(const std::string& dir, const std::string& name);

// Writes `scene` as frame `scene.name` of `dir` (which must exist), each file as
// WriteFileAtomically does (core/io/file_writer.h). InvalidArgument for a label with a comma or
// a newline, or truth of another length than the frame; the writer's errors otherwise.
absl::Status WriteSceneFile(const std::string& dir, const SceneFile& scene);

}  // namespace shapeid

#endif  // SHAPEID_CORE_IO_SCENE_FILES_H_
