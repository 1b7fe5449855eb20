#include "server/calls/cloud_rpcs.h"

#include <array>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "absl/time/time.h"
#include "core/descriptor_registry.h"
#include "core/gallery/gallery_registry.h"
#include "core/status_macros.h"
#include "server/calls/service_options.h"
#include "server/calls/stream_reactor.h"
#include "server/runtime/work_costs.h"
#include "server/wire/cloud_assembler.h"
#include "server/wire/proto_convert.h"

namespace shapeid {
namespace {

// The up direction a header's sensor frame turns the clouds towards: the descriptor's (+z
// without one: an incompatible gallery, refused when described).
std::array<float, 3> UpOf(const Descriptor* descriptor) {
  return descriptor != nullptr ? descriptor->up_direction() : std::array<float, 3>{0, 0, 1};
}

// The format of the clouds a header announces: its point layout, and its sensor frame turned
// towards the descriptor's up.
template <typename Header>
absl::StatusOr<WireCloudFormat> FormatOf(const Header& header, const Descriptor* descriptor) {
  WireCloudFormat format;
  SHAPEID_ASSIGN_OR_RETURN(format.layout, FromProto(header.layout()));
  SHAPEID_ASSIGN_OR_RETURN(format.frame, FromProto(header.sensor_frame(), UpOf(descriptor)));
  return format;
}

// The named gallery and its snapshot, which must hold samples to answer `doing`.
struct GalleryAndSnapshot {
  std::shared_ptr<Gallery> gallery;
  std::shared_ptr<const GallerySnapshot> snapshot;
};
absl::StatusOr<GalleryAndSnapshot> GalleryWithSamples(const ServiceRuntime& runtime,
                                                      CallRecord& record, const std::string& name,
                                                      absl::string_view doing) {
  GalleryAndSnapshot found;
  SHAPEID_ASSIGN_OR_RETURN(found.gallery, NamedGallery(runtime, record, name));
  found.snapshot = found.gallery->Snapshot();
  SHAPEID_RETURN_IF_ERROR(found.snapshot->CheckCompatible());
  SHAPEID_RETURN_IF_ERROR(found.snapshot->RequireSamples(doing));
  return found;
}

class TrainReactor final : public CloudAssemblingReactor<v1::TrainRequest, v1::TrainResponse> {
 public:
  TrainReactor(grpc::CallbackServerContext* context, const ServiceRuntime& runtime,
               absl::string_view method, grpc::ByteBuffer* response)
      : CloudAssemblingReactor(context, runtime, method, response) {
    StartReading();
  }

 private:
  absl::StatusOr<std::optional<Work>> OnMessage(const v1::TrainRequest& request) override {
    switch (request.kind_case()) {
      case v1::TrainRequest::kHeader:
        SHAPEID_RETURN_IF_ERROR(OnHeader(request.header()));
        return std::nullopt;
      case v1::TrainRequest::kSample: {
        if (batch_ == nullptr) {
          return absl::InvalidArgumentError("Train: the first message must be a TrainHeader");
        }
        const int64_t max_samples = runtime_.options->max_samples_per_train;
        if (max_samples > 0 && sample_headers_ >= max_samples) {
          return absl::ResourceExhaustedError(absl::StrCat(
              "Train: the stream carries more than ", max_samples,
              " samples, the limit per stream (max_samples_per_train); send them in several "
              "streams"));
        }
        ++sample_headers_;
        if (!assembler_.started()) {  // the first sample: nothing to describe yet
          sample_ = request.sample();
          SHAPEID_RETURN_IF_ERROR(assembler_.Start(sample_.expected_points(), format_));
          return std::nullopt;
        }
        return DescribeSample().Then(Work::Inline([this, sample = request.sample()] {
          sample_ = sample;
          return assembler_.Start(sample.expected_points(), format_);
        }));
      }
      case v1::TrainRequest::kPoints:
        if (batch_ == nullptr) {
          return absl::InvalidArgumentError("Train: the first message must be a TrainHeader");
        }
        if (!assembler_.started()) {
          return absl::InvalidArgumentError(
              absl::StrCat("Train: points after sample ", samples_, " without a SampleHeader"));
        }
        SHAPEID_RETURN_IF_ERROR(assembler_.Append(request.points().xyz()));
        call().record().points = static_cast<int64_t>(assembler_.points_received());
        return std::nullopt;
      case v1::TrainRequest::KIND_NOT_SET:
        break;
    }
    return absl::InvalidArgumentError("Train: a message with no header, sample or points");
  }

