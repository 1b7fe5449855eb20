#ifndef SHAPEID_SERVER_CALLS_CLOUD_RPCS_H_
#define SHAPEID_SERVER_CALLS_CLOUD_RPCS_H_

// The RPCs that bring clouds (server/calls/rpc_list.h): Describe, Classify and RecognizeScene,
// each a stream and a one-message call served by server/calls/cloud_call.h from its
// declaration here, each planning its work from the header with one gallery snapshot; and
// Train, a stream of many labeled clouds committed as one batch. All hand describing,
// searching and committing to the scheduler with their estimated costs
// (server/runtime/work_costs.h).

#include <memory>

#include "absl/status/statusor.h"
#include "core/descriptor.h"
#include "core/gallery/gallery.h"
#include "core/scene/scene_recognition.h"
#include "grpcpp/grpcpp.h"
#include "server/calls/admitted_call.h"
#include "server/calls/cloud_call.h"
#include "shapeid/v1/shapeid.pb.h"

namespace shapeid {

// A cloud in, its descriptor out: the header's spec, else the named gallery's descriptor, else
// the server's default.
struct DescribeRpc {
  using StreamRequest = v1::DescribeRequest;
  using CloudRequest = v1::DescribeCloudRequest;
  using Header = v1::DescribeHeader;
  using Response = v1::DescribeResponse;
  static constexpr bool kHeaderRequired = false;
  struct Plan {
    std::shared_ptr<const Descriptor> descriptor;
    WireCloudFormat format;
  };
  static absl::StatusOr<Plan> PlanOf(const ServiceRuntime& runtime, const Header& header,
                                     CallRecord& record);
  static Work WorkOf(Plan plan, size_t points, CloudSource cloud, AdmittedCall& call,
                     Response* response);
};

// A cloud in, the gallery's answer out (label, neighbors, votes), against the snapshot the
// gallery had when the header arrived.
struct ClassifyRpc {
  using StreamRequest = v1::ClassifyRequest;
  using CloudRequest = v1::ClassifyCloudRequest;
  using Header = v1::ClassifyHeader;
  using Response = v1::ClassifyResponse;
  static constexpr bool kHeaderRequired = true;
  struct Plan {
    std::shared_ptr<const GallerySnapshot> snapshot;
    CloudLimits limits;  // the gallery's
    WireCloudFormat format;
    int k = 0;
    SearchMode mode = SearchMode::kDefault;
  };
  static absl::StatusOr<Plan> PlanOf(const ServiceRuntime& runtime, const Header& header,
                                     CallRecord& record);
  static Work WorkOf(Plan plan, size_t points, CloudSource cloud, AdmittedCall& call,
                     Response* response);
};

// A frame in, the objects found in it out (core/scene/scene_recognition.h), against the
// snapshot the gallery had when the header arrived. The frame is taken as sent: non-finite
// points kept (segmentation skips them) and no transform, so that indices count every point
// sent and answers are in the frame's coordinates.
struct RecognizeSceneRpc {
  using StreamRequest = v1::RecognizeSceneRequest;
  using CloudRequest = v1::RecognizeSceneCloudRequest;
  using Header = v1::SceneHeader;
  using Response = v1::RecognizeSceneResponse;
  static constexpr bool kHeaderRequired = true;
  struct Plan {
    std::shared_ptr<const GallerySnapshot> snapshot;
    SceneRecognitionOptions options;
    WireCloudFormat format;
    bool return_indices = false;
  };
  static absl::StatusOr<Plan> PlanOf(const ServiceRuntime& runtime, const Header& header,
                                     CallRecord& record);
  static Work WorkOf(Plan plan, size_t points, CloudSource cloud, AdmittedCall& call,
                     Response* response);
};

// A stream of labeled clouds (v1::TrainRequest: a TrainHeader, then a SampleHeader and its
// points for each sample) added to one gallery as one batch, committed at the end
// (v1::TrainResponse).
struct TrainRpc {
  static grpc::ServerReadReactor<grpc::ByteBuffer>* Start(grpc::CallbackServerContext* context,
                                                          const ServiceRuntime& runtime,
                                                          absl::string_view method,
                                                          grpc::ByteBuffer* response);
};

}  // namespace shapeid

#endif  // SHAPEID_SERVER_CALLS_CLOUD_RPCS_H_
