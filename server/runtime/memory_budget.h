#ifndef SHAPEID_SERVER_RUNTIME_MEMORY_BUDGET_H_
#define SHAPEID_SERVER_RUNTIME_MEMORY_BUDGET_H_

// A server-wide bound on the memory calls hold beyond the galleries: clouds in transit (a
// stream's points until it ends, a one-message cloud) and the working memory of describing
// them. Each caller may hold only a share of it, so that one caller cannot take it all and
// leave the others refused. gRPC-free.

#include <cstddef>
#include <cstdint>
#include <map>
#include <mutex>
#include <string>

#include "absl/base/thread_annotations.h"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"

namespace shapeid {

struct MemoryBudgetOptions {
  // Bytes that all calls together may hold; 0: no bound (nothing is refused, all is counted).
  size_t total_bytes = 0;
  // The part of total_bytes one caller may hold, in (0, 1].
  double caller_share = 0.5;
};

// The total a server gets when --memory_budget_mib is 0 (auto): half of the memory the
// process may use (its cgroup's limit when it has one, else the machine's), the other half
// being left to the galleries, the process itself and gRPC's buffers.
size_t DefaultMemoryBudgetBytes();

// Thread-safe.
class MemoryBudget {
 public:
  explicit MemoryBudget(MemoryBudgetOptions options);
  MemoryBudget(const MemoryBudget&) = delete;
  MemoryBudget& operator=(const MemoryBudget&) = delete;

  // Bytes held by one caller for one purpose, given back when destroyed. Move-only. Must not
  // outlive its budget.
  class Grant {
   public:
    Grant() = default;
    Grant(Grant&& other) noexcept { *this = std::move(other); }
    Grant& operator=(Grant&& other) noexcept;
    Grant(const Grant&) = delete;
    Grant& operator=(const Grant&) = delete;
    ~Grant() { Release(); }

    // Holds `more` bytes in addition, or ResourceExhausted as MemoryBudget::Reserve (the
    // grant keeps what it held).
    absl::Status Grow(size_t more, absl::string_view what = "the cloud in transit");
    // Gives everything back now.
    void Release();
    size_t bytes() const { return bytes_; }

   private:
    friend class MemoryBudget;
    MemoryBudget* budget_ = nullptr;
    std::string caller_;
    size_t bytes_ = 0;
  };

  // Holds `bytes` for `caller` ("key:lab", "10.0.0.7"), or ResourceExhausted naming the limit
  // that refused it (the caller's share or the server's total, with the numbers and the flag
  // that sets them). `what` says what the memory is for ("the cloud in transit"), for the
  // message.
  absl::StatusOr<Grant> Reserve(absl::string_view caller, size_t bytes,
                                absl::string_view what = "this call");

  // Whether Reserve(caller, bytes) would succeed now.
  bool Fits(absl::string_view caller, size_t bytes) const;
  // Whether `bytes` fit in what no caller holds now (whoever asks: the server's total, not a
  // caller's share).
  bool FitsTotal(size_t bytes) const;
  // Whether Reserve(caller, bytes) could ever succeed (bytes within the caller's share).
  bool EverFits(size_t bytes) const { return total_ == 0 || bytes <= per_caller_; }
  // The status Reserve gives `caller` for `bytes` when it does not fit.
  absl::Status Refusal(absl::string_view caller, size_t bytes, absl::string_view what) const;

  size_t total_bytes() const { return total_; }  // 0: no bound
  size_t caller_bytes() const { return per_caller_; }
  size_t held_bytes() const;
  size_t held_bytes(absl::string_view caller) const;
  // The most held at once since the budget was made.
  size_t peak_bytes() const;

 private:
  bool FitsLocked(absl::string_view caller, size_t bytes) const ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);
  absl::Status RefusalLocked(absl::string_view caller, size_t bytes, absl::string_view what) const
      ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);
  void Take(const std::string& caller, size_t bytes) ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);
  void Give(const std::string& caller, size_t bytes);

  const size_t total_;
  const size_t per_caller_;
  mutable std::mutex mu_;
  size_t held_ ABSL_GUARDED_BY(mu_) = 0;
  size_t peak_ ABSL_GUARDED_BY(mu_) = 0;
  std::map<std::string, size_t, std::less<>> by_caller_ ABSL_GUARDED_BY(mu_);
};

}  // namespace shapeid

#endif  // SHAPEID_SERVER_RUNTIME_MEMORY_BUDGET_H_
