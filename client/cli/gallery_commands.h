#ifndef SHAPEID_CLIENT_CLI_GALLERY_COMMANDS_H_
#define SHAPEID_CLIENT_CLI_GALLERY_COMMANDS_H_

// `shapeid gallery create|list|show|delete|remove|export|import`, `shapeid descriptors` and
// `shapeid health`: one call each to the server, printed as table, json or csv.

#include <cstdint>
#include <string>
#include <vector>

#include "client/cli/cli_common.h"
#include "shapeid/v1/shapeid.pb.h"

namespace shapeid {

struct GalleryCreateOptions {
  std::string name;
  std::string spec;            // empty: the server's default descriptor
  uint32_t k = 0;              // 0: the server's default (1)
  std::string weighting;       // "", "uniform" or "distance"
  std::string scaling;         // "", "none", "zscore" or "maxabs"
  double reject_distance = 0;  // 0: never answer "unknown"
  // View augmentation: synthetic single-view scans per trained cloud (0: off), and whether
  // each is also turned to a random pose.
  uint32_t augment_views = 0;
  bool augment_random_pose = false;
  std::string augment_mix;  // "", "camera" or "varied"
  std::string learn;        // eval --local only: "", "off" or "mlp" (core/gallery/gallery_head.h)
  bool exist_ok = false;    // an existing gallery is success (scripts re-run safely)
};

// The CreateGalleryRequest for `options`; InvalidArgument for an unknown weighting/scaling.
absl::StatusOr<v1::CreateGalleryRequest> CreateGalleryRequestFor(
    const GalleryCreateOptions& options);

int RunGalleryCreate(const GalleryCreateOptions& options, const CliContext& context);
int RunGalleryList(const CliContext& context);
int RunGalleryShow(const std::string& name, const CliContext& context);
int RunGalleryDelete(const std::string& name, bool missing_ok, const CliContext& context);

struct GalleryRemoveOptions {
  std::string name;
  std::vector<uint64_t> sample_ids;
  std::vector<std::string> labels;
};
int RunGalleryRemove(const GalleryRemoveOptions& options, const CliContext& context);

struct GallerySamplesOptions {
  std::string name;
  std::string label;   // empty: every label
  uint64_t limit = 0;  // 0: every sample
  uint32_t page_size = 1000;
};
// Lists a gallery's samples with their provenance, in id order, fetched a page at a time
// (ListSamples) and printed as they arrive: table (ID LABEL VIEWS SOURCE METADATA), JSON
// Lines (one object per sample) or CSV (metadata as a JSON object in one field).
int RunGallerySamples(const GallerySamplesOptions& options, const CliContext& context);

// Writes gallery `name` to `file` (client/gallery_file.h; "-": stdout), replacing it only
// once the whole export has arrived. Table format: "exported gallery 'NAME': N samples to
// FILE (B bytes)" on stderr unless --quiet; json and csv: the same facts on stdout (on stderr
// when the export itself goes to stdout). Exit 2 when FILE cannot be created, 1 when it
// cannot be written, else as ExitCodeForStatus.
int RunGalleryExport(const std::string& name, const std::string& file, const CliContext& context);
// Streams `file` ("-": stdin) to the server as a new gallery, named `new_name` or, when
// empty, as exported; prints it as `gallery show` does. Exit 2 when FILE cannot be opened or
// is not an export; 4 when the server refuses the import (name taken, another descriptor
// version) or the export is damaged or truncated, whether the client or the server finds out.
int RunGalleryImport(const std::string& file, const std::string& new_name,
                     const CliContext& context);

int RunDescriptors(const CliContext& context);

// Exit 0 when the server answers SERVING, 3 otherwise. Prints "SERVING <target>" (table),
// {"status":"SERVING","target":...} (json) or a CSV row.
int RunHealth(const CliContext& context);

// Renderings shared with other commands and tests.
std::string GalleryJson(const v1::Gallery& gallery);  // one line, with '\n'
std::string ScalingName(v1::FeatureScaling scaling);
std::string WeightingName(v1::VoteWeighting weighting);

}  // namespace shapeid

#endif  // SHAPEID_CLIENT_CLI_GALLERY_COMMANDS_H_
