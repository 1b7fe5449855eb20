#ifndef SHAPEID_SERVER_STREAM_REACTOR_H_
#define SHAPEID_SERVER_STREAM_REACTOR_H_

#include <mutex>
#include <optional>

#include "absl/base/thread_annotations.h"
#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"
#include "grpcpp/grpcpp.h"
#include "grpcpp/impl/codegen/proto_utils.h"
#include "grpcpp/support/byte_buffer.h"
#include "server/call_gate.h"
#include "server/call_observer.h"
#include "server/ceiling_alarm.h"
#include "server/grpc_status.h"

namespace shapeid {

// The shape every client-streaming RPC of the service shares: pass the call gate, read
// messages one by one, hand each to OnMessage, and when the client half-closes, answer with
// OnEnd. The first error either returns ends the call at once with that status (the rest of
// the stream is not read).
//
// The messages arrive as bytes (the service registers its streams raw) and are parsed here:
// gRPC's own parsing reports a message that does not parse exactly as it reports the end of
// the stream, so a Train stream with a damaged last message would commit the samples before
// it. Here such a message is INVALID_ARGUMENT and the stream keeps nothing. A cancelled call
// (client gone, deadline passed) ends without calling OnEnd, so a cut Train stream publishes
// nothing. A stream still reading at the server's ceiling (CallGate::CutOff) is ended
// DEADLINE_EXCEEDED, also without OnEnd; once OnEnd has started, the call is left to finish with
// its answer. Deletes itself when gRPC is done with it. Every call, refused or not, is reported
// once to the observer (a log line, the metrics) with the status it is finished with.
template <typename Request, typename Response>
class StreamReactor : public grpc::ServerReadReactor<grpc::ByteBuffer> {
 public:
  // `method` is the full name ("/shapeid.v1.ShapeId/Train"); `response` is where gRPC takes
  // the serialised answer from.
  StreamReactor(grpc::CallbackServerContext* context, CallGate* gate,
                const CallObserver* observer, absl::string_view method,
                grpc::ByteBuffer* response)
      : context_(context),
        gate_(gate),
        observer_(observer),
        method_(method.substr(method.rfind('/') + 1)),
        raw_response_(response),
        call_(observer->Start(*context, method)),
        pass_(gate->Admit(*context, method, CallGate::Kind::kStream)) {}

  // Call once, at the end of the derived constructor: starts reading, or refuses the call.
  void StartReading() {
    if (!pass_.ok()) {
      std::lock_guard<std::mutex> lock(mu_);
      FinishLocked(ToGrpcStatus(pass_.status()));
      return;
    }
    call_.caller = std::string(pass_->caller());
    if (const std::optional<absl::Time> cut = gate_->CutOff(*context_)) {
      ceiling_.Arm(*cut, [this] { Cut(); });
    }
    std::lock_guard<std::mutex> lock(mu_);
    if (state_ == State::kReading) this->StartRead(&raw_request_);
  }

 protected:
  virtual absl::Status OnMessage(const Request& request) = 0;
  // Fills response() when the stream ends well.
  virtual absl::Status OnEnd() = 0;
  Response* response() { return &response_; }
  // What the call reports when it ends: derived reactors fill in gallery, points, samples.
  CallRecord& call() { return call_; }
  const CallObserver& observer() const { return *observer_; }

 private:
  enum class State { kReading, kEnding, kFinished };

  // gRPC runs neither OnReadDone nor OnDone inside StartRead or Finish (their reactions are
  // scheduled), so calling them under mu_ cannot deadlock.
  // `report`: tell the observer now. Only the ceiling's Cut passes false: OnMessage may still
  // be filling in call_ on another thread, so OnDone reports it instead.
  void FinishLocked(grpc::Status status, bool report = true) ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_) {
    state_ = State::kFinished;
    if (pass_.ok()) pass_->ReleaseSlot();
    if (status.ok()) {
      bool own_buffer = false;
      status =
          grpc::SerializationTraits<Response>::Serialize(response_, raw_response_, &own_buffer);
    }
    final_status_ = status;
    // Before Finish, so that a client that has its answer finds the call in the log and the
    // metrics.
    if (report) observer_->Finish(call_, status);
    this->Finish(status);
  }

  // The message just read, parsed into request_.
  absl::Status ParseRequest() {
    ++messages_;
    request_.Clear();
    if (grpc::SerializationTraits<Request>::Deserialize(&raw_request_, &request_).ok()) {
      return absl::OkStatus();
    }
    return absl::InvalidArgumentError(absl::StrCat(method_, ": message ", messages_,
                                                   " of the stream is not a valid ",
                                                   Request::descriptor()->full_name(),
                                                   " (damaged, or from another protocol version); "
                                                   "the stream is refused whole"));
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
    absl::Status status = ParseRequest();
    if (status.ok()) status = OnMessage(request_);
    std::lock_guard<std::mutex> lock(mu_);
    if (state_ != State::kReading) return;
    if (!status.ok()) {
      FinishLocked(ToGrpcStatus(status));
      return;
    }
    this->StartRead(&raw_request_);
  }

  // The ceiling alarm. Finishing with a read outstanding is allowed; that read then ends
  // with ok = false.
  void Cut() {
    std::lock_guard<std::mutex> lock(mu_);
    if (state_ != State::kReading) return;
    FinishLocked(ToGrpcStatus(CeilingExceeded(gate_->max_call())), /*report=*/false);
  }

  void OnDone() override {
    ceiling_.Disarm();
    // A call cut at the ceiling is reported here, after every other reaction (a no-op for
    // the others, reported when finished).
    observer_->Finish(call_, final_status_);
    delete this;  // releases the pass: out of the in-flight count, the stream slot free
  }

  grpc::CallbackServerContext* const context_;
  CallGate* const gate_;
  const CallObserver* const observer_;
  const absl::string_view method_;  // "Train", for messages
  grpc::ByteBuffer* const raw_response_;
  CallRecord call_;  // before pass_: a refused call is reported too
  absl::StatusOr<CallGate::Pass> pass_;
  CeilingAlarm ceiling_;
  std::mutex mu_;
  State state_ ABSL_GUARDED_BY(mu_) = State::kReading;
  grpc::ByteBuffer raw_request_;
  Request request_;
  int64_t messages_ = 0;
  Response response_;
  grpc::Status final_status_;
};

}  // namespace shapeid

#endif  // SHAPEID_SERVER_STREAM_REACTOR_H_
