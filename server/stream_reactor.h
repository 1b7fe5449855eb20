#ifndef SHAPEID_SERVER_STREAM_REACTOR_H_
#define SHAPEID_SERVER_STREAM_REACTOR_H_

#include <atomic>
#include <cstdint>

#include "absl/status/status.h"
#include "grpcpp/grpcpp.h"
#include "server/grpc_status.h"

namespace shapeid {

// Counts the calls in progress so a shutdown can drain them: once draining starts, new calls
// are refused with UNAVAILABLE and the server waits only for the calls already running.
// (gRPC's own Server::Shutdown(deadline) also waits for idle client connections, which robots
// keep open, so on its own it would always take the full grace period.)
class CallTracker {
 public:
  // Registers a call; false (and nothing registered) once draining has started.
  bool Enter() {
    in_flight_.fetch_add(1);
    if (draining_.load()) {
      Exit();
      return false;
    }
    return true;
  }
  void Exit() { in_flight_.fetch_sub(1); }
  void StartDraining() { draining_.store(true); }
  int64_t in_flight() const { return in_flight_.load(); }

  static grpc::Status Refusal() {
    return grpc::Status(grpc::StatusCode::UNAVAILABLE,
                        "the server is shutting down; retry on another replica or shortly");
  }

 private:
  std::atomic<int64_t> in_flight_{0};
  std::atomic<bool> draining_{false};
};

// The shape every client-streaming RPC of the service shares: read messages one by one,
// hand each to OnMessage, and when the client half-closes, answer with OnEnd. The first error
// either returns ends the call at once with that status (the rest of the stream is not read).
// A cancelled call (client gone, deadline passed) ends without calling OnEnd, so a cut Train
// stream publishes nothing. Deletes itself when gRPC is done with it.
template <typename Request>
class StreamReactor : public grpc::ServerReadReactor<Request> {
 public:
  StreamReactor(grpc::CallbackServerContext* context, CallTracker* tracker)
      : context_(context), tracker_(tracker), entered_(tracker->Enter()) {}

  // Call once, at the end of the derived constructor: starts reading, or refuses the call
  // when the server is draining.
  void StartReading() {
    if (entered_) {
      this->StartRead(&request_);
    } else {
      this->Finish(CallTracker::Refusal());
    }
  }

 protected:
  virtual absl::Status OnMessage(const Request& request) = 0;
  virtual absl::Status OnEnd() = 0;

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

  void OnDone() override {
    if (entered_) tracker_->Exit();
    delete this;
  }

  grpc::CallbackServerContext* context_;
  CallTracker* tracker_;
  const bool entered_;
  Request request_;
};

}  // namespace shapeid

#endif  // SHAPEID_SERVER_STREAM_REACTOR_H_
