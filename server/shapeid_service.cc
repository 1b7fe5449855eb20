#include "server/shapeid_service.h"

#include <memory>
#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "absl/time/time.h"
#include "core/descriptor_registry.h"
#include "core/status_macros.h"
#include "server/cloud_assembler.h"
#include "server/grpc_status.h"
#include "server/stream_reactor.h"

namespace shapeid {
namespace {

void SetDuration(absl::Duration d, google::protobuf::Duration* out) {
  const int64_t nanos = absl::ToInt64Nanoseconds(d);
  out->set_seconds(nanos / 1'000'000'000);
  out->set_nanos(static_cast<int32_t>(nanos % 1'000'000'000));
}

class DescribeReactor final : public StreamReactor<v1::DescribeRequest> {
 public:
  DescribeReactor(grpc::CallbackServerContext* context, const ServiceOptions& options,
                  v1::DescribeResponse* response)
      : StreamReactor(context),
        options_(options),
        response_(response),
        assembler_(options.max_points_per_cloud) {
    StartReading();
  }

 private:
  absl::Status OnMessage(const v1::DescribeRequest& request) override {
    switch (request.kind_case()) {
      case v1::DescribeRequest::kHeader:
        return OnHeader(request.header());
      case v1::DescribeRequest::kPoints:
        if (descriptor_ == nullptr) {
          return absl::InvalidArgumentError(
              "Describe: the first message must be a DescribeHeader; points came first");
        }
        return assembler_.Append(request.points().xyz());
      case v1::DescribeRequest::KIND_NOT_SET:
        break;
    }
    return absl::InvalidArgumentError("Describe: a message with neither header nor points");
  }

  absl::Status OnHeader(const v1::DescribeHeader& header) {
    if (descriptor_ != nullptr) {
      return absl::InvalidArgumentError("Describe: a second DescribeHeader in one stream");
    }
    if (!header.gallery().empty()) {
      return absl::UnimplementedError("Describe: galleries arrive with the gallery service");
    }
    const std::string& spec =
        header.descriptor_spec().empty() ? options_.default_descriptor_spec : header.descriptor_spec();
    SHAPEID_ASSIGN_OR_RETURN(descriptor_, CreateDescriptor(spec));
    return assembler_.Start(header.expected_points());
  }

  absl::Status OnEnd() override {
    if (descriptor_ == nullptr) {
      return absl::InvalidArgumentError("Describe: the stream ended without a DescribeHeader");
    }
    SHAPEID_ASSIGN_OR_RETURN(const PointCloud cloud, assembler_.Finish());
    const absl::Time start = absl::Now();
    std::vector<float> values;
    SHAPEID_RETURN_IF_ERROR(descriptor_->Compute(cloud, &values));
    SetDuration(absl::Now() - start, response_->mutable_describe_time());
    response_->set_descriptor_spec(descriptor_->spec().ToString());
    response_->mutable_values()->Assign(values.begin(), values.end());
    response_->set_num_points(cloud.size());
    return absl::OkStatus();
  }

  const ServiceOptions& options_;
  v1::DescribeResponse* response_;
  CloudAssembler assembler_;
  std::unique_ptr<Descriptor> descriptor_;
};

}  // namespace

grpc::ServerReadReactor<v1::DescribeRequest>* ShapeIdService::Describe(
    grpc::CallbackServerContext* context, v1::DescribeResponse* response) {
  return new DescribeReactor(context, options_, response);
}

grpc::ServerUnaryReactor* ShapeIdService::ListDescriptors(
    grpc::CallbackServerContext* context, const v1::ListDescriptorsRequest* /*request*/,
    v1::ListDescriptorsResponse* response) {
  absl::Status status;
  for (const DescriptorKind& kind : RegisteredDescriptors()) {
    v1::DescriptorKind* out = response->add_descriptors();
    out->set_kind(kind.kind);
    out->set_summary(kind.summary);
    for (const DescriptorParam& p : kind.params) {
      v1::DescriptorParameter* param = out->add_parameters();
      param->set_name(p.name);
      param->set_default_value(p.default_value);
      param->set_help(p.help);
    }
    auto defaults = CreateDescriptor(kind.kind);
    if (!defaults.ok()) {
      status = defaults.status();
      break;
    }
    out->set_default_spec((*defaults)->spec().ToString());
    out->set_default_dimension(static_cast<uint32_t>((*defaults)->dimension()));
  }
  grpc::ServerUnaryReactor* reactor = context->DefaultReactor();
  reactor->Finish(ToGrpcStatus(status));
  return reactor;
}

}  // namespace shapeid