  absl::Status OnHeader(const v1::TrainHeader& header) {
    if (batch_ != nullptr) return absl::InvalidArgumentError("Train: a second TrainHeader");
    SHAPEID_ASSIGN_OR_RETURN(gallery_, NamedGallery(runtime_, call().record(), header.gallery()));
    const std::shared_ptr<const GallerySnapshot> snapshot = gallery_->Snapshot();
    SHAPEID_ASSIGN_OR_RETURN(format_, FormatOf(header, snapshot->shared_descriptor().get()));
    batch_ = std::make_unique<TrainBatch>(gallery_->NewBatch());
    augment_ = snapshot->options().augment;
    if (header.has_augmentation()) {
      SHAPEID_ASSIGN_OR_RETURN(augment_, FromProto(header.augmentation()));
      SHAPEID_RETURN_IF_ERROR(batch_->SetAugment(augment_));
    }
    return absl::OkStatus();
  }

  // Describes the sample whose points have all arrived into the batch.
  Work DescribeSample() {
    const std::shared_ptr<const Descriptor>& descriptor = gallery_->Snapshot()->shared_descriptor();
    // An incompatible gallery has no descriptor; AddSample refuses it with the reason.
    const WorkEstimate cost = descriptor != nullptr
                                  ? EstimateTrainSample(*descriptor, augment_, assembler_.points())
                                  : WorkEstimate{};
    return Work::Compute(cost.cpu, cost.memory, [this, descriptor] {
      auto cloud = assembler_.Finish();
      if (!cloud.ok()) {
        return absl::Status(cloud.status().code(),
                            absl::StrCat("sample ", samples_, ": ", cloud.status().message()));
      }
      const absl::Time start = absl::Now();
      SHAPEID_RETURN_IF_ERROR(batch_->AddSample(sample_.sample_id(), sample_.label(), *cloud,
                                                ProvenanceFromProto(sample_)));
      const absl::Duration elapsed = absl::Now() - start;
      if (descriptor != nullptr) {
        call().observer().Described(call().record(), descriptor->spec().kind, elapsed);
      }
      describe_time_ += elapsed;
      ++samples_;
      call().record().samples = samples_;
      return absl::OkStatus();
    });
  }

  absl::StatusOr<Work> OnEnd() override {
    if (batch_ == nullptr) {
      return absl::InvalidArgumentError("Train: the stream ended without a TrainHeader");
    }
    Work work =
        assembler_.started() ? DescribeSample() : Work::Inline([] { return absl::OkStatus(); });
    return std::move(work)
        .Then(Work::Inline([this] {
          return samples_ == 0 ? absl::InvalidArgumentError("Train: the stream carried no sample")
                               : absl::OkStatus();
        }))
        .Then(Work::Store(
            EstimateCommit(*gallery_->Snapshot(), sample_headers_ * (1 + augment_.views)), [this] {
              SHAPEID_ASSIGN_OR_RETURN(const CommitResult committed, batch_->Commit());
              response()->mutable_sample_ids()->Assign(committed.ids.begin(), committed.ids.end());
              response()->set_gallery_version(committed.version);
              response()->set_gallery_sample_count(
                  static_cast<uint64_t>(gallery_->Snapshot()->num_samples()));
              ToProto(describe_time_, response()->mutable_describe_time());
              return absl::OkStatus();
            }));
  }

