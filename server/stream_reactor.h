#ifndef SHAPEID_SERVER_STREAM_REACTOR_H_
#define SHAPEID_SERVER_STREAM_REACTOR_H_

#include <mutex>
#include <optional>

#include "absl/base/thread_annotations.h"
#include "absl/status/status.h"
#include "absl/strings/string_view.h"
#include "grpcpp/grpcpp.h"
#include "server/call_gate.h"
#include "server/ceiling_alarm.h"
#include "server/grpc_status.h"

namespace shapeid {

// The shape every client-streaming RPC of the service shares: pass the call gate, read
// messages one by one, hand each to OnMessage, and when the client half-closes, answer with
// OnEnd. The first error either returns ends the call at once with that status (the rest of
// the stream is not read). A cancelled call (client gone, deadline passed) ends without
// calling OnEnd, so a cut Train stream publishes nothing. A stream still reading at the
// server's ceiling (CallGate::CutOff) is ended DEADLINE_EXCEEDED, also without OnEnd; once
// OnEnd has started, the call is left to finish with its answer. Deletes itself when gRPC is
// done with it.
template <typename Request>
class StreamReactor : public grpc::ServerReadReactor<Request> {
 public:
  StreamReactor(grpc::CallbackServerContext* context, CallGate* gate, absl::string_view method)
      : context_(context),
        gate_(gate),
        pass_(gate->Admit(*context, method, CallGate::Kind::kStream)) {}

  // Call once, at the end of the derived constructor: starts reading, or refuses the call.
  void StartReading() {
    if (!pass_.ok()) {
      std::lock_guard<std::mutex> lock(mu_);
      FinishLocked(ToGrpcStatus(pass_.status()));
      return;
    }
    if (const std::optional<absl::Time> cut = gate_->CutOff(*context_)) {
      ceiling_.Arm(*cut, [this] { Cut(); });
    }
    std::lock_guard<std::mutex> lock(mu_);
    if (state_ == State::kReading) this->StartRead(&request_);
  }

 protected:
  virtual absl::Status OnMessage(const Request& request) = 0;
  virtual absl::Status OnEnd() = 0;

 private:
  enum class State { kReading, kEnding, kFinished };

  // gRPC runs neither OnReadDone nor OnDone inside StartRead or Finish (their reactions are
  // scheduled), so calling them under mu_ cannot deadlock.
  void FinishLocked(const grpc::Status& status) ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_) {
    state_ = State::kFinished;
    if (pass_.ok()) pass_->ReleaseSlot();
    this->Finish(status);
  }

  void OnReadDone(bool ok) override {
    if (!ok) {
      {
        std::lock_guard<std::mutex> lock(mu_);
        if (state_ != State::kReading) return;  // cut at the ceiling
        state_ = State::kEnding;                // from here the ceiling leaves the call alone
      }
      const grpc::Status status =
          context_->IsCancelled()
              ? grpc::Status(grpc::StatusCode::CANCELLED, "the call was cancelled")
              : ToGrpcStatus(OnEnd());
      std::lock_guard<std::mutex> lock(mu_);
      FinishLocked(status);
      return;
    }
    // The ceiling may end the call while OnMessage works; its work is then dropped.
    const absl::Status status = OnMessage(request_);
    std::lock_guard<std::mutex> lock(mu_);
    if (state_ != State::kReading) return;
    if (!status.ok()) {
      FinishLocked(ToGrpcStatus(status));
      return;
    }
    request_.Clear();
    this->StartRead(&request_);
  }

  // The ceiling alarm. Finishing with a read outstanding is allowed; that read then ends
  // with ok = false.
  void Cut() {
    std::lock_guard<std::mutex> lock(mu_);
    if (state_ != State::kReading) return;
    FinishLocked(ToGrpcStatus(CeilingExceeded(gate_->max_call())));
  }

  void OnDone() override {
    ceiling_.Disarm();
    delete this;  // releases the pass: out of the in-flight count, the stream slot free
  }

  grpc::CallbackServerContext* const context_;
  CallGate* const gate_;
  absl::StatusOr<CallGate::Pass> pass_;
  CeilingAlarm ceiling_;
  std::mutex mu_;
  State state_ ABSL_GUARDED_BY(mu_) = State::kReading;
  Request request_;
};

}  // namespace shapeid

#endif  // SHAPEID_SERVER_STREAM_REACTOR_H_
