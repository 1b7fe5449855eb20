#include "server/wire/proto_convert.h"

#include <algorithm>
#include <limits>
#include <memory>
#include <string>

#include "Eigen/Geometry"
#include "absl/strings/str_cat.h"
#include "core/status_macros.h"

namespace shapeid {

absl::Status RequireGalleryName(absl::string_view rpc, absl::string_view name) {
  if (name.empty()) {
    return absl::InvalidArgumentError(absl::StrCat(rpc, ": the gallery name is empty"));
  }
  return absl::OkStatus();
}

int BoundedK(uint32_t k) { return static_cast<int>(std::min<uint32_t>(k, 1 << 20)); }

absl::StatusOr<KnnOptions> FromProto(const v1::KnnOptions& knn) {
  KnnOptions out;
  out.k = knn.k() == 0 ? 1 : BoundedK(knn.k());
  switch (knn.weighting()) {
    case v1::VOTE_WEIGHTING_UNSPECIFIED:
    case v1::VOTE_WEIGHTING_UNIFORM:
      out.weighting = VoteWeighting::kUniform;
      break;
    case v1::VOTE_WEIGHTING_DISTANCE:
      out.weighting = VoteWeighting::kDistance;
      break;
    default:
      return absl::InvalidArgumentError(absl::StrCat("unknown vote weighting ", knn.weighting()));
  }
  switch (knn.scaling()) {
    case v1::FEATURE_SCALING_UNSPECIFIED:
    case v1::FEATURE_SCALING_NONE:
      out.scaling = FeatureScaling::kNone;
      break;
    case v1::FEATURE_SCALING_ZSCORE:
      out.scaling = FeatureScaling::kZScore;
      break;
    case v1::FEATURE_SCALING_MAXABS:
      out.scaling = FeatureScaling::kMaxAbs;
      break;
    default:
      return absl::InvalidArgumentError(absl::StrCat("unknown feature scaling ", knn.scaling()));
  }
  return out;
}

v1::KnnOptions ToProto(const KnnOptions& knn) {
  v1::KnnOptions out;
  out.set_k(static_cast<uint32_t>(knn.k));
  out.set_weighting(knn.weighting == VoteWeighting::kDistance ? v1::VOTE_WEIGHTING_DISTANCE
                                                              : v1::VOTE_WEIGHTING_UNIFORM);
  switch (knn.scaling) {
    case FeatureScaling::kNone:
      out.set_scaling(v1::FEATURE_SCALING_NONE);
      break;
    case FeatureScaling::kZScore:
      out.set_scaling(v1::FEATURE_SCALING_ZSCORE);
      break;
    case FeatureScaling::kMaxAbs:
      out.set_scaling(v1::FEATURE_SCALING_MAXABS);
      break;
  }
  return out;
}

absl::StatusOr<PointLayout> FromProto(const v1::PointLayout& layout) {
  PointLayout out;
  out.drop_nonfinite = layout.drop_nonfinite();
  if (layout.point_step() == 0 && !layout.has_x() && !layout.has_y() && !layout.has_z() &&
      !layout.is_bigendian() && layout.width() == 0 && layout.row_step() == 0) {
    return out;  // the default layout, perhaps dropping non-finite points
  }
  out.point_step = layout.point_step();
  out.big_endian = layout.is_bigendian();
  out.width = layout.width();
  out.row_step = layout.row_step();
  const v1::PointCoordinate* coordinates[3] = {&layout.x(), &layout.y(), &layout.z()};
  const bool present[3] = {layout.has_x(), layout.has_y(), layout.has_z()};
  static constexpr const char* kAxis[3] = {"x", "y", "z"};
  for (int a = 0; a < 3; ++a) {
    if (!present[a]) {
      return absl::InvalidArgumentError(
          absl::StrCat("point layout: ", kAxis[a], " is missing (a layout names x, y and z)"));
    }
    const int datatype = coordinates[a]->datatype();
    if (datatype == v1::FLOAT32 || datatype == v1::FLOAT64) {
      out.xyz[a] = {coordinates[a]->offset(), datatype == v1::FLOAT64
                                                  ? PointLayout::Type::kFloat64
                                                  : PointLayout::Type::kFloat32};
      continue;
    }
    // sensor_msgs/PointField's other datatypes, by number.
    static constexpr const char* kRosTypes[] = {"unspecified", "INT8",  "UINT8", "INT16",
                                                "UINT16",      "INT32", "UINT32"};
    const std::string type = datatype >= 0 && datatype <= 6
                                 ? absl::StrCat(kRosTypes[datatype], " (", datatype, ")")
                                 : absl::StrCat(datatype);
    return absl::InvalidArgumentError(absl::StrCat("point layout: ", kAxis[a], " has datatype ",
                                                   type,
                                                   "; x, y and z must be FLOAT32 (7) or "
                                                   "FLOAT64 (8)"));
  }
  SHAPEID_RETURN_IF_ERROR(ValidatePointLayout(out));
  return out;
}

absl::StatusOr<RigidTransform> FromProto(const v1::SensorFrame& frame,
                                         const std::array<float, 3>& gallery_up) {
  if (!frame.transform().empty() && !frame.up().empty()) {
    return absl::InvalidArgumentError(
        "sensor frame: give a transform or an up direction, not both (a transform fixes up "
        "too)");
  }
  if (!frame.transform().empty()) return RigidTransformFromRows(frame.transform());
  if (!frame.up().empty()) return RotationTakingUpTo(frame.up(), gallery_up);
  return RigidTransform();
}

absl::StatusOr<AugmentOptions> FromProto(const v1::ViewAugmentation& augmentation) {
  AugmentOptions out;
  // Clamped before the int conversion; ValidateAugmentOptions names the value if too large.
  out.views = static_cast<int>(std::min<uint32_t>(augmentation.views(), 1 << 20));
  if (augmentation.has_noise()) out.sensor.noise_fraction = augmentation.noise();
  if (augmentation.min_points() != 0) out.sensor.min_points = augmentation.min_points();
  if (augmentation.max_points() != 0) out.sensor.max_points = augmentation.max_points();
  out.sensor.random_pose = augmentation.random_pose();
  if (augmentation.seed() != 0) out.seed = augmentation.seed();
  switch (augmentation.mix()) {
    case v1::VIEW_MIX_UNSPECIFIED:
    case v1::VIEW_MIX_CAMERA:
      out.mix = ViewMix::kCamera;
      break;
    case v1::VIEW_MIX_VARIED:
      out.mix = ViewMix::kVaried;
      break;
    default:
      return absl::InvalidArgumentError(
          absl::StrCat("augmentation: unknown view mix ", static_cast<int>(augmentation.mix())));
  }
  if (absl::Status s = ValidateAugmentOptions(out); !s.ok()) return s;
  return out;
}

v1::ViewAugmentation ToProto(const AugmentOptions& augment) {
  v1::ViewAugmentation out;
  out.set_views(static_cast<uint32_t>(augment.views));
  out.set_noise(augment.sensor.noise_fraction);
  out.set_min_points(static_cast<uint32_t>(augment.sensor.min_points));
  out.set_max_points(static_cast<uint32_t>(augment.sensor.max_points));
  out.set_random_pose(augment.sensor.random_pose);
  out.set_seed(augment.seed);
  // The camera's mix stays unset: galleries and exports from before `mix` keep their bytes.
  if (augment.mix == ViewMix::kVaried) out.set_mix(v1::VIEW_MIX_VARIED);
  return out;
}

absl::StatusOr<GalleryOptions> GalleryOptionsFromProto(const v1::CreateGalleryRequest& request) {
  GalleryOptions options;
  if (!request.descriptor_spec().empty()) options.descriptor_spec = request.descriptor_spec();
  auto knn = FromProto(request.knn());
  if (!knn.ok()) return knn.status();
  options.knn = *knn;
  options.reject_distance = request.reject_distance();
  if (request.has_augmentation()) {
    auto augment = FromProto(request.augmentation());
    if (!augment.ok()) return augment.status();
    options.augment = *augment;
  }
  return options;
}

SampleProvenance ProvenanceFromProto(const v1::SampleHeader& sample) {
  SampleProvenance provenance;
  provenance.source = sample.source();
  for (const auto& [key, value] : sample.metadata()) provenance.metadata.emplace_back(key, value);
  return provenance;
}

void ToProto(const SampleInfo& sample, v1::SampleInfo* out) {
  out->set_sample_id(sample.id);
  out->set_label(sample.label);
  out->set_views(static_cast<uint32_t>(sample.views));
  if (sample.provenance == nullptr) return;
  out->set_source(sample.provenance->source);
  for (const auto& [key, value] : sample.provenance->metadata) {
    (*out->mutable_metadata())[key] = value;
  }
}

void ToProto(absl::Duration d, google::protobuf::Duration* out) {
  const int64_t nanos = absl::ToInt64Nanoseconds(d);
  out->set_seconds(nanos / 1'000'000'000);
  out->set_nanos(static_cast<int32_t>(nanos % 1'000'000'000));
}

void ToProto(absl::Time t, google::protobuf::Timestamp* out) {
  const int64_t nanos = absl::ToUnixNanos(t);
  out->set_seconds(nanos / 1'000'000'000);
  out->set_nanos(static_cast<int32_t>(nanos % 1'000'000'000));
}

absl::Time FromProto(const google::protobuf::Timestamp& t) {
  return absl::FromUnixSeconds(t.seconds()) + absl::Nanoseconds(t.nanos());
}

namespace {

// The fields v1::Gallery and v1::GalleryExportHeader share, under the same names.
template <typename Message>
void CommonMetadataToProto(const GalleryMetadata& meta, Message* out) {
  out->set_name(meta.name);
  out->set_descriptor_spec(meta.options.descriptor_spec);
  out->set_dimension(static_cast<uint32_t>(meta.dimension));
  *out->mutable_knn() = ToProto(meta.options.knn);
  out->set_reject_distance(meta.options.reject_distance);
  ToProto(meta.created, out->mutable_create_time());
  ToProto(meta.updated, out->mutable_update_time());
  out->set_descriptor_version(meta.descriptor_version);
  out->set_software_version(meta.software_version);
}

}  // namespace

void ToProto(const GalleryMetadata& meta, v1::Gallery* out) {
  CommonMetadataToProto(meta, out);
  out->set_version(meta.version);
  *out->mutable_augmentation() = ToProto(meta.options.augment);
}

void ToProto(const GalleryMetadata& meta, v1::GalleryExportHeader* out) {
  CommonMetadataToProto(meta, out);
  if (meta.options.augment.enabled()) *out->mutable_augmentation() = ToProto(meta.options.augment);
}

absl::StatusOr<GalleryMetadata> MetadataFromProto(const v1::GalleryExportHeader& header) {
  GalleryMetadata meta;
  meta.name = header.name();
  meta.options.descriptor_spec = header.descriptor_spec();
  SHAPEID_ASSIGN_OR_RETURN(meta.options.knn, FromProto(header.knn()));
  meta.options.reject_distance = header.reject_distance();
  if (header.has_augmentation()) {
    SHAPEID_ASSIGN_OR_RETURN(meta.options.augment, FromProto(header.augmentation()));
  }
  meta.created = FromProto(header.create_time());
  meta.updated = FromProto(header.update_time());
  meta.descriptor_version = header.descriptor_version();
  meta.software_version = header.software_version();
  meta.dimension = static_cast<int>(header.dimension());
  return meta;
}

void ToProto(const GallerySnapshot& snapshot, v1::Gallery* out) {
  ToProto(snapshot.metadata(), out);
  out->set_sample_count(static_cast<uint64_t>(snapshot.num_samples()));
  for (const auto& [label, count] : snapshot.LabelCounts()) {  // std::map: sorted by label
    v1::LabelCount* entry = out->add_label_counts();
    entry->set_label(label);
    entry->set_count(static_cast<uint64_t>(count));
  }
  out->set_incompatible(snapshot.incompatible());
  out->set_vector_count(static_cast<uint64_t>(snapshot.index().num_rows()));
  out->set_approximate_lists(static_cast<uint32_t>(snapshot.index().approximate_lists()));
  if (const std::shared_ptr<const GalleryHead>& head = snapshot.head(); head != nullptr) {
    v1::GalleryHead* h = out->mutable_head();
    h->set_fitted_version(head->fitted_version);
    h->set_answers(snapshot.head_answers());
    h->set_fitted_samples(static_cast<uint64_t>(head->fitted_samples));
    h->set_fitted_vectors(static_cast<uint64_t>(head->fitted_rows));
    h->set_holdout_samples(static_cast<uint64_t>(head->holdout_samples));
    h->set_holdout_vectors(static_cast<uint64_t>(head->holdout_rows));
    h->set_holdout_accuracy(head->holdout_accuracy());
    ToProto(head->fit_time, h->mutable_fit_time());
  }
}

void ToProto(const GalleryClassification& answer, size_t num_points, v1::ClassifyResponse* out) {
  out->set_label(answer.label);
  out->set_unknown(answer.unknown);
  out->set_confidence(answer.confidence);
  for (size_t i = 0; i < answer.knn.neighbors.size(); ++i) {
    const Neighbor& n = answer.knn.neighbors[i];
    v1::Neighbor* neighbor = out->add_neighbors();
    neighbor->set_sample_id(n.id);
    neighbor->set_label(n.label);
    neighbor->set_distance(n.distance);
    neighbor->set_view(static_cast<uint32_t>(n.view));
    if (i < answer.provenance.size() && answer.provenance[i] != nullptr) {
      neighbor->set_source(answer.provenance[i]->source);
      for (const auto& [key, value] : answer.provenance[i]->metadata) {
        (*neighbor->mutable_metadata())[key] = value;
      }
    }
  }
  for (const ClassVote& v : answer.knn.votes) {
    v1::ClassVote* vote = out->add_votes();
    vote->set_label(v.label);
    vote->set_weight(v.weight);
  }
  out->set_num_points(num_points);
  ToProto(answer.describe_time, out->mutable_describe_time());
  ToProto(answer.search_time, out->mutable_search_time());
  out->set_approximate(answer.knn.approximate);
  out->set_by_head(answer.by_head);
}

namespace {

// Values past INT_MAX become INT_MAX: still out of every range, so the check names them.
int ClampToInt(uint32_t value) {
  return static_cast<int>(std::min<uint32_t>(value, std::numeric_limits<int>::max()));
}

void ToProto(const Eigen::Vector3f& v, v1::Vector3* out) {
  out->set_x(v.x());
  out->set_y(v.y());
  out->set_z(v.z());
}

Eigen::Vector3f FromProto(const v1::Vector3& v) {
  return Eigen::Vector3d(v.x(), v.y(), v.z()).cast<float>();
}

}  // namespace

SceneSegmentationOptions FromProto(const v1::SceneSegmentation& segmentation,
                                   const v1::AxisAlignedBox* region) {
  SceneSegmentationOptions out;
  if (segmentation.has_max_planes()) out.max_planes = ClampToInt(segmentation.max_planes());
  if (segmentation.has_plane_distance()) out.plane_distance = segmentation.plane_distance();
  if (segmentation.has_min_plane_share()) out.min_plane_share = segmentation.min_plane_share();
  if (segmentation.has_plane_iterations()) {
    out.plane_iterations = ClampToInt(segmentation.plane_iterations());
  }
  if (segmentation.has_cluster_tolerance()) {
    out.cluster_tolerance = segmentation.cluster_tolerance();
  }
  if (segmentation.has_min_cluster_points()) {
    out.min_cluster_points = static_cast<size_t>(segmentation.min_cluster_points());
  }
  if (segmentation.has_max_cluster_points()) {
    out.max_cluster_points = static_cast<size_t>(segmentation.max_cluster_points());
  }
  if (segmentation.has_max_plane_tilt_degrees()) {
    out.max_plane_tilt_degrees = segmentation.max_plane_tilt_degrees();
  }
  out.seed = segmentation.seed();
  if (region != nullptr) {
    out.region = SceneSegmentationOptions::Box{FromProto(region->min()), FromProto(region->max())};
  }
  return out;
}

void ToProto(const SceneRecognition& scene, size_t num_points, bool with_indices,
             v1::RecognizeSceneResponse* out) {
  for (const RecognizedObject& object : scene.objects) {
    v1::SceneObject* found = out->add_objects();
    ToProto(object.classification, object.indices.size(), found->mutable_classification());
    ToProto(object.geometry.centroid, found->mutable_centroid());
    v1::OrientedBox* box = found->mutable_box();
    ToProto(object.geometry.box.center, box->mutable_center());
    const Eigen::Quaternionf rotation(object.geometry.box.axes);
    box->mutable_orientation()->set_x(rotation.x());
    box->mutable_orientation()->set_y(rotation.y());
    box->mutable_orientation()->set_z(rotation.z());
    box->mutable_orientation()->set_w(rotation.w());
    ToProto(object.geometry.box.size, box->mutable_size());
    if (with_indices)
      found->mutable_indices()->Assign(object.indices.begin(), object.indices.end());
    if (!object.status.ok()) found->set_error(std::string(object.status.message()));
  }
  for (const ScenePlane& plane : scene.segmentation.planes) {
    v1::ScenePlane* removed = out->add_planes();
    for (int i = 0; i < 4; ++i) removed->add_coefficients(plane.coefficients[i]);
    removed->set_num_points(plane.points);
  }
  out->set_num_points(num_points);
  out->set_non_finite_points(scene.segmentation.non_finite_points);
  out->set_outside_region(scene.segmentation.outside_region);
  out->set_in_small_clusters(scene.segmentation.in_small_clusters);
  out->set_in_large_clusters(scene.segmentation.in_large_clusters);
  ToProto(scene.segment_time, out->mutable_segment_time());
  ToProto(scene.classify_time, out->mutable_classify_time());
}

absl::Status ToProto(absl::Span<const DescriptorKind> kinds, v1::ListDescriptorsResponse* out) {
  for (const DescriptorKind& kind : kinds) {
    v1::DescriptorKind* described = out->add_descriptors();
    described->set_kind(kind.kind);
    described->set_summary(kind.summary);
    for (const DescriptorParam& p : kind.params) {
      v1::DescriptorParameter* param = described->add_parameters();
      param->set_name(p.name);
      param->set_default_value(p.default_value);
      param->set_help(p.help);
    }
    SHAPEID_ASSIGN_OR_RETURN(const std::unique_ptr<Descriptor> defaults,
                             CreateDescriptor(kind.kind));
    described->set_default_spec(defaults->spec().ToString());
    described->set_default_dimension(static_cast<uint32_t>(defaults->dimension()));
  }
  return absl::OkStatus();
}

}  // namespace shapeid
