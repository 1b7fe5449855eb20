#ifndef SHAPEID_SERVER_RUNTIME_CEILING_ALARM_H_
#define SHAPEID_SERVER_RUNTIME_CEILING_ALARM_H_

#include <functional>
#include <memory>
#include <mutex>
#include <utility>

#include "absl/time/time.h"
#include "grpcpp/alarm.h"

namespace shapeid {

// Runs a function at a point in time unless disarmed first: how a stream reactor ends a call
// at the server's ceiling (CallGate::CutOff). gRPC's callback alarm may fire on any thread,
// and may still be running or pending when its owner is done; Disarm makes sure the function
// is neither running nor going to run, so the owner may then delete itself.
class CeilingAlarm {
 public:
  CeilingAlarm() = default;
  CeilingAlarm(const CeilingAlarm&) = delete;
  CeilingAlarm& operator=(const CeilingAlarm&) = delete;
  ~CeilingAlarm() { Disarm(); }

  // At most once per alarm.
  void Arm(absl::Time when, std::function<void()> expire) {
    shared_ = std::make_shared<Shared>();
    shared_->expire = std::move(expire);
    alarm_ = std::make_unique<grpc::Alarm>();
    alarm_->Set(absl::ToChronoTime(when), [shared = shared_](bool fired) {
      std::lock_guard<std::mutex> lock(shared->mu);
      if (fired && shared->expire) shared->expire();
      shared->expire = nullptr;
    });
  }

  // Waits for a running function to return; afterwards it never runs. Idempotent.
  void Disarm() {
    if (shared_ == nullptr) return;
    {
      std::lock_guard<std::mutex> lock(shared_->mu);
      shared_->expire = nullptr;
    }
    alarm_->Cancel();
    shared_ = nullptr;
  }

 private:
  // Outlives the owner when the alarm's callback is still pending.
  struct Shared {
    std::mutex mu;
    std::function<void()> expire;
  };
  std::shared_ptr<Shared> shared_;
  // Made only when armed: most calls carry a deadline within the ceiling and need none.
  std::unique_ptr<grpc::Alarm> alarm_;
};

}  // namespace shapeid

#endif  // SHAPEID_SERVER_RUNTIME_CEILING_ALARM_H_
