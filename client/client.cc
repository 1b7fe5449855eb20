#include "client/client.h"

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <limits>
#include <mutex>
#include <optional>
#include <thread>
#include <utility>

#include "absl/strings/ascii.h"
#include "absl/strings/cord.h"
#include "absl/strings/escaping.h"
#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/strip.h"
#include "client/client_channel.h"
#include "core/request_id.h"
#include "grpcpp/generic/generic_stub.h"

// The wire carries little-endian float32; the cloud's floats are copied as they are.
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__
#error "shapeid::Client copies floats verbatim: add a byte swap for big-endian hosts"
#endif

namespace shapeid {
namespace {

// A PointCloud as the default wire layout (packed little-endian float32 x y z; this client
// runs on little-endian hosts, as the server's tests do).
SensorCloud Packed(const PointCloud& cloud) {
  return {absl::string_view(reinterpret_cast<const char*>(cloud.data()), cloud.size() * 12), {}};
}

// Bytes a point takes in `layout` (12 for the default).
size_t PointStep(const v1::PointLayout& layout) {
  return layout.point_step() != 0 ? layout.point_step() : 12;
}

// Writes a request stream so that a small cloud leaves in one flush: messages are held back
// one step, headers carry buffer_hint, the last message goes with WriteLast (which also
// half-closes). With the context's initial metadata corked, a header plus one chunk is a
// single write to the transport (docs/performance.md).
template <typename Request>
class StreamWriter {
 public:
  explicit StreamWriter(grpc::ClientWriter<Request>* writer) : writer_(writer) {}

  void Push(Request request, bool buffer) {
    Flush();
    pending_ = std::move(request);
    pending_buffer_ = buffer;
  }

  // Sends the held message as the last one. Finish() reports what went wrong, if anything.
  void Close() {
    if (!open_) return;
    if (pending_) {
      // WriteLast, keeping the result (WriteLast itself returns void).
      open_ = writer_->Write(*pending_, grpc::WriteOptions().set_last_message());
      pending_.reset();
    } else {
      writer_->WritesDone();
    }
  }

 private:
  void Flush() {
    if (!pending_ || !open_) return;
    grpc::WriteOptions options;
    if (pending_buffer_) options.set_buffer_hint();
    open_ = writer_->Write(*pending_, options);
    pending_.reset();
  }

