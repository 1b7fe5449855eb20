#ifndef SHAPEID_SERVER_WIRE_PROTO_CONVERT_H_
#define SHAPEID_SERVER_WIRE_PROTO_CONVERT_H_

// Conversions between the wire messages and core/ types: the only place that knows both.

#include "absl/status/statusor.h"
#include "absl/time/time.h"
#include "absl/types/span.h"
#include "core/descriptor_registry.h"
#include "core/gallery/gallery_metadata.h"
#include "core/gallery/gallery_options.h"
#include "core/gallery/gallery_snapshot.h"
#include "core/knn/knn_options.h"
#include "core/scene/scene_recognition.h"
#include "server/wire/cloud_assembler.h"
#include "shapeid/v1/shapeid.pb.h"

namespace shapeid {

// InvalidArgument "RPC: the gallery name is empty" for a request that names no gallery: every
// call that names one checks this before asking the registry.
absl::Status RequireGalleryName(absl::string_view rpc, absl::string_view name);

// A request's k as an int, bounded so that an absurd k is refused by its answer's size, not
// by overflow.
int BoundedK(uint32_t k);

// A header's point layout; the empty message is the default packed float32 layout.
// InvalidArgument naming the field: a coordinate missing or of a type other than FLOAT32 or
// FLOAT64, or what ValidatePointLayout refuses.
absl::StatusOr<PointLayout> FromProto(const v1::PointLayout& layout);

// The transform a header's sensor frame asks for: its rigid transform, or the rotation that
// turns its `up` onto `gallery_up` (the descriptor's up_direction); identity when empty.
// InvalidArgument when both are given or either is malformed (core/rigid_transform.h).
absl::StatusOr<RigidTransform> FromProto(const v1::SensorFrame& frame,
                                         const std::array<float, 3>& gallery_up);

// UNSPECIFIED enums and k = 0 take the defaults (uniform, no scaling, k = 1).
absl::StatusOr<KnnOptions> FromProto(const v1::KnnOptions& knn);
v1::KnnOptions ToProto(const KnnOptions& knn);

// Zeros take the defaults (noise 0.01 only when unset, 300-500 points, seed 1);
// InvalidArgument (ValidateAugmentOptions's message) for values out of range.
absl::StatusOr<AugmentOptions> FromProto(const v1::ViewAugmentation& augmentation);
v1::ViewAugmentation ToProto(const AugmentOptions& augment);

absl::StatusOr<GalleryOptions> GalleryOptionsFromProto(const v1::CreateGalleryRequest& request);

// A gallery's metadata as v1::Gallery reports it (augmentation always set, defaults filled).
void ToProto(const GalleryMetadata& meta, v1::Gallery* out);
// The same in an export header, but the version and incarnation (an import makes a new
// gallery) and the augmentation only when on (so such exports keep their bytes). The format
// version and sample count are the exporter's.
void ToProto(const GalleryMetadata& meta, v1::GalleryExportHeader* out);
// The inverse for an export header: FromProto's errors for its knn options and augmentation.
absl::StatusOr<GalleryMetadata> MetadataFromProto(const v1::GalleryExportHeader& header);

// The gallery as GetGallery / ListGalleries report it: its metadata, counts and
// incompatibility.
void ToProto(const GallerySnapshot& snapshot, v1::Gallery* out);

// The descriptors a server offers (core/descriptor_registry.h), each with its parameters, its
// canonical default spec and dimension; the registry's error if a default cannot be built.
absl::Status ToProto(absl::Span<const DescriptorKind> kinds, v1::ListDescriptorsResponse* out);

void ToProto(const GalleryClassification& answer, size_t num_points, v1::ClassifyResponse* out);
// A trained sample's provenance from a SampleHeader, metadata in the map's order (neither
// sorted nor validated: TrainBatch::AddSample does both).
// A SceneHeader's segmentation parameters and region of interest over the defaults (unset
// fields keep them). Ranges are SegmentScene's to check, naming the field; here only the
// conversion: counts too large for an int are clamped so that the check names them.
SceneSegmentationOptions FromProto(const v1::SceneSegmentation& segmentation,
                                   const v1::AxisAlignedBox* region);
// A recognized frame of `num_points` points; each object's indices only `with_indices`.
void ToProto(const SceneRecognition& scene, size_t num_points, bool with_indices,
             v1::RecognizeSceneResponse* out);

SampleProvenance ProvenanceFromProto(const v1::SampleHeader& sample);
void ToProto(const SampleInfo& sample, v1::SampleInfo* out);

void ToProto(absl::Duration d, google::protobuf::Duration* out);
void ToProto(absl::Time t, google::protobuf::Timestamp* out);
// Exact inverse of ToProto for any time it produced (nanosecond resolution).
absl::Time FromProto(const google::protobuf::Timestamp& t);

}  // namespace shapeid

#endif  // SHAPEID_SERVER_WIRE_PROTO_CONVERT_H_
