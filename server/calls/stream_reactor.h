#ifndef SHAPEID_SERVER_CALLS_STREAM_REACTOR_H_
#define SHAPEID_SERVER_CALLS_STREAM_REACTOR_H_

#include <mutex>
#include <optional>
#include <utility>

#include "absl/base/thread_annotations.h"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"
#include "grpcpp/grpcpp.h"
#include "grpcpp/impl/codegen/proto_utils.h"
#include "grpcpp/support/byte_buffer.h"
#include "server/calls/admitted_call.h"
#include "server/calls/grpc_status.h"

namespace shapeid {

// The shape every client-streaming RPC of the service shares: admit the call
// (server/calls/admitted_call.h), read messages one by one and hand each to OnMessage, and when the
// client half-closes, run what OnEnd returns and answer. OnMessage and OnEnd run on gRPC's
// threads and only move bytes and check headers; the work they return (describing a cloud, a
// commit) runs on the scheduler, and the stream reads its next message only when that work is
// done, so a client cannot run ahead of the server's workers. The first error ends the call at
// once with that status (the rest of the stream is not read).
//
// The messages arrive as bytes (the service registers its streams raw) and are parsed here:
// gRPC's own parsing reports a message that does not parse exactly as it reports the end of
// the stream, so a Train stream with a damaged last message would commit the samples before
// it. Here such a message is INVALID_ARGUMENT and the stream keeps nothing. A cancelled call
// (client gone, deadline passed) ends without running OnEnd's work, so a cut Train stream
// publishes nothing. A stream still reading at the server's ceiling (CallGate::CutOff) is
// ended DEADLINE_EXCEEDED; one whose work runs at the ceiling is ended so when that work
// returns, unless it was OnEnd's, which is left to finish with its answer. Deletes itself when
// gRPC is done with it. Every call, refused or not, is reported once to the observer with the
// status it is finished with.
template <typename Request, typename Response>
class StreamReactor : public grpc::ServerReadReactor<grpc::ByteBuffer> {
 public:
  // `method` is the full name ("/shapeid.v1.ShapeId/Train"); `response` is where gRPC takes
  // the serialized answer from.
  StreamReactor(grpc::CallbackServerContext* context, const ServiceRuntime& runtime,
                absl::string_view method, grpc::ByteBuffer* response)
      : context_(context),
        raw_response_(response),
        call_(context, runtime, method, CallGate::Kind::kStream) {}

  // Call once, at the end of the derived constructor: starts reading, or refuses the call.
  void StartReading() {
    std::lock_guard<std::mutex> lock(mu_);
    if (!call_.admission().ok()) {
      FinishLocked(ToGrpcStatus(call_.admission()));
      return;
    }
    call_.ArmCeiling(absl::ZeroDuration(), [this] { Cut(); });
    this->StartRead(&raw_request_);
  }

 protected:
  // A message, parsed. Returns nothing to read on, or work to run first.
  virtual absl::StatusOr<std::optional<Work>> OnMessage(const Request& request) = 0;
  // The client half-closed: the work that fills response() (it may be Work::Inline).
  virtual absl::StatusOr<Work> OnEnd() = 0;
  Response* response() { return &response_; }
  AdmittedCall& call() { return call_; }

 private:
  // kWorking: work of OnMessage runs on the scheduler; no read is outstanding.
  enum class State { kReading, kWorking, kEnding, kFinished };

  // gRPC runs neither OnReadDone nor OnDone inside StartRead or Finish (their reactions are
  // scheduled), so calling them under mu_ cannot deadlock.
  // `report`: tell the observer now. Only the ceiling's Cut passes false: OnMessage may still
  // be filling in the record on another thread, so OnDone reports it instead.
  void FinishLocked(grpc::Status status, bool report = true) ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_) {
    state_ = State::kFinished;
    if (status.ok()) {
      bool own_buffer = false;
      status =
          grpc::SerializationTraits<Response>::Serialize(response_, raw_response_, &own_buffer);
    }
    // Before Finish, so that a client that has its answer finds the call in the log and the
    // metrics.
    this->Finish(call_.Conclude(status, report));
  }

  // Holds the bytes of the message just read, and of its parsed copy, from the budget.
  absl::Status HoldMessage() {
    MemoryBudget* budget = call_.budget();
    const size_t bytes = 2 * raw_request_.Length();
    if (budget == nullptr || bytes == 0) return absl::OkStatus();
    absl::StatusOr<MemoryBudget::Grant> grant =
        budget->Reserve(call_.caller(), bytes, "a message of the stream");
    if (!grant.ok()) return grant.status();
    message_memory_ = *std::move(grant);
    return absl::OkStatus();
  }

