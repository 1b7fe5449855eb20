#ifndef SHAPEID_CLIENT_CLIENT_H_
#define SHAPEID_CLIENT_CLIENT_H_

// The C++ client of a shapeid server (the ShapeId service of proto/shapeid/v1/shapeid.proto).
//
//   shapeid::ClientOptions options;
//   options.target = "recognizer:50051";
//   auto client = shapeid::Client::Connect(options);
//   if (!client.ok()) ...
//   absl::StatusOr<shapeid::v1::ClassifyResponse> result = (*client)->Classify("parts", cloud);
//
// Results are the service's response messages (shapeid/v1/shapeid.pb.h): every field is
// documented in the proto. Errors are the server's gRPC status as an absl::Status with the same
// code and message (INVALID_ARGUMENT, NOT_FOUND, ALREADY_EXISTS, ...; see the proto's header),
// or UNAVAILABLE / DEADLINE_EXCEEDED from the transport, or RESOURCE_EXHAUSTED from this
// client for an answer over ClientOptions::max_receive_bytes (IsClientReceiveLimit). A failed
// call changes nothing on the server.
//
// Thread safety: a Client is safe to share; any number of threads may call any method at
// once. Calls block the calling thread until the reply, the error or the deadline.

#include <atomic>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "absl/types/span.h"
#include "client/client_options.h"
#include "core/point_cloud.h"
#include "grpcpp/grpcpp.h"
#include "shapeid/v1/shapeid.grpc.pb.h"
#include "shapeid/v1/shapeid.pb.h"

namespace shapeid {

// One labeled cloud for Train. The cloud is borrowed: it must outlive the Train call.
struct TrainSample {
  std::string label;
  // Client-chosen id, unique in the gallery; 0 lets the server choose (and disables retries).
  uint64_t sample_id = 0;
  const PointCloud* cloud = nullptr;
  // Optional provenance, returned with the sample as a neighbor and by ListSamples: where
  // the cloud came from (a file path, a URI) and small key/value pairs (SampleHeader's
  // limits: 4,096 bytes of source, 64 pairs, 4,096 bytes of keys and values).
  std::string source = {};
  std::map<std::string, std::string> metadata = {};
};

// One labeled cloud for Train in a sensor's own layout (given once per call): its bytes,
// borrowed.
struct SensorTrainSample {
  std::string label;
  uint64_t sample_id = 0;  // as in TrainSample
  absl::string_view data;
  std::string source = {};  // as in TrainSample
  std::map<std::string, std::string> metadata = {};
};

// A cloud in a sensor's own byte layout (the `data` of a sensor_msgs/PointCloud2 with the
// layout its fields declare), sent as it is: the server decodes it (proto PointLayout) and
// refuses a layout that does not hold together. Borrowed: it must outlive the call.
struct SensorCloud {
  absl::string_view data;
  v1::PointLayout layout;
};

// The points `data` holds in `layout` (padded rows' padding skipped; an empty layout is
// packed float32, 12 bytes a point): what the header announces as expected_points.
uint64_t PointsIn(absl::string_view data, const v1::PointLayout& layout);

class Client {
 public:
  // Checks `options` (InvalidArgument for an empty target, a bad list of endpoints (see
  // ClientOptions::target), an unknown load_balancing, max_attempts < 1, chunk_points < 1,
  // a non-positive deadline, max_receive_bytes outside 1 to 2^31 - 1, a TLS file that cannot be
  // read or is not PEM, a client certificate without its key, an API key with characters metadata
  // cannot carry, a request_id that CheckRequestId refuses) and creates the channel. Touches the
  // network only to look up the host names of a list of endpoints (Unavailable if DNS does not
  // answer): a server that is down, or a TLS handshake that fails, shows up as UNAVAILABLE on the
  // first call.
  static absl::StatusOr<std::unique_ptr<Client>> Connect(ClientOptions options);

  Client(const Client&) = delete;
  Client& operator=(const Client&) = delete;
  ~Client();

  const ClientOptions& options() const { return options_; }

