#ifndef SHAPEID_SERVER_CALLS_ADMITTED_CALL_H_
#define SHAPEID_SERVER_CALLS_ADMITTED_CALL_H_

// What every call of the ShapeId service goes through, whatever its shape (unary, client
// stream, server stream): the call gate (key, scope, server state, stream slot), the
// observer's record (one log line and the metrics, reported once), the ceiling (a call cut
// at --max_call_seconds), the memory it holds, the hand-off of its work to the scheduler,
// and one finish. The reactors (server/calls/unary_call.h, server/calls/stream_reactor.h, the
// export's) only move messages.

#include <cstddef>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "absl/time/time.h"
#include "google/protobuf/message_lite.h"
#include "grpcpp/grpcpp.h"
#include "server/ops/call_observer.h"
#include "server/runtime/call_gate.h"
#include "server/runtime/ceiling_alarm.h"
#include "server/runtime/memory_budget.h"
#include "server/runtime/work_costs.h"
#include "server/runtime/work_scheduler.h"

namespace shapeid {

class Gallery;
class GalleryRegistry;
struct ServerDescription;
struct ServiceOptions;

// What the service shares with every call; all outlive the calls.
struct ServiceRuntime {
  CallGate* gate = nullptr;
  const CallObserver* observer = nullptr;
  WorkScheduler* scheduler = nullptr;
  MemoryBudget* budget = nullptr;
  // For the handlers.
  const ServiceOptions* options = nullptr;
  GalleryRegistry* registry = nullptr;
  const ServerDescription* description = nullptr;  // for GetServerStats
};

// Work a handler hands over: steps run one after another, each on the scheduler's lane its
// estimate says (or at once, on the calling thread, for the inline ones); the first error
// ends the chain.
class Work {
 public:
  using Step = std::function<absl::Status()>;

  // Runs at once, on the thread that runs the chain (gRPC's, or the worker of the step
  // before): only for what costs microseconds.
  static Work Inline(Step run);
  // CPU work: `cost` its estimated time, `memory` the working memory it needs while it
  // runs (held from the budget; it waits in its lane until granted).
  static Work Compute(absl::Duration cost, size_t memory, Step run);
  // CPU work whose cost is known only when the chain reaches it (a scene's objects, once
  // the step before has found them): `plan` runs then, on the thread running the chain, and
  // its estimate places the step as Compute's would.
  static Work Planned(std::function<WorkEstimate()> plan, Step run);
  // Work that waits on the gallery store (a commit, a creation, a removal).
  static Work Store(absl::Duration cost, Step run);

  // Appends `next` to run after this chain's steps.
  Work Then(Work next) &&;

 private:
  friend class AdmittedCall;
  struct Piece {
    bool inline_ = false;
    bool store = false;
    absl::Duration cost;
    size_t memory = 0;
    Step run;
    std::function<WorkEstimate()> plan;  // when set, gives cost and memory when reached
  };
  std::vector<Piece> pieces_;
};

class AdmittedCall {
 public:
  // Starts the call's record (and its request id) and asks the gate to admit it.
  AdmittedCall(grpc::CallbackServerContext* context, const ServiceRuntime& runtime,
               absl::string_view full_method, CallGate::Kind kind);
  AdmittedCall(const AdmittedCall&) = delete;
  AdmittedCall& operator=(const AdmittedCall&) = delete;
  ~AdmittedCall() { ceiling_.Disarm(); }

  // OK when admitted; else the status to end the call with.
  const absl::Status& admission() const { return admission_; }
  // What the call will report: handlers fill in gallery, points, samples.
  CallRecord& record() { return record_; }
  const CallObserver& observer() const { return *runtime_.observer; }
  MemoryBudget* budget() const { return runtime_.budget; }
  // Whom the call is for, for fair shares of the scheduler and the memory budget
  // (server/runtime/caller_identity.h): "key:NAME", "cert:CN", or the client's host with the
  // client's own caller id, if it sent one.
  const std::string& caller() const { return caller_; }
  // "Train", for messages.
  absl::string_view method() const { return record_.method; }

