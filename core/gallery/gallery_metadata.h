#ifndef SHAPEID_CORE_GALLERY_GALLERY_METADATA_H_
#define SHAPEID_CORE_GALLERY_GALLERY_METADATA_H_

#include <cstdint>
#include <string>

#include "absl/time/time.h"
#include "core/gallery/gallery_options.h"

namespace shapeid {

// Everything about a gallery but its samples: one value held by its snapshots
// (GallerySnapshot::metadata), its stored form (StoredGallery) and its export. A new field
// goes here, then into each serialization: the SQLite and PostgreSQL gallery rows
// (server/storage/), the export header and v1::Gallery (server/wire/proto_convert.cc).
struct GalleryMetadata {
  std::string name;
  GalleryOptions options;  // canonical
  absl::Time created;
  // Time of the last published change; `created` for a new gallery.
  absl::Time updated;
  // What made the descriptors: DescriptorKind::version of the spec's kind, and the shapeid
  // version (kShapeidVersion). A server whose descriptor version differs cannot add to the
  // gallery or classify against it (see GallerySnapshot::incompatible()).
  uint32_t descriptor_version = 0;
  std::string software_version;
  // Features per sample (per view). Stored so that a gallery whose spec this server cannot
  // build still loads (and can be exported or deleted).
  int dimension = 0;
  // Published changes: 0 for a new gallery, +1 per committed batch or removal. A private
  // store may leave it 0 (versions then restart at each load); a store shared by several
  // servers keeps it, so that every server reports the same version and a write from a
  // server whose copy is behind is detected (see GalleryStore).
  uint64_t version = 0;
  // Drawn at random when the gallery is created or imported (never 0 then): tells a gallery
  // from an earlier one of the same name. A shared store uses it so that a server never
  // applies one incarnation's change to another; 0 from a store that does not keep it.
  uint64_t incarnation = 0;
};

}  // namespace shapeid

#endif  // SHAPEID_CORE_GALLERY_GALLERY_METADATA_H_
