#ifndef SHAPEID_SERVER_RUNTIME_CALL_GATE_H_
#define SHAPEID_SERVER_RUNTIME_CALL_GATE_H_

// What every call of the ShapeId service passes before it runs: its API key and scope, the
// server's state (loading, serving, draining) and, for streams, the client's stream count;
// and when the server cuts a stream short (the call ceiling). One place, so that no handler
// can forget a check (docs/security.md).

#include <atomic>
#include <cstdint>
#include <memory>
#include <optional>
#include <utility>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "absl/time/time.h"
#include "grpcpp/grpcpp.h"
#include "server/runtime/stream_limiter.h"
#include "server/security/api_keys.h"

namespace shapeid {

// Counts the calls in progress so a shutdown can drain them, and refuses calls while the
// server is not ready: before its galleries are loaded (a client must not see an empty
// registry and conclude a gallery is gone) and once draining has started (the server waits
// only for the calls already running). gRPC's own Server::Shutdown(deadline) also waits for
// idle client connections, which robots keep open, so on its own it would always take the full
// grace period.
class CallTracker {
 public:
  // kStoreUnreachable: a replica over a shared store (PostgreSQL) that has lost it; its
  // galleries may be stale, so it answers nothing until it is back and caught up.
  enum class State { kLoading, kServing, kStoreUnreachable, kDraining };

  // Registers a call; false (and nothing registered) unless serving.
  bool Enter() {
    in_flight_.fetch_add(1);
    if (state_.load() != State::kServing) {
      Exit();
      return false;
    }
    return true;
  }
  // Registers a call whatever the state: the operator's calls (GetServerStats, SetLogLevel),
  // which must answer most when the server is not serving.
  void EnterAnyway() { in_flight_.fetch_add(1); }
  void Exit() { in_flight_.fetch_sub(1); }
  // kLoading -> kServing <-> kStoreUnreachable; draining is final.
  void SetState(State state) {
    State expected = state_.load();
    while (expected != State::kDraining && !state_.compare_exchange_weak(expected, state)) {
    }
  }
  void StartDraining() { state_.store(State::kDraining); }
  int64_t in_flight() const { return in_flight_.load(); }
  State state() const { return state_.load(); }
  // "serving", "loading", "store unreachable", "draining": for GetServerStats.
  static const char* StateName(State state) {
    switch (state) {
      case State::kLoading:
        return "loading";
      case State::kServing:
        return "serving";
      case State::kStoreUnreachable:
        return "store unreachable";
      case State::kDraining:
        return "draining";
    }
    return "serving";
  }

  // The status a refused call gets: UNAVAILABLE, loading or shutting down.
  absl::Status Refusal() const {
    if (state_.load() == State::kLoading) {
      return absl::UnavailableError("the server is loading its galleries; retry shortly");
    }
    if (state_.load() == State::kStoreUnreachable) {
      return absl::UnavailableError(
          "this replica has lost its gallery store (PostgreSQL) and may be stale; retry on "
          "another replica or shortly");
    }
    return absl::UnavailableError(
        "the server is shutting down; retry on another replica or shortly");
  }

 private:
  std::atomic<int64_t> in_flight_{0};
  std::atomic<State> state_{State::kServing};
};

class CallGate {
 public:
  // `keys` null or empty: every call is allowed (an open server). `max_streams_per_client`
  // 0: no limit. `max_call` zero or negative: no ceiling.
  CallGate(std::shared_ptr<const ApiKeyStore> keys, int max_streams_per_client,
           absl::Duration max_call);

  // An admitted call: counted in flight and, for a stream, holding one of its client's stream
  // slots, until destroyed. Move-only.
  class Pass {
   public:
    // Frees the stream slot now: a stream calls it just before Finish, so that a client that
    // opens its next stream on seeing the answer finds the slot free (the reactor itself
    // lives on a moment, until gRPC's OnDone).
    void ReleaseSlot() { slot_ = StreamLimiter::Slot(); }
    // The name of the caller's API key (never the key); empty on a server without keys.
    absl::string_view caller() const { return caller_; }
    Pass() = default;
    Pass(Pass&& other) noexcept
        : tracker_(std::exchange(other.tracker_, nullptr)),
          slot_(std::move(other.slot_)),
          caller_(other.caller_) {}
    Pass& operator=(Pass&& other) noexcept {
      if (this != &other) {
        Leave();
        tracker_ = std::exchange(other.tracker_, nullptr);
        slot_ = std::move(other.slot_);
        caller_ = other.caller_;
      }
      return *this;
    }
    Pass(const Pass&) = delete;
    Pass& operator=(const Pass&) = delete;
    ~Pass() { Leave(); }

   private:
    friend class CallGate;
    void Leave() {
      if (tracker_ != nullptr) tracker_->Exit();
      tracker_ = nullptr;
    }
    CallTracker* tracker_ = nullptr;
    StreamLimiter::Slot slot_;
    absl::string_view caller_;  // into the gate's key store, which outlives every call
  };

  // kOperations: a unary call admitted in every state (loading, draining, store lost), with
  // its key and scope checked as any other's.
  enum class Kind { kUnary, kStream, kOperations };

  // Admits a new call of `method` (its full name, "/shapeid.v1.ShapeId/Train"), or returns the
  // status to end it with, checked in this order: its key covers the scope the method needs
  // (UNAUTHENTICATED, PERMISSION_DENIED; server/security/authorization.h), the server is serving
  // (UNAVAILABLE), a stream's client has a slot free (RESOURCE_EXHAUSTED).
  absl::StatusOr<Pass> Admit(const grpc::CallbackServerContext& context, absl::string_view method,
                             Kind kind);

  // When the server must end a stream that is still running: the ceiling (`max_call` from
  // now) when the client's own deadline is later or absent; nullopt when the client's deadline
  // comes first (gRPC enforces it) or there is no ceiling.
  std::optional<absl::Time> CutOff(const grpc::CallbackServerContext& context) const;
  absl::Duration max_call() const { return max_call_; }

  CallTracker& tracker() { return tracker_; }
  const CallTracker& tracker() const { return tracker_; }

 private:
  const std::shared_ptr<const ApiKeyStore> keys_;
  StreamLimiter streams_;
  const absl::Duration max_call_;
  CallTracker tracker_;
};

// The status of a stream the server ends at its ceiling.
absl::Status CeilingExceeded(absl::Duration max_call);

}  // namespace shapeid

#endif  // SHAPEID_SERVER_RUNTIME_CALL_GATE_H_