  // Runs `expire` at the server's ceiling (CallGate::CutOff; streams only) plus `slack`,
  // unless the client's own deadline comes first. Once per call; `expire` must not outlive what it
  // captures (Disarm, or the destructor, waits for it).
  void ArmCeiling(absl::Duration slack, std::function<void()> expire);
  void DisarmCeiling() { ceiling_.Disarm(); }
  // When the ceiling ends the call (InfiniteFuture: never), and the server's ceiling itself.
  absl::Time cut_off() const { return cut_off_; }
  absl::Duration max_call() const { return runtime_.gate->max_call(); }

  // Holds `bytes` more of the memory budget until the call is concluded (a one-message
  // cloud); ResourceExhausted naming the limit.
  absl::Status HoldMemory(size_t bytes, absl::string_view what);
  // Counts the answer `response` in the call's memory until it is sent (the message and its
  // serialized copy). ResourceExhausted, saying what to ask for instead (`smaller`, e.g.
  // "fewer neighbors (k)"), when it is larger than the service sends (--max_answer_bytes)
  // or than the budget can hold.
  absl::Status HoldAnswer(const google::protobuf::MessageLite& response, absl::string_view smaller);
  // Why the call's work should stop now: Cancelled when the client cancelled or went away,
  // DeadlineExceeded when its deadline (or the server's ceiling) has passed; else OK. Cheap:
  // for work to ask between its pieces (the objects of a scene).
  absl::Status Interruption() const;

  // Memory the call holds outside HoldMemory (a stream's assembler holds its cloud's own
  // grant): read when each step is submitted, so that work which, with it, could never fit
  // a caller's share of the budget is refused at once instead of waiting for ever.
  void CountHeld(std::function<size_t()> held) { held_elsewhere_ = std::move(held); }

  // Runs `work`'s chain, then `done` with its status, exactly once: the first step's error, a
  // refusal of the scheduler (queue full, backlog, memory), the drop of a step whose
  // deadline passed or whose call was cancelled before it started, or OK. `done` runs on a
  // worker, or on this thread when the chain ends without reaching the scheduler (refused,
  // or inline only). Each step's wait is added to the record and the metrics.
  void Run(Work work, std::function<void(absl::Status)> done);

  // Reports the call to the observer (unless `report` is false: then the destructor's
  // owner must call Report later) and gives back its stream slot and memory, just before
  // the reactor's Finish. Returns what to finish with.
  grpc::Status Conclude(const grpc::Status& status, bool report = true);
  // Reports a call concluded with report = false; a no-op for the others.
  void Report() { runtime_.observer->Finish(record_, final_status_); }

 private:
  struct Chain;
  void RunNext(const std::shared_ptr<Chain>& chain);

  grpc::CallbackServerContext* const context_;
  const ServiceRuntime runtime_;
  CallRecord record_;  // before the pass: a refused call is reported too
  absl::Status admission_;
  std::optional<CallGate::Pass> pass_;
  std::string caller_;
  absl::Time cut_off_ = absl::InfiniteFuture();
  absl::Time deadline_ = absl::InfiniteFuture();  // the client's, or the ceiling
  MemoryBudget::Grant memory_;
  std::function<size_t()> held_elsewhere_;
  CeilingAlarm ceiling_;
  grpc::Status final_status_;
};

// The gallery a call names, recorded as the call's: INVALID_ARGUMENT "METHOD: the gallery name
// is empty", NOT_FOUND when the registry holds none of that name.
absl::StatusOr<std::shared_ptr<Gallery>> NamedGallery(const ServiceRuntime& runtime,
                                                      CallRecord& record, absl::string_view name);

}  // namespace shapeid

#endif  // SHAPEID_SERVER_CALLS_ADMITTED_CALL_H_
