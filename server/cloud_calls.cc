#include "server/cloud_calls.h"

#include <algorithm>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "absl/time/time.h"
#include "core/descriptor_registry.h"
#include "core/gallery/gallery.h"
#include "core/gallery/gallery_registry.h"
#include "core/scene/scene_recognition.h"
#include "core/status_macros.h"
#include "server/authorization.h"
#include "server/cloud_assembler.h"
#include "server/proto_convert.h"
#include "server/service_options.h"
#include "server/stream_reactor.h"
#include "server/work_costs.h"

namespace shapeid {
namespace {

// Points in a one-message call's bytes, for its report and cost (a partial point counts
// nothing; the assembler refuses it).
int64_t PointsIn(const std::string& bytes, const WireCloudFormat& format) {
  return static_cast<int64_t>(bytes.size() / format.layout.point_step);
}

// The format of the clouds a header announces: its point layout, and its sensor frame turned
// towards the descriptor's up (+z without a descriptor: an incompatible gallery, refused later).
template <typename Header>
absl::StatusOr<WireCloudFormat> FormatOf(const Header& header, const Descriptor* descriptor) {
  WireCloudFormat format;
  SHAPEID_ASSIGN_OR_RETURN(format.layout, FromProto(header.layout()));
  SHAPEID_ASSIGN_OR_RETURN(
      format.frame,
      FromProto(header.sensor_frame(), descriptor != nullptr ? descriptor->up_direction()
                                                             : std::array<float, 3>{0, 0, 1}));
  return format;
}

// The cloud of a DescribeCloud or ClassifyCloud request: the streams' assembler with a single
// chunk, so the same checks and the same messages. Its memory is the call's (RunUnary holds
// the request's).
absl::StatusOr<PointCloud> CloudInOneMessage(const ServiceRuntime& runtime,
                                             uint64_t expected_points,
                                             const WireCloudFormat& format, absl::string_view xyz) {
  CloudAssembler assembler(runtime.registry->limits().max_points_per_cloud);
  SHAPEID_RETURN_IF_ERROR(assembler.Start(expected_points, format));
  SHAPEID_RETURN_IF_ERROR(assembler.Append(xyz));
  return assembler.Finish();
}

// The descriptor a DescribeHeader asks for, shared by the stream and the one-message call:
// its spec, else the named gallery's, else the server's default.
absl::StatusOr<std::shared_ptr<const Descriptor>> DescriptorToUse(const v1::DescribeHeader& header,
                                                                  const ServiceRuntime& runtime) {
  if (header.descriptor_spec().empty() && !header.gallery().empty()) {
    SHAPEID_ASSIGN_OR_RETURN(const std::shared_ptr<Gallery> gallery,
                             runtime.registry->Get(header.gallery()));
    return gallery->Snapshot()->shared_descriptor();
  }
  const std::string& spec = header.descriptor_spec().empty()
                                ? runtime.options->default_descriptor_spec
                                : header.descriptor_spec();
  SHAPEID_ASSIGN_OR_RETURN(std::unique_ptr<Descriptor> descriptor, CreateDescriptor(spec));
  return std::shared_ptr<const Descriptor>(std::move(descriptor));
}

Work DescribeWork(std::shared_ptr<const Descriptor> descriptor, size_t points,
                  std::function<absl::StatusOr<PointCloud>()> cloud, AdmittedCall& call,
                  v1::DescribeResponse* response) {
  const WorkEstimate cost = EstimateDescribe(*descriptor, points);
  return Work::Compute(cost.cpu, cost.memory, [descriptor, cloud, &call, response] {
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

// Classify's checks on its header, shared by the stream and the one-message call: the
// gallery exists and has samples (failing before the points are read, not after).
absl::StatusOr<std::shared_ptr<Gallery>> GalleryToClassify(const GalleryRegistry& registry,
                                                           const v1::ClassifyHeader& header) {
  SHAPEID_RETURN_IF_ERROR(RequireGalleryName("Classify", header.gallery()));
  SHAPEID_ASSIGN_OR_RETURN(std::shared_ptr<Gallery> gallery, registry.Get(header.gallery()));
  SHAPEID_RETURN_IF_ERROR(gallery->Snapshot()->RequireSamples("classifying"));
  return gallery;
}

// Describes and classifies the cloud `cloud` gives against the snapshot the gallery has when
// the work starts.
Work ClassifyWork(std::shared_ptr<Gallery> gallery, const v1::ClassifyHeader& header, size_t points,
                  std::function<absl::StatusOr<PointCloud>()> cloud, AdmittedCall& call,
                  v1::ClassifyResponse* response) {
  const int k = static_cast<int>(std::min<uint32_t>(header.k(), 1 << 20));
  const WorkEstimate cost = EstimateClassify(*gallery->Snapshot(), points, k);
  const SearchMode mode = header.exact() ? SearchMode::kExact : SearchMode::kDefault;
  return Work::Compute(cost.cpu, cost.memory, [gallery, k, mode, cloud, &call, response] {
    SHAPEID_ASSIGN_OR_RETURN(const PointCloud received, cloud());
    const std::shared_ptr<const GallerySnapshot> snapshot = gallery->Snapshot();
    SHAPEID_ASSIGN_OR_RETURN(
        const GalleryClassification answer,
        snapshot->Classify(received, gallery->limits().cloud_limits(), k, mode));
    call.observer().Described(call.record(), snapshot->shared_descriptor()->spec().kind,
                              answer.describe_time);
    call.observer().Searched(call.record(), answer.knn.approximate, answer.search_time);
    ToProto(answer, received.size(), response);
    return call.HoldAnswer(*response, "fewer neighbours (k)");
  });
}

// What a SceneHeader asks for, checked before any point is read: the gallery exists and has
// samples, and the layout, sensor frame and segmentation parameters are well formed.
struct SceneCall {
  std::shared_ptr<Gallery> gallery;
  SceneRecognitionOptions options;
  // The frame as sent: non-finite points kept (segmentation skips them) and no transform,
  // so that indices count every point sent and answers are in the frame's coordinates.
  WireCloudFormat format;
  bool return_indices = false;
};

absl::StatusOr<SceneCall> SceneCallOf(const GalleryRegistry& registry,
                                      const v1::SceneHeader& header) {
  SHAPEID_RETURN_IF_ERROR(RequireGalleryName("RecognizeScene", header.gallery()));
  SceneCall scene;
  SHAPEID_ASSIGN_OR_RETURN(scene.gallery, registry.Get(header.gallery()));
  const std::shared_ptr<const GallerySnapshot> snapshot = scene.gallery->Snapshot();
  SHAPEID_RETURN_IF_ERROR(snapshot->RequireSamples("recognizing scenes"));
  SHAPEID_ASSIGN_OR_RETURN(scene.format.layout, FromProto(header.layout()));
  scene.format.layout.drop_nonfinite = false;
  const v1::SensorFrame& frame = header.sensor_frame();
  if (!frame.transform().empty() || !frame.up().empty()) {
    const Descriptor* descriptor = snapshot->shared_descriptor().get();
    SHAPEID_ASSIGN_OR_RETURN(
        scene.options.frame_to_gallery,
        FromProto(frame, descriptor != nullptr ? descriptor->up_direction()
                                               : std::array<float, 3>{0, 0, 1}));
  }
  scene.options.segmentation =
      FromProto(header.segmentation(), header.has_region() ? &header.region() : nullptr);
  if (absl::Status s = ValidateSceneSegmentationOptions(scene.options.segmentation); !s.ok()) {
    return absl::InvalidArgumentError(absl::StrCat("RecognizeScene: ", s.message()));
  }
  scene.options.k = static_cast<int>(std::min<uint32_t>(header.k(), 1 << 20));
  scene.options.mode = header.exact() ? SearchMode::kExact : SearchMode::kDefault;
  scene.options.limits = scene.gallery->limits().cloud_limits();
  scene.return_indices = header.return_indices();
  return scene;
}

// Segments the frame `cloud` gives, then classifies its objects against the snapshot the
// gallery had when the segmentation started: two steps, the second planned from the
// clusters the first found, so that a frame of thousands of objects goes to the heavy lane
// with its true cost. Both stop when the call's deadline passes or it is cancelled.
Work SceneWork(SceneCall scene, size_t points, std::function<absl::StatusOr<PointCloud>()> cloud,
               AdmittedCall& call, v1::RecognizeSceneResponse* response) {
  struct Frame {
    SceneCall scene;
    PointCloud points;
    std::shared_ptr<const GallerySnapshot> snapshot;
    SceneSegmentation segmentation;
    absl::Duration segment_time;
  };
  auto frame = std::make_shared<Frame>();
  frame->scene = std::move(scene);
  frame->scene.options.interrupt = [&call] { return call.Interruption(); };
  const WorkEstimate segment = EstimateSceneSegmentation(points, frame->scene.options.segmentation);
  return Work::Compute(
             segment.cpu, segment.memory,
             [frame, cloud] {
               SHAPEID_ASSIGN_OR_RETURN(frame->points, cloud());
               frame->snapshot = frame->scene.gallery->Snapshot();
               const absl::Time start = absl::Now();
               SHAPEID_ASSIGN_OR_RETURN(
                   frame->segmentation,
                   SegmentSceneForGallery(*frame->snapshot, frame->points, frame->scene.options));
               frame->segment_time = absl::Now() - start;
               return absl::OkStatus();
             })
      .Then(Work::Planned(
          [frame] {
            return EstimateSceneObjects(*frame->snapshot, frame->segmentation,
                                        frame->scene.options.k, frame->scene.return_indices);
          },
          [frame, &call, response] {
            SHAPEID_ASSIGN_OR_RETURN(
                SceneRecognition recognized,
                ClassifySceneObjects(*frame->snapshot, frame->points,
                                     std::move(frame->segmentation), frame->scene.options));
            recognized.segment_time = frame->segment_time;
            const std::string& kind = frame->snapshot->shared_descriptor()->spec().kind;
            for (const RecognizedObject& object : recognized.objects) {
              if (!object.status.ok()) continue;
              call.observer().Described(call.record(), kind, object.classification.describe_time);
              call.observer().Searched(call.record(), object.classification.knn.approximate,
                                       object.classification.search_time);
            }
            ToProto(recognized, frame->points.size(), frame->scene.return_indices, response);
            return call.HoldAnswer(*response,
                                   "fewer neighbours (k), no point indices, larger "
                                   "min_cluster_points or a smaller region");
          }));
}

class DescribeReactor final : public StreamReactor<v1::DescribeRequest, v1::DescribeResponse> {
 public:
  DescribeReactor(grpc::CallbackServerContext* context, const ServiceRuntime& runtime,
                  grpc::ByteBuffer* response)
      : StreamReactor(context, runtime, SHAPEID_METHOD(Describe), response),
        runtime_(runtime),
        assembler_(runtime.registry->limits().max_points_per_cloud, runtime.budget,
                   call().caller()) {
    call().CountHeld([this] { return assembler_.held_bytes(); });
    StartReading();
  }

 private:
  absl::StatusOr<std::optional<Work>> OnMessage(const v1::DescribeRequest& request) override {
    switch (request.kind_case()) {
      case v1::DescribeRequest::kHeader:
        SHAPEID_RETURN_IF_ERROR(OnHeader(request.header()));
        return std::nullopt;
      case v1::DescribeRequest::kPoints:
        if (descriptor_ == nullptr) {
          return absl::InvalidArgumentError(
              "Describe: the first message must be a DescribeHeader; points came first");
        }
        SHAPEID_RETURN_IF_ERROR(assembler_.Append(request.points().xyz()));
        call().record().points = static_cast<int64_t>(assembler_.points_received());
        return std::nullopt;
      case v1::DescribeRequest::KIND_NOT_SET:
        break;
    }
    return absl::InvalidArgumentError("Describe: a message with neither header nor points");
  }

  absl::Status OnHeader(const v1::DescribeHeader& header) {
    if (descriptor_ != nullptr) {
      return absl::InvalidArgumentError("Describe: a second DescribeHeader in one stream");
    }
    if (header.descriptor_spec().empty()) call().record().gallery = header.gallery();
    SHAPEID_ASSIGN_OR_RETURN(descriptor_, DescriptorToUse(header, runtime_));
    SHAPEID_ASSIGN_OR_RETURN(const WireCloudFormat format, FormatOf(header, descriptor_.get()));
    return assembler_.Start(header.expected_points(), format);
  }

  absl::StatusOr<Work> OnEnd() override {
    if (descriptor_ == nullptr) {
      return absl::InvalidArgumentError("Describe: the stream ended without a DescribeHeader");
    }
    return DescribeWork(
        descriptor_, assembler_.points(), [this] { return assembler_.Finish(); }, call(),
        response());
  }

  const ServiceRuntime runtime_;
  CloudAssembler assembler_;
  std::shared_ptr<const Descriptor> descriptor_;
};

// One Train stream: TrainHeader, then samples (SampleHeader + PointChunks). Each sample is
// described on the scheduler as soon as its points are complete (the next SampleHeader, or
// the end); the batch commits only when the stream ends OK, so an error or a cut stream (the
// reactor dies without its end) publishes nothing.
class TrainReactor final : public StreamReactor<v1::TrainRequest, v1::TrainResponse> {
 public:
  TrainReactor(grpc::CallbackServerContext* context, const ServiceRuntime& runtime,
               grpc::ByteBuffer* response)
      : StreamReactor(context, runtime, SHAPEID_METHOD(Train), response),
        runtime_(runtime),
        assembler_(runtime.registry->limits().max_points_per_cloud, runtime.budget,
                   call().caller()) {
    call().CountHeld([this] { return assembler_.held_bytes(); });
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
    call().record().gallery = header.gallery();
    SHAPEID_RETURN_IF_ERROR(RequireGalleryName("Train", header.gallery()));
    SHAPEID_ASSIGN_OR_RETURN(gallery_, runtime_.registry->Get(header.gallery()));
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

  const ServiceRuntime runtime_;
  CloudAssembler assembler_;
  std::shared_ptr<Gallery> gallery_;
  std::unique_ptr<TrainBatch> batch_;
  AugmentOptions augment_;
  WireCloudFormat format_;
  v1::SampleHeader sample_;
  int64_t sample_headers_ = 0;
  int64_t samples_ = 0;
  absl::Duration describe_time_;
};

class ClassifyReactor final : public StreamReactor<v1::ClassifyRequest, v1::ClassifyResponse> {
 public:
  ClassifyReactor(grpc::CallbackServerContext* context, const ServiceRuntime& runtime,
                  grpc::ByteBuffer* response)
      : StreamReactor(context, runtime, SHAPEID_METHOD(Classify), response),
        runtime_(runtime),
        assembler_(runtime.registry->limits().max_points_per_cloud, runtime.budget,
                   call().caller()) {
    call().CountHeld([this] { return assembler_.held_bytes(); });
    StartReading();
  }

 private:
  absl::StatusOr<std::optional<Work>> OnMessage(const v1::ClassifyRequest& request) override {
    switch (request.kind_case()) {
      case v1::ClassifyRequest::kHeader: {
        if (gallery_ != nullptr) {
          return absl::InvalidArgumentError("Classify: a second ClassifyHeader");
        }
        call().record().gallery = request.header().gallery();
        SHAPEID_ASSIGN_OR_RETURN(gallery_, GalleryToClassify(*runtime_.registry, request.header()));
        header_ = request.header();
        SHAPEID_ASSIGN_OR_RETURN(
            const WireCloudFormat format,
            FormatOf(header_, gallery_->Snapshot()->shared_descriptor().get()));
        SHAPEID_RETURN_IF_ERROR(assembler_.Start(header_.expected_points(), format));
        return std::nullopt;
      }
      case v1::ClassifyRequest::kPoints:
        if (gallery_ == nullptr) {
          return absl::InvalidArgumentError(
              "Classify: the first message must be a ClassifyHeader; points came first");
        }
        SHAPEID_RETURN_IF_ERROR(assembler_.Append(request.points().xyz()));
        call().record().points = static_cast<int64_t>(assembler_.points_received());
        return std::nullopt;
      case v1::ClassifyRequest::KIND_NOT_SET:
        break;
    }
    return absl::InvalidArgumentError("Classify: a message with neither header nor points");
  }

  absl::StatusOr<Work> OnEnd() override {
    if (gallery_ == nullptr) {
      return absl::InvalidArgumentError("Classify: the stream ended without a ClassifyHeader");
    }
    return ClassifyWork(
        gallery_, header_, assembler_.points(), [this] { return assembler_.Finish(); }, call(),
        response());
  }

  const ServiceRuntime runtime_;
  CloudAssembler assembler_;
  std::shared_ptr<Gallery> gallery_;
  v1::ClassifyHeader header_;
};

class SceneReactor final
    : public StreamReactor<v1::RecognizeSceneRequest, v1::RecognizeSceneResponse> {
 public:
  SceneReactor(grpc::CallbackServerContext* context, const ServiceRuntime& runtime,
               grpc::ByteBuffer* response)
      : StreamReactor(context, runtime, SHAPEID_METHOD(RecognizeScene), response),
        runtime_(runtime),
        assembler_(runtime.registry->limits().max_points_per_cloud, runtime.budget,
                   call().caller()) {
    call().CountHeld([this] { return assembler_.held_bytes(); });
    StartReading();
  }

 private:
  absl::StatusOr<std::optional<Work>> OnMessage(const v1::RecognizeSceneRequest& request) override {
    switch (request.kind_case()) {
      case v1::RecognizeSceneRequest::kHeader: {
        if (scene_.has_value()) {
          return absl::InvalidArgumentError("RecognizeScene: a second SceneHeader");
        }
        call().record().gallery = request.header().gallery();
        SHAPEID_ASSIGN_OR_RETURN(scene_, SceneCallOf(*runtime_.registry, request.header()));
        SHAPEID_RETURN_IF_ERROR(
            assembler_.Start(request.header().expected_points(), scene_->format));
        return std::nullopt;
      }
      case v1::RecognizeSceneRequest::kPoints:
        if (!scene_.has_value()) {
          return absl::InvalidArgumentError(
              "RecognizeScene: the first message must be a SceneHeader; points came first");
        }
        SHAPEID_RETURN_IF_ERROR(assembler_.Append(request.points().xyz()));
        call().record().points = static_cast<int64_t>(assembler_.points_received());
        return std::nullopt;
      case v1::RecognizeSceneRequest::KIND_NOT_SET:
        break;
    }
    return absl::InvalidArgumentError("RecognizeScene: a message with neither header nor points");
  }

  absl::StatusOr<Work> OnEnd() override {
    if (!scene_.has_value()) {
      return absl::InvalidArgumentError("RecognizeScene: the stream ended without a SceneHeader");
    }
    return SceneWork(
        *std::move(scene_), assembler_.points(), [this] { return assembler_.Finish(); }, call(),
        response());
  }

  const ServiceRuntime runtime_;
  CloudAssembler assembler_;
  std::optional<SceneCall> scene_;
};

}  // namespace

grpc::ServerReadReactor<grpc::ByteBuffer>* StartDescribe(grpc::CallbackServerContext* context,
                                                         const ServiceRuntime& runtime,
                                                         grpc::ByteBuffer* response) {
  return new DescribeReactor(context, runtime, response);
}

grpc::ServerReadReactor<grpc::ByteBuffer>* StartTrain(grpc::CallbackServerContext* context,
                                                      const ServiceRuntime& runtime,
                                                      grpc::ByteBuffer* response) {
  return new TrainReactor(context, runtime, response);
}

grpc::ServerReadReactor<grpc::ByteBuffer>* StartClassify(grpc::CallbackServerContext* context,
                                                         const ServiceRuntime& runtime,
                                                         grpc::ByteBuffer* response) {
  return new ClassifyReactor(context, runtime, response);
}

grpc::ServerReadReactor<grpc::ByteBuffer>* StartRecognizeScene(grpc::CallbackServerContext* context,
                                                               const ServiceRuntime& runtime,
                                                               grpc::ByteBuffer* response) {
  return new SceneReactor(context, runtime, response);
}

absl::StatusOr<Work> DescribeCloud(const ServiceRuntime& runtime,
                                   const v1::DescribeCloudRequest& request,
                                   v1::DescribeResponse* response, AdmittedCall& call) {
  if (request.header().descriptor_spec().empty()) {
    call.record().gallery = request.header().gallery();
  }
  SHAPEID_ASSIGN_OR_RETURN(const std::shared_ptr<const Descriptor> descriptor,
                           DescriptorToUse(request.header(), runtime));
  SHAPEID_ASSIGN_OR_RETURN(WireCloudFormat format, FormatOf(request.header(), descriptor.get()));
  call.record().points = PointsIn(request.points().xyz(), format);
  return DescribeWork(
      descriptor, static_cast<size_t>(call.record().points),
      [&runtime, &request, format = std::move(format)] {
        return CloudInOneMessage(runtime, request.header().expected_points(), format,
                                 request.points().xyz());
      },
      call, response);
}

absl::StatusOr<Work> ClassifyCloud(const ServiceRuntime& runtime,
                                   const v1::ClassifyCloudRequest& request,
                                   v1::ClassifyResponse* response, AdmittedCall& call) {
  call.record().gallery = request.header().gallery();
  if (!request.has_header()) {
    return absl::InvalidArgumentError("ClassifyCloud: the request has no header");
  }
  SHAPEID_ASSIGN_OR_RETURN(const std::shared_ptr<Gallery> gallery,
                           GalleryToClassify(*runtime.registry, request.header()));
  SHAPEID_ASSIGN_OR_RETURN(
      WireCloudFormat format,
      FormatOf(request.header(), gallery->Snapshot()->shared_descriptor().get()));
  call.record().points = PointsIn(request.points().xyz(), format);
  return ClassifyWork(
      gallery, request.header(), static_cast<size_t>(call.record().points),
      [&runtime, &request, format = std::move(format)] {
        return CloudInOneMessage(runtime, request.header().expected_points(), format,
                                 request.points().xyz());
      },
      call, response);
}

absl::StatusOr<Work> RecognizeSceneCloud(const ServiceRuntime& runtime,
                                         const v1::RecognizeSceneCloudRequest& request,
                                         v1::RecognizeSceneResponse* response, AdmittedCall& call) {
  call.record().gallery = request.header().gallery();
  if (!request.has_header()) {
    return absl::InvalidArgumentError("RecognizeSceneCloud: the request has no header");
  }
  SHAPEID_ASSIGN_OR_RETURN(SceneCall scene, SceneCallOf(*runtime.registry, request.header()));
  call.record().points = PointsIn(request.points().xyz(), scene.format);
  WireCloudFormat format = scene.format;
  return SceneWork(
      std::move(scene), static_cast<size_t>(call.record().points),
      [&runtime, &request, format = std::move(format)] {
        return CloudInOneMessage(runtime, request.header().expected_points(), format,
                                 request.points().xyz());
      },
      call, response);
}

}  // namespace shapeid
