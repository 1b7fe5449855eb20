#include "server/ops/call_observer.h"

#include <cstdio>

#include "absl/random/random.h"
#include "absl/strings/ascii.h"
#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "core/request_id.h"

namespace shapeid {
namespace {

std::string NewRequestId() {
  thread_local absl::InsecureBitGen random;
  char id[17];
  std::snprintf(id, sizeof id, "%016llx",
                static_cast<unsigned long long>(absl::Uniform<uint64_t>(random)));
  return id;
}

// Failures the client caused or can retry are warnings; the server's own faults errors.
LogLevel LevelOf(grpc::StatusCode code) {
  switch (code) {
    case grpc::StatusCode::OK:
      return LogLevel::kInfo;
    case grpc::StatusCode::UNKNOWN:
    case grpc::StatusCode::INTERNAL:
    case grpc::StatusCode::DATA_LOSS:
    case grpc::StatusCode::UNIMPLEMENTED:
      return LogLevel::kError;
    default:
      return LogLevel::kWarning;
  }
}

}  // namespace

CallRecord CallObserver::Start(grpc::CallbackServerContext& context,
                               absl::string_view full_method) const {
  CallRecord record;
  record.method = full_method.substr(full_method.rfind('/') + 1);
  record.start = absl::Now();
  const auto& metadata = context.client_metadata();
  const auto it = metadata.find(kRequestIdMetadata);
  if (it != metadata.end() &&
      IsValidRequestId(absl::string_view(it->second.data(), it->second.size()))) {
    record.request_id.assign(it->second.data(), it->second.size());
  } else {
    record.request_id = NewRequestId();
  }
  context.AddInitialMetadata(kRequestIdMetadata, record.request_id);
  if (logger_ != nullptr) record.peer = context.peer();
  return record;
}

void CallObserver::Finish(CallRecord& record, const grpc::Status& status) const {
  if (record.finished) return;
  record.finished = true;
  const absl::Duration elapsed = absl::Now() - record.start;
  const auto code = static_cast<absl::StatusCode>(status.error_code());
  if (metrics_ != nullptr) {
    metrics_->RecordCall({record.method, record.gallery, code, elapsed, record.points,
                          record.method == "Train" && status.ok() ? record.samples : 0,
                          record.wait_time});
  }
  const LogLevel level = LevelOf(status.error_code());
  if (logger_ == nullptr || !logger_->Enabled(level)) return;
  const std::string code_name = absl::StatusCodeToString(code);
  // Bounded, whatever a client sent: a gallery name is at most 128 bytes when valid, and an
  // error message may quote what the client sent.
  const absl::string_view gallery = absl::string_view(record.gallery).substr(0, 128);
  std::string error = status.error_message();  // a copy: LogField keeps a view
  if (error.size() > 1024) error = absl::StrCat(error.substr(0, 1024), "...");
  const LogField fields[] = {{"method", record.method},
                             {"gallery", gallery},
                             {"code", code_name},
                             {"us", absl::ToInt64Microseconds(elapsed)},
                             {"points", record.points},
                             {"samples", record.samples},
                             {"describe_us", absl::ToInt64Microseconds(record.describe_time)},
                             {"search_us", absl::ToInt64Microseconds(record.search_time)},
                             {"wait_us", absl::ToInt64Microseconds(record.wait_time)},
                             {"peer", record.peer},
                             {"caller", record.caller},
                             {"request_id", record.request_id},
                             {"error", error}};
  // The error field only for a failed call.
  logger_->Log(level, "rpc", absl::MakeConstSpan(fields, status.ok() ? 12 : 13));
}

void CallObserver::Described(CallRecord& record, absl::string_view kind,
                             absl::Duration elapsed) const {
  record.describe_time += elapsed;
  if (metrics_ != nullptr) metrics_->ObserveDescribe(kind, elapsed);
}

void CallObserver::Waited(CallRecord& record, absl::string_view lane, absl::Duration waited) const {
  record.wait_time += waited;
  if (metrics_ != nullptr) metrics_->ObserveWait(lane, waited);
}

void CallObserver::Searched(CallRecord& record, bool approximate, absl::Duration elapsed) const {
  record.search_time += elapsed;
  if (metrics_ != nullptr) metrics_->ObserveSearch(approximate, elapsed);
}

}  // namespace shapeid