  // The descriptor of `cloud`. `spec` empty: the spec of `gallery` if given, else the
  // server's default. A cloud of up to options().chunk_points points goes in one
  // DescribeCloud message; a larger one streams in chunks of that many points (as does
  // every cloud once a server has answered UNIMPLEMENTED to DescribeCloud).
  absl::StatusOr<v1::DescribeResponse> Describe(const PointCloud& cloud,
                                                const std::string& spec = "",
                                                const std::string& gallery = "");

  // Per-call choices of Describe.
  struct DescribeOptions {
    std::string spec;     // empty: the spec of `gallery` if given, else the server's default
    std::string gallery;  // optional: describe with this gallery's spec
    // The sensor's frame (a rigid transform, or which way is up); empty: the points are in
    // the frame the descriptor expects.
    v1::SensorFrame sensor_frame;
  };
  absl::StatusOr<v1::DescribeResponse> Describe(const PointCloud& cloud,
                                                const DescribeOptions& options);
  absl::StatusOr<v1::DescribeResponse> Describe(const SensorCloud& cloud,
                                                const DescribeOptions& options);

  // Classifies `cloud` against `gallery` with `k` neighbors (0: the gallery's k).
  // FAILED_PRECONDITION on an empty gallery, NOT_FOUND on an unknown one. A cloud of up to
  // options().chunk_points points goes in one ClassifyCloud message (about a third less
  // CPU per call than a stream); a larger one streams through Classify, and so does every
  // cloud once a server has answered UNIMPLEMENTED to ClassifyCloud (an older server).
  absl::StatusOr<v1::ClassifyResponse> Classify(const std::string& gallery, const PointCloud& cloud,
                                                uint32_t k = 0);

  // Per-call choices of Classify.
  struct ClassifyOptions {
    // Neighbors that vote; 0: the gallery's k.
    uint32_t k = 0;
    // Search every stored vector even where the server searches the gallery approximately
    // (v1::Gallery::approximate_lists > 0): slower, never misses a neighbor.
    bool exact = false;
    // The sensor's frame, as in DescribeOptions.
    v1::SensorFrame sensor_frame;
  };
  absl::StatusOr<v1::ClassifyResponse> Classify(const std::string& gallery, const PointCloud& cloud,
                                                const ClassifyOptions& options);
  absl::StatusOr<v1::ClassifyResponse> Classify(const std::string& gallery,
                                                const SensorCloud& cloud,
                                                const ClassifyOptions& options);

  // Per-call choices of RecognizeScene (the proto's SceneHeader).
  struct SceneOptions {
    // Neighbors that vote for each object; 0: the gallery's k.
    uint32_t k = 0;
    // As in ClassifyOptions.
    bool exact = false;
    // The sensor's frame: each object is turned by it before it is described, and only level
    // planes are supports. Empty: the first plane removed gives up.
    v1::SensorFrame sensor_frame;
    // How the frame is split; unset fields take the server's defaults (proto
    // SceneSegmentation).
    v1::SceneSegmentation segmentation;
    // Only points inside this box (the frame's coordinates) are considered; none: all.
    std::optional<v1::AxisAlignedBox> region;
    // Send each object's point indices in the frame (to color or crop it).
    bool return_indices = false;
  };

  // Finds the objects of one sensor frame and classifies each against `gallery`: supporting
  // planes removed, Euclidean clusters, one classification per cluster; geometry in the
  // frame's coordinates. Non-finite points are skipped and counted, never an error, and keep
  // their place: indices count every point of `frame`. FAILED_PRECONDITION on an empty
  // gallery, NOT_FOUND on an unknown one, INVALID_ARGUMENT naming a segmentation field out of
  // range. A frame of up to options().chunk_points points goes in one RecognizeSceneCloud
  // message, a larger one streams through RecognizeScene (as every frame does once a server
  // has answered UNIMPLEMENTED to RecognizeSceneCloud); retried like Classify.
  absl::StatusOr<v1::RecognizeSceneResponse> RecognizeScene(const std::string& gallery,
                                                            const PointCloud& frame,
                                                            const SceneOptions& options);
  // The same for a frame in a sensor's own layout (an organized one's indices are its pixels).
  absl::StatusOr<v1::RecognizeSceneResponse> RecognizeScene(const std::string& gallery,
                                                            const SensorCloud& frame,
                                                            const SceneOptions& options);

