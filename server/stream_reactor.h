#ifndef SHAPEID_SERVER_STREAM_REACTOR_H_
#define SHAPEID_SERVER_STREAM_REACTOR_H_

#include "absl/status/status.h"
#include "grpcpp/grpcpp.h"
#include "server/grpc_status.h"

namespace shapeid {

// The shape every client-streaming RPC of the service shares: read messages one by one,
// hand each to OnMessage, and when the client half-closes, answer with OnEnd. The first error
// either returns ends the call at once with that status (the rest of the stream is not read).
// A cancelled call (client gone, deadline passed) ends without calling OnEnd, so a cut Train
// stream publishes nothing. Deletes itself when gRPC is done with it.
template <typename Request>
class StreamReactor : public grpc::ServerReadReactor<Request> {
 public:
  explicit StreamReactor(grpc::CallbackServerContext* context) : context_(context) {}

  // Call once, at the end of the derived constructor.
  void StartReading() { this->StartRead(&request_); }

 protected:
  virtual absl::Status OnMessage(const Request& request) = 0;
  virtual absl::Status OnEnd() = 0;
  grpc::CallbackServerContext* context() const { return context_; }

 private:
  void OnReadDone(bool ok) override {
    if (!ok) {
      if (context_->IsCancelled()) {
        this->Finish(grpc::Status(grpc::StatusCode::CANCELLED, "the call was cancelled"));
      } else {
        this->Finish(ToGrpcStatus(OnEnd()));
      }
      return;
    }
    const absl::Status status = OnMessage(request_);
    if (!status.ok()) {
      this->Finish(ToGrpcStatus(status));
      return;
    }
    request_.Clear();
    this->StartRead(&request_);
  }

  void OnDone() override { delete this; }

  grpc::CallbackServerContext* context_;
  Request request_;
};

}  // namespace shapeid

#endif  // SHAPEID_SERVER_STREAM_REACTOR_H_
