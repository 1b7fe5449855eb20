#include "server/runtime/call_gate.h"

#include <optional>
#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "server/security/authorization.h"

namespace shapeid {

CallGate::CallGate(std::shared_ptr<const ApiKeyStore> keys, int max_streams_per_client,
                   absl::Duration max_call)
    : keys_(keys != nullptr ? std::move(keys) : std::make_shared<const ApiKeyStore>()),
      streams_(max_streams_per_client),
      max_call_(max_call) {}

absl::StatusOr<CallGate::Pass> CallGate::Admit(const grpc::CallbackServerContext& context,
                                               absl::string_view method, Kind kind) {
  std::optional<absl::string_view> authorization;
  if (!keys_->empty()) {
    const auto& metadata = context.client_metadata();
    const auto it = metadata.find(
        grpc::string_ref(kAuthorizationMetadata.data(), kAuthorizationMetadata.size()));
    if (it != metadata.end())
      authorization = absl::string_view(it->second.data(), it->second.size());
  }
  const ApiKeyEntry* caller = nullptr;
  if (absl::Status s = Authorize(*keys_, method, authorization, &caller); !s.ok()) return s;
  Pass pass;
  if (caller != nullptr) pass.caller_ = caller->name;
  if (kind == Kind::kOperations) {
    tracker_.EnterAnyway();
  } else if (!tracker_.Enter()) {
    return tracker_.Refusal();
  }
  pass.tracker_ = &tracker_;
  if (kind == Kind::kStream) {
    absl::StatusOr<StreamLimiter::Slot> slot = streams_.Acquire(ClientOfPeer(context.peer()));
    if (!slot.ok()) return slot.status();  // `pass` leaves the tracker
    pass.slot_ = std::move(slot).value();
  }
  return pass;
}

std::optional<absl::Time> CallGate::CutOff(const grpc::CallbackServerContext& context) const {
  if (max_call_ <= absl::ZeroDuration()) return std::nullopt;
  const absl::Time ceiling = absl::Now() + max_call_;
  const gpr_timespec raw = context.raw_deadline();
  if (gpr_time_cmp(raw, gpr_inf_future(raw.clock_type)) != 0 &&
      absl::FromChrono(context.deadline()) <= ceiling) {
    return std::nullopt;
  }
  return ceiling;
}

absl::Status CeilingExceeded(absl::Duration max_call) {
  return absl::DeadlineExceededError(absl::StrCat(
      "the call ran for ", absl::FormatDuration(max_call),
      ", this server's limit per call (max_call_seconds); use shorter calls (fewer samples per "
      "Train stream) or ask the operator to raise it"));
}

}  // namespace shapeid
