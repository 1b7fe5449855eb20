#include "server/calls/admitted_call.h"

#include <algorithm>
#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "core/gallery/gallery_registry.h"
#include "core/status_macros.h"
#include "server/calls/grpc_status.h"
#include "server/calls/service_options.h"
#include "server/runtime/caller_identity.h"
#include "server/runtime/stream_limiter.h"
#include "server/wire/proto_convert.h"

namespace shapeid {

Work Work::Inline(Step run) {
  Work work;
  work.pieces_.push_back(
      Piece{/*inline_=*/true, /*store=*/false, absl::ZeroDuration(), 0, std::move(run), nullptr});
  return work;
}

Work Work::Compute(absl::Duration cost, size_t memory, Step run) {
  Work work;
  work.pieces_.push_back(Piece{false, false, cost, memory, std::move(run), nullptr});
  return work;
}

Work Work::Planned(std::function<WorkEstimate()> plan, Step run) {
  Work work;
  work.pieces_.push_back(
      Piece{false, false, absl::ZeroDuration(), 0, std::move(run), std::move(plan)});
  return work;
}

Work Work::Store(absl::Duration cost, Step run) {
  Work work;
  work.pieces_.push_back(Piece{false, /*store=*/true, cost, 0, std::move(run), nullptr});
  return work;
}

Work Work::Then(Work next) && {
  for (Piece& piece : next.pieces_) pieces_.push_back(std::move(piece));
  return std::move(*this);
}

struct AdmittedCall::Chain {
  std::vector<Work::Piece> pieces;
  size_t next = 0;
  std::function<void(absl::Status)> done;
};

AdmittedCall::AdmittedCall(grpc::CallbackServerContext* context, const ServiceRuntime& runtime,
                           absl::string_view full_method, CallGate::Kind kind)
    : context_(context),
      runtime_(runtime),
      record_(runtime.observer->Start(*context, full_method)) {
  absl::StatusOr<CallGate::Pass> pass = runtime_.gate->Admit(*context, full_method, kind);
  if (!pass.ok()) {
    admission_ = pass.status();
    return;
  }
  pass_.emplace(*std::move(pass));
  record_.caller = std::string(pass_->caller());
  absl::StatusOr<std::string> caller = CallerOf(*context, record_.caller);
  if (!caller.ok()) {
    admission_ = caller.status();
    pass_.reset();
    return;
  }
  caller_ = *std::move(caller);
  // Unary calls have no ceiling: their size is bounded by the message limit instead.
  if (kind == CallGate::Kind::kStream) {
    if (const std::optional<absl::Time> cut = runtime_.gate->CutOff(*context)) cut_off_ = *cut;
  }
  deadline_ = cut_off_;
  const gpr_timespec raw = context->raw_deadline();
  if (gpr_time_cmp(raw, gpr_inf_future(raw.clock_type)) != 0) {
    deadline_ = std::min(deadline_, absl::FromChrono(context->deadline()));
  }
}

void AdmittedCall::ArmCeiling(absl::Duration slack, std::function<void()> expire) {
  if (cut_off_ == absl::InfiniteFuture()) return;
  ceiling_.Arm(cut_off_ + slack, std::move(expire));
}

absl::Status AdmittedCall::HoldMemory(size_t bytes, absl::string_view what) {
  if (runtime_.budget == nullptr || bytes == 0) return absl::OkStatus();
  if (memory_.bytes() > 0) return memory_.Grow(bytes, what);
  absl::StatusOr<MemoryBudget::Grant> grant = runtime_.budget->Reserve(caller_, bytes, what);
  if (!grant.ok()) return grant.status();
  memory_ = *std::move(grant);
  return absl::OkStatus();
}

absl::Status AdmittedCall::HoldAnswer(const google::protobuf::MessageLite& response,
                                      absl::string_view smaller) {
  const size_t bytes = response.ByteSizeLong();
  const size_t limit = runtime_.options->max_answer_bytes;
  if (limit > 0 && bytes > limit) {
    return absl::ResourceExhaustedError(absl::StrCat(
        method(), ": the answer would be ", bytes, " bytes, more than this server sends in one ",
        "message (", limit, ", --max_answer_bytes); ask for ", smaller));
  }
  return HoldMemory(2 * bytes,
                    absl::StrCat("the answer (", bytes, " bytes; ask for ", smaller, ")"));
}

absl::Status AdmittedCall::Interruption() const {
  if (context_->IsCancelled()) {
    return absl::CancelledError("the call was cancelled; its work stopped");
  }
  if (absl::Now() >= deadline_) {
    return absl::DeadlineExceededError(
        "the call's deadline passed while its work ran; the work stopped");
  }
  return absl::OkStatus();
}

void AdmittedCall::Run(Work work, std::function<void(absl::Status)> done) {
  auto chain = std::make_shared<Chain>();
  chain->pieces = std::move(work.pieces_);
  chain->done = std::move(done);
  RunNext(chain);
}

void AdmittedCall::RunNext(const std::shared_ptr<Chain>& chain) {
  while (chain->next < chain->pieces.size()) {
    Work::Piece& piece = chain->pieces[chain->next++];
    if (piece.inline_) {
      if (absl::Status status = piece.run(); !status.ok()) return chain->done(std::move(status));
      continue;
    }
    if (piece.plan) {
      const WorkEstimate estimate = piece.plan();
      piece.cost = estimate.cpu;
      piece.memory = estimate.memory;
    }
    WorkOrder order;
    order.caller = caller_;
    order.cost = piece.cost;
    order.memory = piece.memory;
    order.held = memory_.bytes() + (held_elsewhere_ ? held_elsewhere_() : 0);
    order.store = piece.store;
    order.deadline = deadline_;
    grpc::CallbackServerContext* context = context_;
    order.cancelled = [context] { return context->IsCancelled(); };
    const absl::Status submitted =
        runtime_.scheduler->Submit(std::move(order), [this, chain](const WorkStart& start) {
          runtime_.observer->Waited(record_, WorkLaneName(start.lane), start.waited);
          if (!start.status.ok()) return chain->done(start.status);
          if (absl::Status status = chain->pieces[chain->next - 1].run(); !status.ok()) {
            return chain->done(std::move(status));
          }
          RunNext(chain);
        });
    if (!submitted.ok()) chain->done(submitted);
    return;
  }
  chain->done(absl::OkStatus());
}

grpc::Status AdmittedCall::Conclude(const grpc::Status& status, bool report) {
  final_status_ = status;
  if (pass_.has_value()) pass_->ReleaseSlot();
  memory_.Release();
  if (report) runtime_.observer->Finish(record_, status);
  return status;
}

absl::StatusOr<std::shared_ptr<Gallery>> NamedGallery(const ServiceRuntime& runtime,
                                                      CallRecord& record, absl::string_view name) {
  record.gallery = std::string(name);
  SHAPEID_RETURN_IF_ERROR(RequireGalleryName(record.method, name));
  return runtime.registry->Get(name);
}

}  // namespace shapeid