  std::shared_ptr<Gallery> gallery_;
  std::unique_ptr<TrainBatch> batch_;
  AugmentOptions augment_;
  WireCloudFormat format_;
  v1::SampleHeader sample_;
  int64_t sample_headers_ = 0;
  int64_t samples_ = 0;
  absl::Duration describe_time_;
};

}  // namespace

absl::StatusOr<PointCloud> CloudInOneMessage(const ServiceRuntime& runtime,
                                             uint64_t expected_points,
                                             const WireCloudFormat& format, absl::string_view xyz) {
  CloudAssembler assembler(runtime.registry->limits().max_points_per_cloud);
  SHAPEID_RETURN_IF_ERROR(assembler.Start(expected_points, format));
  SHAPEID_RETURN_IF_ERROR(assembler.Append(xyz));
  return assembler.Finish();
}

absl::StatusOr<DescribeRpc::Plan> DescribeRpc::PlanOf(const ServiceRuntime& runtime,
                                                      const Header& header, CallRecord& record) {
  Plan plan;
  if (header.descriptor_spec().empty() && !header.gallery().empty()) {
    SHAPEID_ASSIGN_OR_RETURN(const std::shared_ptr<Gallery> gallery,
                             NamedGallery(runtime, record, header.gallery()));
    const std::shared_ptr<const GallerySnapshot> snapshot = gallery->Snapshot();
    SHAPEID_RETURN_IF_ERROR(snapshot->CheckCompatible());
    plan.descriptor = snapshot->shared_descriptor();
  } else {
    const std::string& spec = header.descriptor_spec().empty()
                                  ? runtime.options->default_descriptor_spec
                                  : header.descriptor_spec();
    SHAPEID_ASSIGN_OR_RETURN(std::unique_ptr<Descriptor> descriptor, CreateDescriptor(spec));
    plan.descriptor = std::move(descriptor);
  }
  SHAPEID_ASSIGN_OR_RETURN(plan.format, FormatOf(header, plan.descriptor.get()));
  return plan;
}

Work DescribeRpc::WorkOf(Plan plan, size_t points, CloudSource cloud, AdmittedCall& call,
                         Response* response) {
  const WorkEstimate cost = EstimateDescribe(*plan.descriptor, points);
  return Work::Compute(
      cost.cpu, cost.memory,
      [descriptor = std::move(plan.descriptor), cloud = std::move(cloud), &call, response] {
        SHAPEID_ASSIGN_OR_RETURN(const PointCloud received, cloud());
        const absl::Time start = absl::Now();
        std::vector<float> values;
        SHAPEID_RETURN_IF_ERROR(descriptor->Compute(received, &values));
        const absl::Duration elapsed = absl::Now() - start;
        call.observer().Described(call.record(), descriptor->spec().kind, elapsed);
        ToProto(elapsed, response->mutable_describe_time());
        response->set_descriptor_spec(descriptor->spec().ToString());
        response->mutable_values()->Assign(values.begin(), values.end());
        response->set_num_points(received.size());
        return absl::OkStatus();
      });
}

absl::StatusOr<ClassifyRpc::Plan> ClassifyRpc::PlanOf(const ServiceRuntime& runtime,
                                                      const Header& header, CallRecord& record) {
  SHAPEID_ASSIGN_OR_RETURN(GalleryAndSnapshot found,
                           GalleryWithSamples(runtime, record, header.gallery(), "classifying"));
  Plan plan;
  plan.limits = found.gallery->limits().cloud_limits();
  plan.snapshot = std::move(found.snapshot);
  SHAPEID_ASSIGN_OR_RETURN(plan.format, FormatOf(header, plan.snapshot->shared_descriptor().get()));
  plan.k = BoundedK(header.k());
  plan.mode = header.exact() ? SearchMode::kExact : SearchMode::kDefault;
  return plan;
}

Work ClassifyRpc::WorkOf(Plan plan, size_t points, CloudSource cloud, AdmittedCall& call,
                         Response* response) {
  const WorkEstimate cost = EstimateClassify(*plan.snapshot, points, plan.k);
  return Work::Compute(
      cost.cpu, cost.memory, [plan = std::move(plan), cloud = std::move(cloud), &call, response] {
        SHAPEID_ASSIGN_OR_RETURN(const PointCloud received, cloud());
        SHAPEID_ASSIGN_OR_RETURN(const GalleryClassification answer,
                                 plan.snapshot->Classify(received, plan.limits, plan.k, plan.mode));
        call.observer().Described(call.record(), plan.snapshot->shared_descriptor()->spec().kind,
                                  answer.describe_time);
        call.observer().Searched(call.record(), answer.knn.approximate, answer.search_time);
        ToProto(answer, received.size(), response);
        return call.HoldAnswer(*response, "fewer neighbors (k)");
      });
}

absl::StatusOr<RecognizeSceneRpc::Plan> RecognizeSceneRpc::PlanOf(const ServiceRuntime& runtime,
                                                                  const Header& header,
                                                                  CallRecord& record) {
  SHAPEID_ASSIGN_OR_RETURN(
      GalleryAndSnapshot found,
      GalleryWithSamples(runtime, record, header.gallery(), "recognizing scenes"));
  Plan plan;
  plan.snapshot = std::move(found.snapshot);
  SHAPEID_ASSIGN_OR_RETURN(plan.format.layout, FromProto(header.layout()));
  plan.format.layout.drop_nonfinite = false;
  const v1::SensorFrame& frame = header.sensor_frame();
  if (!frame.transform().empty() || !frame.up().empty()) {
    SHAPEID_ASSIGN_OR_RETURN(plan.options.frame_to_gallery,
                             FromProto(frame, UpOf(plan.snapshot->shared_descriptor().get())));
  }
  plan.options.segmentation =
      FromProto(header.segmentation(), header.has_region() ? &header.region() : nullptr);
  if (absl::Status s = ValidateSceneSegmentationOptions(plan.options.segmentation); !s.ok()) {
    return absl::InvalidArgumentError(absl::StrCat(record.method, ": ", s.message()));
  }
  plan.options.k = BoundedK(header.k());
  plan.options.mode = header.exact() ? SearchMode::kExact : SearchMode::kDefault;
  plan.options.limits = found.gallery->limits().cloud_limits();
  plan.return_indices = header.return_indices();
  return plan;
}

// Two steps, the second planned from the clusters the first found, so that a frame of
// thousands of objects goes to the heavy lane with its true cost. Both stop when the call's
// deadline passes or it is cancelled.
Work RecognizeSceneRpc::WorkOf(Plan plan, size_t points, CloudSource cloud, AdmittedCall& call,
                               Response* response) {
  struct Frame {
    Plan plan;
    PointCloud points;
    SceneSegmentation segmentation;
    absl::Duration segment_time;
  };
  auto frame = std::make_shared<Frame>();
  frame->plan = std::move(plan);
  frame->plan.options.interrupt = [&call] { return call.Interruption(); };
  const WorkEstimate segment = EstimateSceneSegmentation(points, frame->plan.options.segmentation);
  return Work::Compute(segment.cpu, segment.memory,
                       [frame, cloud = std::move(cloud)] {
                         SHAPEID_ASSIGN_OR_RETURN(frame->points, cloud());
                         const absl::Time start = absl::Now();
                         SHAPEID_ASSIGN_OR_RETURN(
                             frame->segmentation,
                             SegmentSceneForGallery(*frame->plan.snapshot, frame->points,
                                                    frame->plan.options));
                         frame->segment_time = absl::Now() - start;
                         return absl::OkStatus();
                       })
      .Then(Work::Planned(
          [frame] {
            return EstimateSceneObjects(*frame->plan.snapshot, frame->segmentation,
                                        frame->plan.options.k, frame->plan.return_indices);
          },
          [frame, &call, response] {
            const GallerySnapshot& snapshot = *frame->plan.snapshot;
            SHAPEID_ASSIGN_OR_RETURN(
                SceneRecognition recognized,
                ClassifySceneObjects(snapshot, frame->points, std::move(frame->segmentation),
                                     frame->plan.options));
            recognized.segment_time = frame->segment_time;
            const std::string& kind = snapshot.shared_descriptor()->spec().kind;
            for (const RecognizedObject& object : recognized.objects) {
              if (!object.status.ok()) continue;
              call.observer().Described(call.record(), kind, object.classification.describe_time);
              call.observer().Searched(call.record(), object.classification.knn.approximate,
                                       object.classification.search_time);
            }
            ToProto(recognized, frame->points.size(), frame->plan.return_indices, response);
            return call.HoldAnswer(*response,
                                   "fewer neighbors (k), no point indices, larger "
                                   "min_cluster_points or a smaller region");
          }));
}

grpc::ServerReadReactor<grpc::ByteBuffer>* TrainRpc::Start(grpc::CallbackServerContext* context,
                                                           const ServiceRuntime& runtime,
                                                           absl::string_view method,
                                                           grpc::ByteBuffer* response) {
  return new TrainReactor(context, runtime, method, response);
}

}  // namespace shapeid