  grpc::ClientWriter<Request>* writer_;
  std::optional<Request> pending_;
  bool pending_buffer_ = false;
  bool open_ = true;
};

// Pushes `cloud` as PointChunk messages of at most `chunk_points` points' bytes.
template <typename Request>
void PushCloud(StreamWriter<Request>& writer, const SensorCloud& cloud, size_t chunk_points) {
  const size_t chunk_bytes = chunk_points * PointStep(cloud.layout);
  for (size_t first = 0; first < cloud.data.size(); first += chunk_bytes) {
    Request request;
    const absl::string_view chunk = cloud.data.substr(first, chunk_bytes);
    request.mutable_points()->set_xyz(chunk.data(), chunk.size());
    writer.Push(std::move(request), /*buffer=*/false);
  }
}

// Marks a status as IsClientReceiveLimit's.
constexpr char kClientReceiveLimitUrl[] = "shapeid.client/receive-limit";

// gRPC's refusal of an answer over this channel's receive limit, "Received message larger
// than max (N vs. M)", reads like the same refusal by a server of a request too large for
// it; M being this client's limit tells them apart (this client's requests are chunks far
// below any server's limit). OK for any other status.
absl::Status ClientReceiveLimitStatus(const grpc::Status& status, size_t limit) {
  constexpr absl::string_view kPrefix = "Received message larger than max (";
  const std::string text = status.error_message();  // a copy: gRPC returns it by value
  absl::string_view message = text;
  if (status.error_code() != grpc::StatusCode::RESOURCE_EXHAUSTED ||
      !absl::ConsumePrefix(&message, kPrefix) || !absl::ConsumeSuffix(&message, ")")) {
    return absl::OkStatus();
  }
  const size_t vs = message.find(" vs. ");
  uint64_t size = 0, max = 0;
  if (vs == absl::string_view::npos || !absl::SimpleAtoi(message.substr(0, vs), &size) ||
      !absl::SimpleAtoi(message.substr(vs + 5), &max) || max != limit) {
    return absl::OkStatus();
  }
  absl::Status refused = absl::ResourceExhaustedError(absl::StrCat(
      "the server's answer is ", size, " bytes, more than this client's receive limit of ", max,
      " bytes: this client refused it, not the server; ask for less (a smaller page, fewer "
      "neighbors)"));
  refused.SetPayload(kClientReceiveLimitUrl, absl::Cord(absl::StrCat(size)));
  return refused;
}

}  // namespace

uint64_t PointsIn(absl::string_view data, const v1::PointLayout& layout) {
  const uint64_t step = PointStep(layout);
  if (layout.width() == 0 || layout.row_step() == 0) return data.size() / step;
  const uint64_t rows = data.size() / layout.row_step();
  const uint64_t rest = data.size() % layout.row_step();
  return rows * layout.width() + std::min<uint64_t>(rest / step, layout.width());
}

absl::Status FromGrpcStatus(const grpc::Status& status) {
  if (status.ok()) return absl::OkStatus();
  return absl::Status(static_cast<absl::StatusCode>(status.error_code()), status.error_message());
}

bool IsClientReceiveLimit(const absl::Status& status) {
  return absl::IsResourceExhausted(status) && status.GetPayload(kClientReceiveLimitUrl).has_value();
}

absl::Status CheckRequestId(absl::string_view id) {
  constexpr char kRule[] = "a request id is 1 to 128 characters of A-Z a-z 0-9 . _ : / + = -";
  if (id.empty() || id.size() > kMaxRequestIdChars) {
    return absl::InvalidArgumentError(
        absl::StrCat("the request id has ", id.size(), " characters: ", kRule));
  }
  for (char c : id) {
    if (!IsRequestIdChar(c)) {
      return absl::InvalidArgumentError(absl::StrCat("the request id \"", absl::CHexEscape(id),
                                                     "\" holds '", absl::CHexEscape({&c, 1}),
                                                     "': ", kRule));
    }
  }
  return absl::OkStatus();
}

absl::StatusOr<std::unique_ptr<Client>> Client::Connect(ClientOptions options) {
  if (options.target.empty()) return absl::InvalidArgumentError("ClientOptions.target is empty");
  if (options.max_attempts < 1) {
    return absl::InvalidArgumentError(
        absl::StrCat("ClientOptions.max_attempts must be >= 1, got ", options.max_attempts));
  }
  if (options.chunk_points < 1) {
    return absl::InvalidArgumentError("ClientOptions.chunk_points must be >= 1");
  }
  if (options.max_receive_bytes < 1 ||
      options.max_receive_bytes > static_cast<size_t>(std::numeric_limits<int>::max())) {
    return absl::InvalidArgumentError(absl::StrCat(
        "ClientOptions.max_receive_bytes must be 1 to 2^31 - 1, got ", options.max_receive_bytes));
  }
  if (options.deadline <= absl::ZeroDuration()) {
    return absl::InvalidArgumentError(absl::StrCat("ClientOptions.deadline must be positive, got ",
                                                   absl::FormatDuration(options.deadline)));
  }
  // Metadata values are visible ASCII; anything else would fail every call obscurely. The
  // message does not quote the key.
  for (char c : options.api_key) {
    if (c <= ' ' || c == 0x7f) {
      return absl::InvalidArgumentError(
          "the API key holds a space, a line break or another character metadata cannot carry "
          "(a stray newline from a file?)");
    }
  }
  if (!options.request_id.empty()) {
    if (absl::Status id = CheckRequestId(options.request_id); !id.ok()) return id;
  }
  if (!options.caller_id.empty() && !IsValidCallerId(options.caller_id)) {
    return absl::InvalidArgumentError(
        absl::StrCat("caller id '", options.caller_id,
                     "': a caller id is 1 to 64 characters of A-Z a-z 0-9 . _ : -"));
  }
  absl::StatusOr<std::shared_ptr<grpc::Channel>> channel = MakeChannel(options);
  if (!channel.ok()) return channel.status();
  return std::unique_ptr<Client>(new Client(std::move(options), *std::move(channel)));
}

Client::Client(ClientOptions options, std::shared_ptr<grpc::Channel> channel)
    : options_(std::move(options)),
      authorization_(options_.api_key.empty() ? "" : absl::StrCat("Bearer ", options_.api_key)),
      channel_(std::move(channel)),
      stub_(v1::ShapeId::NewStub(channel_)) {}

Client::~Client() = default;

template <typename Attempt>
absl::Status Client::Call(bool retry, bool corked, const Attempt& attempt,
                          const std::function<bool()>& may_retry) {
  const absl::Time deadline = absl::Now() + options_.deadline;
  absl::Duration backoff = options_.initial_backoff;
  const int attempts = retry ? options_.max_attempts : 1;
  grpc::Status status;
  for (int i = 0; i < attempts; ++i) {
    if (i > 0) {
      if (may_retry && !may_retry()) break;
      if (absl::Now() + backoff >= deadline) break;  // the last answer stands
      std::this_thread::sleep_for(absl::ToChronoNanoseconds(backoff));
      backoff *= 2;
    }
    grpc::ClientContext context;
    context.set_deadline(absl::ToChronoTime(deadline));
    if (!authorization_.empty()) context.AddMetadata("authorization", authorization_);
    if (!options_.request_id.empty()) context.AddMetadata("x-request-id", options_.request_id);
    if (!options_.caller_id.empty()) {
      context.AddMetadata(std::string(kCallerIdMetadata), options_.caller_id);
    }
    if (corked) context.set_initial_metadata_corked(true);
    status = attempt(context);
    // CANCELLED too: this client cancels only calls it then stops (a failing export sink, an
    // import), so a CANCELLED here comes from a server that stopped before serving the call
    // (a shutdown cancels what it had not started), which another replica can serve.
    // Never RESOURCE_EXHAUSTED, busy or not (ClientOptions::max_attempts says why).
    if (status.error_code() != grpc::StatusCode::UNAVAILABLE &&
        status.error_code() != grpc::StatusCode::CANCELLED) {
      break;
    }
  }
  if (absl::Status refused = ClientReceiveLimitStatus(status, options_.max_receive_bytes);
      !refused.ok()) {
    return refused;
  }
  return FromGrpcStatus(status);
}

template <typename Request, typename Response, typename Open>
absl::StatusOr<Response> Client::SingleCloudCall(Open open, const Request& header,
                                                 const SensorCloud& cloud) {
  Response response;
  absl::Status status = Call(true, true, [&](grpc::ClientContext& context) {
    response.Clear();
    auto writer = open(&context, &response);
    StreamWriter<Request> stream(writer.get());
    stream.Push(Request(header), /*buffer=*/true);
    PushCloud(stream, cloud, options_.chunk_points);
    stream.Close();
    return writer->Finish();
  });
  if (!status.ok()) return status;
  return response;
}

template <typename OneMessage, typename StreamRequest, typename Response, typename Header,
          typename Unary, typename Open>
absl::StatusOr<Response> Client::CloudCall(const Header& header, const SensorCloud& cloud,
                                           Unary unary, Open open, std::atomic<bool>& lacks_unary) {
  if (cloud.data.size() <= options_.chunk_points * PointStep(cloud.layout) &&
      !lacks_unary.load(std::memory_order_relaxed)) {
    OneMessage request;
    *request.mutable_header() = header;
    request.mutable_points()->set_xyz(cloud.data.data(), cloud.data.size());
    Response response;
    const absl::Status status = Call(true, false, [&](grpc::ClientContext& context) {
      response.Clear();
      return unary(&context, request, &response);
    });
    if (status.ok()) return response;
    if (status.code() != absl::StatusCode::kUnimplemented) return status;
    lacks_unary.store(true, std::memory_order_relaxed);
  }
  StreamRequest first;
  *first.mutable_header() = header;
  return SingleCloudCall<StreamRequest, Response>(open, first, cloud);
}

absl::StatusOr<v1::DescribeResponse> Client::Describe(const PointCloud& cloud,
                                                      const std::string& spec,
                                                      const std::string& gallery) {
  DescribeOptions options;
  options.spec = spec;
  options.gallery = gallery;
  return Describe(Packed(cloud), options);
}

absl::StatusOr<v1::DescribeResponse> Client::Describe(const PointCloud& cloud,
                                                      const DescribeOptions& options) {
  return Describe(Packed(cloud), options);
}

absl::StatusOr<v1::DescribeResponse> Client::Describe(const SensorCloud& cloud,
                                                      const DescribeOptions& options) {
  v1::DescribeHeader header;
  header.set_descriptor_spec(options.spec);
  header.set_gallery(options.gallery);
  header.set_expected_points(PointsIn(cloud.data, cloud.layout));
  *header.mutable_layout() = cloud.layout;
  *header.mutable_sensor_frame() = options.sensor_frame;
  return CloudCall<v1::DescribeCloudRequest, v1::DescribeRequest, v1::DescribeResponse>(
      header, cloud,
      [&](grpc::ClientContext* context, const v1::DescribeCloudRequest& request,
          v1::DescribeResponse* response) {
        return stub_->DescribeCloud(context, request, response);
      },
      [&](grpc::ClientContext* context, v1::DescribeResponse* response) {
        return stub_->Describe(context, response);
      },
      server_lacks_one_message_calls_);
}

absl::StatusOr<v1::ClassifyResponse> Client::Classify(const std::string& gallery,
                                                      const PointCloud& cloud, uint32_t k) {
  ClassifyOptions options;
  options.k = k;
  return Classify(gallery, cloud, options);
}

absl::StatusOr<v1::ClassifyResponse> Client::Classify(const std::string& gallery,
                                                      const PointCloud& cloud,
                                                      const ClassifyOptions& options) {
  return Classify(gallery, Packed(cloud), options);
}

absl::StatusOr<v1::ClassifyResponse> Client::Classify(const std::string& gallery,
                                                      const SensorCloud& cloud,
                                                      const ClassifyOptions& options) {
  v1::ClassifyHeader header;
  header.set_gallery(gallery);
  header.set_k(options.k);
  header.set_exact(options.exact);
  header.set_expected_points(PointsIn(cloud.data, cloud.layout));
  *header.mutable_layout() = cloud.layout;
  *header.mutable_sensor_frame() = options.sensor_frame;
  return CloudCall<v1::ClassifyCloudRequest, v1::ClassifyRequest, v1::ClassifyResponse>(
      header, cloud,
      [&](grpc::ClientContext* context, const v1::ClassifyCloudRequest& request,
          v1::ClassifyResponse* response) {
        return stub_->ClassifyCloud(context, request, response);
      },
      [&](grpc::ClientContext* context, v1::ClassifyResponse* response) {
        return stub_->Classify(context, response);
      },
      server_lacks_one_message_calls_);
}

absl::StatusOr<v1::RecognizeSceneResponse> Client::RecognizeScene(const std::string& gallery,
                                                                  const PointCloud& frame,
                                                                  const SceneOptions& options) {
  return RecognizeScene(gallery, Packed(frame), options);
}

absl::StatusOr<v1::RecognizeSceneResponse> Client::RecognizeScene(const std::string& gallery,
                                                                  const SensorCloud& frame,
                                                                  const SceneOptions& options) {
  v1::SceneHeader header;
  header.set_gallery(gallery);
  header.set_k(options.k);
  header.set_exact(options.exact);
  header.set_expected_points(PointsIn(frame.data, frame.layout));
  *header.mutable_layout() = frame.layout;
  *header.mutable_sensor_frame() = options.sensor_frame;
  *header.mutable_segmentation() = options.segmentation;
  if (options.region) *header.mutable_region() = *options.region;
  header.set_return_indices(options.return_indices);
  return CloudCall<v1::RecognizeSceneCloudRequest, v1::RecognizeSceneRequest,
                   v1::RecognizeSceneResponse>(
      header, frame,
      [&](grpc::ClientContext* context, const v1::RecognizeSceneCloudRequest& request,
          v1::RecognizeSceneResponse* response) {
        return stub_->RecognizeSceneCloud(context, request, response);
      },
      [&](grpc::ClientContext* context, v1::RecognizeSceneResponse* response) {
        return stub_->RecognizeScene(context, response);
      },
      server_lacks_one_message_scene_call_);
}

absl::StatusOr<v1::TrainResponse> Client::Train(const std::string& gallery,
                                                absl::Span<const TrainSample> samples) {
  return Train(gallery, samples, TrainOptions());
}

absl::StatusOr<v1::TrainResponse> Client::Train(const std::string& gallery,
                                                absl::Span<const TrainSample> samples,
                                                const TrainOptions& options) {
  std::vector<WireSample> wire;
  wire.reserve(samples.size());
  for (size_t i = 0; i < samples.size(); ++i) {
    if (samples[i].cloud == nullptr) {
      return absl::InvalidArgumentError(absl::StrCat("Train: sample ", i, " has no cloud"));
    }
    wire.push_back({&samples[i].label, samples[i].sample_id, Packed(*samples[i].cloud),
                    &samples[i].source, &samples[i].metadata});
  }
  return TrainWire(gallery, v1::PointLayout(), wire, options);
}

absl::StatusOr<v1::TrainResponse> Client::Train(const std::string& gallery,
                                                const v1::PointLayout& layout,
                                                absl::Span<const SensorTrainSample> samples,
                                                const TrainOptions& options) {
  std::vector<WireSample> wire;
  wire.reserve(samples.size());
  for (const SensorTrainSample& sample : samples) {
    wire.push_back({&sample.label, sample.sample_id, SensorCloud{sample.data, layout},
                    &sample.source, &sample.metadata});
  }
  return TrainWire(gallery, layout, wire, options);
}

absl::StatusOr<v1::TrainResponse> Client::TrainWire(const std::string& gallery,
                                                    const v1::PointLayout& layout,
                                                    const std::vector<WireSample>& samples,
                                                    const TrainOptions& options) {
  bool all_ids = true;
  for (const WireSample& sample : samples) all_ids = all_ids && sample.sample_id != 0;
  v1::TrainResponse response;
  int attempts = 0;
  absl::Status status = Call(all_ids, true, [&](grpc::ClientContext& context) {
    ++attempts;
    response.Clear();
    auto writer = stub_->Train(&context, &response);
    StreamWriter<v1::TrainRequest> stream(writer.get());
    v1::TrainRequest header;
    header.mutable_header()->set_gallery(gallery);
    *header.mutable_header()->mutable_layout() = layout;
    *header.mutable_header()->mutable_sensor_frame() = options.sensor_frame;
    stream.Push(std::move(header), /*buffer=*/true);
    for (const WireSample& sample : samples) {
      v1::TrainRequest start;
      start.mutable_sample()->set_label(*sample.label);
      start.mutable_sample()->set_sample_id(sample.sample_id);
      start.mutable_sample()->set_expected_points(PointsIn(sample.cloud.data, layout));
      start.mutable_sample()->set_source(*sample.source);
      start.mutable_sample()->mutable_metadata()->insert(sample.metadata->begin(),
                                                         sample.metadata->end());
      stream.Push(std::move(start), /*buffer=*/true);
      PushCloud(stream, sample.cloud, options_.chunk_points);
    }
    stream.Close();
    return writer->Finish();
  });
  if (absl::IsAlreadyExists(status) && attempts > 1) {
    // A retry follows an attempt that got no answer: it may have committed all the same.
    // Not proof enough to call it success (another call may hold these ids), so say so.
    return absl::AlreadyExistsError(
        absl::StrCat(status.message(),
                     " (an earlier attempt of this Train got no answer and may have committed "
                     "these samples: check the gallery before training them again)"));
  }
  if (!status.ok()) return status;
  return response;
}

absl::StatusOr<v1::Gallery> Client::CreateGallery(const v1::CreateGalleryRequest& request) {
  v1::Gallery response;
  absl::Status status = Call(false, false, [&](grpc::ClientContext& context) {
    return stub_->CreateGallery(&context, request, &response);
  });
  if (!status.ok()) return status;
  return response;
}

absl::StatusOr<v1::Gallery> Client::GetGallery(const std::string& name) {
  v1::GetGalleryRequest request;
  request.set_name(name);
  v1::Gallery response;
  absl::Status status = Call(true, false, [&](grpc::ClientContext& context) {
    return stub_->GetGallery(&context, request, &response);
  });
  if (!status.ok()) return status;
  return response;
}

absl::StatusOr<std::vector<v1::Gallery>> Client::ListGalleries() {
  v1::ListGalleriesResponse response;
  absl::Status status = Call(true, false, [&](grpc::ClientContext& context) {
    return stub_->ListGalleries(&context, v1::ListGalleriesRequest(), &response);
  });
  if (!status.ok()) return status;
  return std::vector<v1::Gallery>(response.galleries().begin(), response.galleries().end());
}

absl::StatusOr<uint64_t> Client::DeleteGallery(const std::string& name) {
  v1::DeleteGalleryRequest request;
  request.set_name(name);
  v1::DeleteGalleryResponse response;
  absl::Status status = Call(false, false, [&](grpc::ClientContext& context) {
    return stub_->DeleteGallery(&context, request, &response);
  });
  if (!status.ok()) return status;
  return response.samples_deleted();
}

absl::StatusOr<v1::RemoveSamplesResponse> Client::RemoveSamples(
    const std::string& gallery, absl::Span<const uint64_t> sample_ids,
    absl::Span<const std::string> labels) {
  v1::RemoveSamplesRequest request;
  request.set_gallery(gallery);
  request.mutable_sample_ids()->Add(sample_ids.begin(), sample_ids.end());
  for (const std::string& label : labels) request.add_labels(label);
  v1::RemoveSamplesResponse response;
  absl::Status status = Call(false, false, [&](grpc::ClientContext& context) {
    return stub_->RemoveSamples(&context, request, &response);
  });
  if (!status.ok()) return status;
  return response;
}

absl::StatusOr<v1::ListSamplesResponse> Client::ListSamples(const v1::ListSamplesRequest& request) {
  v1::ListSamplesResponse response;
  absl::Status status = Call(true, false, [&](grpc::ClientContext& context) {
    return stub_->ListSamples(&context, request, &response);
  });
  if (!status.ok()) return status;
  return response;
}

absl::StatusOr<std::vector<v1::DescriptorKind>> Client::ListDescriptors() {
  v1::ListDescriptorsResponse response;
  absl::Status status = Call(true, false, [&](grpc::ClientContext& context) {
    return stub_->ListDescriptors(&context, v1::ListDescriptorsRequest(), &response);
  });
  if (!status.ok()) return status;
  return std::vector<v1::DescriptorKind>(response.descriptors().begin(),
                                         response.descriptors().end());
}

absl::StatusOr<v1::ServerStats> Client::GetServerStats() {
  v1::ServerStats response;
  absl::Status status = Call(true, false, [&](grpc::ClientContext& context) {
    return stub_->GetServerStats(&context, v1::GetServerStatsRequest(), &response);
  });
  if (!status.ok()) return status;
  return response;
}

absl::StatusOr<v1::SetLogLevelResponse> Client::SetLogLevel(absl::string_view level) {
  v1::SetLogLevelRequest request;
  request.set_level(std::string(level));
  v1::SetLogLevelResponse response;
  // Retried: a repeated attempt sets the same level again. Its previous_level is then the
  // new level if the lost attempt had committed; the level itself is right either way.
  absl::Status status = Call(true, false, [&](grpc::ClientContext& context) {
    return stub_->SetLogLevel(&context, request, &response);
  });
  if (!status.ok()) return status;
  return response;
}

absl::Status Client::ExportGallery(
    const std::string& name,
    const std::function<absl::Status(const v1::GalleryExportChunk&)>& sink) {
  v1::ExportGalleryRequest request;
  request.set_name(name);
  bool delivered = false;  // a chunk reached the sink: a retry would repeat it
  absl::Status sink_error;
  absl::Status status = Call(
      true, false,
      [&](grpc::ClientContext& context) {
        auto reader = stub_->ExportGallery(&context, request);
        v1::GalleryExportChunk chunk;
        while (reader->Read(&chunk)) {
          delivered = true;
          sink_error = sink(chunk);
          if (!sink_error.ok()) {
            context.TryCancel();
            break;
          }
        }
        return reader->Finish();
      },
      [&] { return !delivered; });
  if (!sink_error.ok()) return sink_error;
  return status;
}

absl::StatusOr<v1::Gallery> Client::ImportGallery(
    const std::function<absl::StatusOr<bool>(v1::GalleryExportChunk*)>& source,
    const std::string& new_name) {
  v1::Gallery response;
  absl::Status source_error;
  absl::Status status = Call(false, false, [&](grpc::ClientContext& context) {
    auto writer = stub_->ImportGallery(&context, &response);
    v1::ImportGalleryRequest request;
    request.set_name(new_name);  // read from the first message only
    for (bool open = true; open;) {
      absl::StatusOr<bool> more = source(request.mutable_chunk());
      if (!more.ok()) {
        // Cancel rather than half-close: the server must not take what was sent so far for
        // a whole export (it would fail it anyway, but as truncated, not with our reason).
        source_error = more.status();
        context.TryCancel();
        return writer->Finish();
      }
      if (!*more) break;
      open = writer->Write(request);  // false: the server has answered (an error)
      request.Clear();
    }
    writer->WritesDone();
    return writer->Finish();
  });
  if (!source_error.ok()) return source_error;
  if (!status.ok()) return status;
  return response;
}

absl::Status Client::CheckHealth() {
  // No generated health stub ships with libgrpc++-dev: a generic call with hand-encoded
  // messages. Request: empty (service "": the whole server). Reply: field 1 (status) varint.
  grpc::GenericStub generic(channel_);
  std::string reply_bytes;
  absl::Status status = Call(true, false, [&](grpc::ClientContext& context) {
    grpc::Slice empty("");
    grpc::ByteBuffer request(&empty, 1);
    grpc::ByteBuffer reply;
    std::mutex mu;
    std::condition_variable cv;
    bool done = false;
    grpc::Status result;
    generic.UnaryCall(&context, "/grpc.health.v1.Health/Check", grpc::StubOptions(), &request,
                      &reply, [&](grpc::Status s) {
                        std::lock_guard<std::mutex> lock(mu);
                        result = std::move(s);
                        done = true;
                        cv.notify_one();
                      });
    std::unique_lock<std::mutex> lock(mu);
    cv.wait(lock, [&] { return done; });
    reply_bytes.clear();
    std::vector<grpc::Slice> slices;
    if (result.ok() && reply.Dump(&slices).ok()) {
      for (const grpc::Slice& s : slices) {
        reply_bytes.append(reinterpret_cast<const char*>(s.begin()), s.size());
      }
    }
    return result;
  });
  if (!status.ok()) return status;
  if (reply_bytes != std::string("\x08\x01", 2)) {  // status: SERVING
    return absl::UnavailableError(
        absl::StrCat("shapeid server at ", options_.target, " is not serving"));
  }
  return absl::OkStatus();
}

}  // namespace shapeid