  // Adds `samples` to `gallery` in one stream: all of them or, on any error, none.
  // InvalidArgument (before sending anything) if a sample has no cloud. Retried on
  // UNAVAILABLE only when every sample has a sample_id; ALREADY_EXISTS after such a retry
  // may mean the first attempt committed (ClientOptions::max_attempts).
  absl::StatusOr<v1::TrainResponse> Train(const std::string& gallery,
                                          absl::Span<const TrainSample> samples);

  // Per-call choices of Train, for every sample of the call.
  struct TrainOptions {
    // The sensor's frame, as in DescribeOptions.
    v1::SensorFrame sensor_frame;
  };
  absl::StatusOr<v1::TrainResponse> Train(const std::string& gallery,
                                          absl::Span<const TrainSample> samples,
                                          const TrainOptions& options);
  // Train with every sample's bytes in `layout` (a sensor's own), sent as they are.
  absl::StatusOr<v1::TrainResponse> Train(const std::string& gallery, const v1::PointLayout& layout,
                                          absl::Span<const SensorTrainSample> samples,
                                          const TrainOptions& options = {});

  // Gallery management: thin wrappers over the unary RPCs of the same names.
  absl::StatusOr<v1::Gallery> CreateGallery(const v1::CreateGalleryRequest& request);
  absl::StatusOr<v1::Gallery> GetGallery(const std::string& name);
  absl::StatusOr<std::vector<v1::Gallery>> ListGalleries();  // sorted by name
  // Returns the number of samples deleted with the gallery.
  absl::StatusOr<uint64_t> DeleteGallery(const std::string& name);
  // Removes the union of `sample_ids` and `labels`; all-or-nothing (an unknown id: NOT_FOUND).
  absl::StatusOr<v1::RemoveSamplesResponse> RemoveSamples(const std::string& gallery,
                                                          absl::Span<const uint64_t> sample_ids,
                                                          absl::Span<const std::string> labels);
  absl::StatusOr<std::vector<v1::DescriptorKind>> ListDescriptors();
  // One page of a gallery's samples with their provenance (ids, labels, views, sources,
  // metadata), in id order; pass the response's next_page_token in the next request until
  // it comes back empty.
  absl::StatusOr<v1::ListSamplesResponse> ListSamples(const v1::ListSamplesRequest& request);

  // Streams gallery `name` out of the server: `sink` receives every chunk in order (the
  // header, runs of samples, the trailer; see GalleryExportChunk in the proto) and returns
  // OK to go on. The server streams one snapshot, so training meanwhile does not tear the
  // export. The chunks are not interpreted here: keep them all, in order, and check the call's
  // status: only OK means the sink saw the whole export. An error from `sink` cancels the
  // call and is returned as it is. Retried on UNAVAILABLE only while no chunk has reached
  // the sink. The whole stream must fit options().deadline: raise it for very large
  // galleries (1,000,000 x 81 floats is 336 MB; about 0.7 s over loopback).
  absl::Status ExportGallery(
      const std::string& name,
      const std::function<absl::Status(const v1::GalleryExportChunk&)>& sink);

  // Streams an export back in, all-or-nothing, and returns the new gallery. `source` fills
  // the next chunk and returns true, returns false at the end, or an error, which cancels
  // the call (nothing is imported) and is returned as it is. `new_name` non-empty imports
  // under that name instead of the exported one. Server errors: ALREADY_EXISTS (name
  // taken), FAILED_PRECONDITION (another descriptor version), INVALID_ARGUMENT / DATA_LOSS
  // (malformed, truncated or damaged export). Never retried: a repeated import of a
  // committed gallery would fail ALREADY_EXISTS and hide the first answer.
  absl::StatusOr<v1::Gallery> ImportGallery(
      const std::function<absl::StatusOr<bool>(v1::GalleryExportChunk*)>& source,
      const std::string& new_name = "");

  // A short live summary of the server that answers (one replica, since it started): calls
  // and latency by method, galleries, memory, state, log level. Read scope.
  absl::StatusOr<v1::ServerStats> GetServerStats();