  // The message just read, parsed into request_.
  absl::Status ParseRequest() {
    ++messages_;
    if (grpc::SerializationTraits<Request>::Deserialize(&raw_request_, &request_).ok()) {
      return absl::OkStatus();
    }
    return absl::InvalidArgumentError(absl::StrCat(call_.method(), ": message ", messages_,
                                                   " of the stream is not a valid ",
                                                   Request::descriptor()->full_name(),
                                                   " (damaged, or from another protocol version); "
                                                   "the stream is refused whole"));
  }

  void OnReadDone(bool ok) override {
    if (!ok) {
      End();
      return;
    }
    // The message as received and parsed is counted in the budget until OnMessage has moved
    // its points into the call's cloud (which counts them itself).
    absl::Status parsed = HoldMessage();
    if (parsed.ok()) parsed = ParseRequest();
    // The ceiling may end the call while OnMessage works; its work is then dropped.
    absl::StatusOr<std::optional<Work>> next =
        parsed.ok() ? OnMessage(request_) : absl::StatusOr<std::optional<Work>>(parsed);
    request_ = Request();  // frees the message's bytes, which Clear() would keep
    message_memory_.Release();
    std::unique_lock<std::mutex> lock(mu_);
    if (state_ != State::kReading) return;
    if (!next.ok()) {
      FinishLocked(ToGrpcStatus(next.status()));
      return;
    }
    if (!next->has_value()) {
      this->StartRead(&raw_request_);
      return;
    }
    state_ = State::kWorking;
    lock.unlock();
    call_.Run(**std::move(next), [this](absl::Status status) {
      std::lock_guard<std::mutex> done_lock(mu_);
      if (state_ != State::kWorking) return;
      if (status.ok() && cut_) status = CeilingExceeded(call_.max_call());
      if (!status.ok()) {
        FinishLocked(ToGrpcStatus(status));
        return;
      }
      state_ = State::kReading;
      this->StartRead(&raw_request_);
    });
  }

  // The client half-closed (or the call was cancelled): run OnEnd's work and answer.
  void End() {
    {
      std::lock_guard<std::mutex> lock(mu_);
      if (state_ != State::kReading) return;  // cut at the ceiling
      state_ = State::kEnding;                // from here the ceiling leaves the call alone
    }
    if (context_->IsCancelled()) {
      std::lock_guard<std::mutex> lock(mu_);
      FinishLocked(grpc::Status(grpc::StatusCode::CANCELLED, "the call was cancelled"));
      return;
    }
    absl::StatusOr<Work> work = OnEnd();
    if (!work.ok()) {
      std::lock_guard<std::mutex> lock(mu_);
      FinishLocked(ToGrpcStatus(work.status()));
      return;
    }
    call_.Run(*std::move(work), [this](const absl::Status& status) {
      std::lock_guard<std::mutex> lock(mu_);
      FinishLocked(ToGrpcStatus(status));
    });
  }

  // The ceiling alarm. Finishing with a read outstanding is allowed; that read then ends
  // with ok = false. Work running now is left to return first.
  void Cut() {
    std::lock_guard<std::mutex> lock(mu_);
    if (state_ == State::kWorking) cut_ = true;
    if (state_ != State::kReading) return;
    FinishLocked(ToGrpcStatus(CeilingExceeded(call_.max_call())), /*report=*/false);
  }

  void OnDone() override {
    call_.DisarmCeiling();
    // A call cut at the ceiling is reported here, after every other reaction (a no-op for
    // the others, reported when finished).
    call_.Report();
    // Whoever called Finish may still hold mu_ for a moment.
    { std::lock_guard<std::mutex> lock(mu_); }
    delete this;
  }

  grpc::CallbackServerContext* const context_;
  grpc::ByteBuffer* const raw_response_;
  AdmittedCall call_;
  std::mutex mu_;
  State state_ ABSL_GUARDED_BY(mu_) = State::kReading;
  bool cut_ ABSL_GUARDED_BY(mu_) = false;
  grpc::ByteBuffer raw_request_;
  MemoryBudget::Grant message_memory_;
  Request request_;
  int64_t messages_ = 0;
  Response response_;
};

}  // namespace shapeid

#endif  // SHAPEID_SERVER_CALLS_STREAM_REACTOR_H_
