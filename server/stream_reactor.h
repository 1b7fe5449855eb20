#ifndef SHAPEID_SERVER_STREAM_REACTOR_H_
#define SHAPEID_SERVER_STREAM_REACTOR_H_

#include <atomic>
#include <cstdint>

#include "absl/status/status.h"
#include "grpcpp/grpcpp.h"
#include "server/grpc_status.h"

namespace shapeid {

// Counts the calls in progress so a shutdown can drain them, and refuses calls while the
// server is not ready: before its galleries are loaded (a client must not see an empty
// registry and conclude a gallery is gone) and once draining has started (the server waits
// only for the calls already running). gRPC's own Server::Shutdown(deadline) also waits for
// idle client connections, which robots keep open, so on its own it would always take the full
// grace period.
class CallTracker {
 public:
  enum class State { kLoading, kServing, kDraining };

  // Registers a call; false (and nothing registered) unless serving.
  bool Enter() {
    in_flight_.fetch_add(1);
    if (state_.load() != State::kServing) {
      Exit();
      return false;
    }
    return true;
  }
  void Exit() { in_flight_.fetch_sub(1); }
  // kLoading -> kServing; draining is final.
  void SetState(State state) {
    State expected = state_.load();
    while (expected != State::kDraining && !state_.compare_exchange_weak(expected, state)) {
    }
  }
  void StartDraining() { state_.store(State::kDraining); }
  int64_t in_flight() const { return in_flight_.load(); }

  // The status a refused call gets.
  grpc::Status Refusal() const {
    if (state_.load() == State::kLoading) {
      return grpc::Status(grpc::StatusCode::UNAVAILABLE,
                          "the server is loading its galleries; retry shortly");
    }
    return grpc::Status(grpc::StatusCode::UNAVAILABLE,
                        "the server is shutting down; retry on another replica or shortly");
  }

 private:
  std::atomic<int64_t> in_flight_{0};
  std::atomic<State> state_{State::kServing};
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
      this->Finish(tracker_->Refusal());
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