  // Sets the log level of the server that answers (one replica) to `level`, "debug",
  // "info", "warning" or "error" (anything else: INVALID_ARGUMENT from the server), until it
  // restarts. Returns the previous level and the new one (after a retried attempt whose
  // first try was applied but not answered, previous_level is the new level). Admin scope.
  absl::StatusOr<v1::SetLogLevelResponse> SetLogLevel(absl::string_view level);

  // grpc.health.v1 Check of the whole server: OK when it answers SERVING, UNAVAILABLE when
  // it answers anything else or cannot be reached. With replicas, of the one the call
  // reaches: under round_robin only serving ones are, so OK while any replica serves.
  absl::Status CheckHealth();

 private:
  Client(ClientOptions options, std::shared_ptr<grpc::Channel> channel);

  // Runs `attempt` (one RPC on a fresh context) up to options_.max_attempts times while it
  // returns UNAVAILABLE (or CANCELLED, which only a server causes here) and `retry` is true,
  // with exponential backoff, all within one deadline. `attempt` is called as
  // grpc::Status(grpc::ClientContext&).
  // `may_retry`, when given, is asked before each further attempt too (false: stop).
  template <typename Attempt>
  absl::Status Call(bool retry, bool corked, const Attempt& attempt,
                    const std::function<bool()>& may_retry = nullptr);
  // Describe and Classify: `header`, then `cloud` in chunks, on the client stream `open`
  // starts (a stub method), retried like any idempotent call.
  // Both Trains: `samples` (label, id, cloud) in one stream whose header declares `layout`.
  struct WireSample {
    const std::string* label;
    uint64_t sample_id;
    SensorCloud cloud;
    const std::string* source;
    const std::map<std::string, std::string>* metadata;
  };
  absl::StatusOr<v1::TrainResponse> TrainWire(const std::string& gallery,
                                              const v1::PointLayout& layout,
                                              const std::vector<WireSample>& samples,
                                              const TrainOptions& options);
  template <typename Request, typename Response, typename Open>
  absl::StatusOr<Response> SingleCloudCall(Open open, const Request& header,
                                           const SensorCloud& cloud);
  // Describe, Classify and RecognizeScene: `header` and `cloud` in one OneMessage request
  // through `unary` (DescribeCloud, ClassifyCloud, RecognizeSceneCloud) when the cloud has at
  // most options_.chunk_points points, else (and for good once a server answers UNIMPLEMENTED
  // to it, which sets `lacks_unary`: an older server) on the stream `open` starts, through
  // SingleCloudCall. Retried like any idempotent call.
  template <typename OneMessage, typename StreamRequest, typename Response, typename Header,
            typename Unary, typename Open>
  absl::StatusOr<Response> CloudCall(const Header& header, const SensorCloud& cloud, Unary unary,
                                     Open open, std::atomic<bool>& lacks_unary);

  const ClientOptions options_;
  const std::string authorization_;  // "Bearer KEY", or empty
  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<v1::ShapeId::Stub> stub_;  // thread-safe
  // Set when the server turned out not to know the one-message calls (DescribeCloud,
  // ClassifyCloud; an older server): stream from then on.
  std::atomic<bool> server_lacks_one_message_calls_{false};
  // The same for RecognizeSceneCloud, apart: a server from before scenes lacks it but still
  // has ClassifyCloud, which must not stop being used.
  std::atomic<bool> server_lacks_one_message_scene_call_{false};
};

// The one conversion of a gRPC status into an absl::Status: same code, same message.
absl::Status FromGrpcStatus(const grpc::Status& status);

// True when `status` is this client's own refusal of an answer larger than
// ClientOptions::max_receive_bytes (RESOURCE_EXHAUSTED, "the server's answer is N bytes, more
// than this client's receive limit of M bytes ..."): the server answered, the client would not
// read it. False for every status a server sent, its RESOURCE_EXHAUSTED included.
bool IsClientReceiveLimit(const absl::Status& status);

// OK when `id` can be a ClientOptions::request_id: 1 to 128 characters of A-Z a-z 0-9 and
// . _ : / + = - (what the server keeps; see the proto's header). InvalidArgument otherwise,
// naming the allowed characters.
absl::Status CheckRequestId(absl::string_view id);

}  // namespace shapeid

#endif  // SHAPEID_CLIENT_CLIENT_H_
