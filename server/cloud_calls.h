#ifndef SHAPEID_SERVER_CLOUD_CALLS_H_
#define SHAPEID_SERVER_CLOUD_CALLS_H_

// The calls that bring clouds: Describe, Train, Classify and RecognizeScene (client streams)
// and DescribeCloud, ClassifyCloud and RecognizeSceneCloud (one message). Each checks its header on
// gRPC's thread and hands describing, searching and committing to the scheduler with their
// estimated costs (server/work_costs.h).

#include "absl/status/statusor.h"
#include "grpcpp/grpcpp.h"
#include "server/admitted_call.h"
#include "shapeid/v1/shapeid.pb.h"

namespace shapeid {

// Streams: messages v1::DescribeRequest, TrainRequest, ClassifyRequest (as bytes); answers
// v1::DescribeResponse, TrainResponse, ClassifyResponse.
grpc::ServerReadReactor<grpc::ByteBuffer>* StartDescribe(grpc::CallbackServerContext* context,
                                                         const ServiceRuntime& runtime,
                                                         grpc::ByteBuffer* response);
grpc::ServerReadReactor<grpc::ByteBuffer>* StartTrain(grpc::CallbackServerContext* context,
                                                      const ServiceRuntime& runtime,
                                                      grpc::ByteBuffer* response);
grpc::ServerReadReactor<grpc::ByteBuffer>* StartClassify(grpc::CallbackServerContext* context,
                                                         const ServiceRuntime& runtime,
                                                         grpc::ByteBuffer* response);
// v1::RecognizeSceneRequest in, v1::RecognizeSceneResponse out.
grpc::ServerReadReactor<grpc::ByteBuffer>* StartRecognizeScene(grpc::CallbackServerContext* context,
                                                               const ServiceRuntime& runtime,
                                                               grpc::ByteBuffer* response);

// The one-message calls' handlers (server/unary_call.h): the same checks and answers as the
// streams'.
absl::StatusOr<Work> DescribeCloud(const ServiceRuntime& runtime,
                                   const v1::DescribeCloudRequest& request,
                                   v1::DescribeResponse* response, AdmittedCall& call);
absl::StatusOr<Work> ClassifyCloud(const ServiceRuntime& runtime,
                                   const v1::ClassifyCloudRequest& request,
                                   v1::ClassifyResponse* response, AdmittedCall& call);
absl::StatusOr<Work> RecognizeSceneCloud(const ServiceRuntime& runtime,
                                         const v1::RecognizeSceneCloudRequest& request,
                                         v1::RecognizeSceneResponse* response, AdmittedCall& call);

}  // namespace shapeid

#endif  // SHAPEID_SERVER_CLOUD_CALLS_H_
