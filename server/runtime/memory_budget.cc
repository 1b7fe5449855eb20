#include "server/runtime/memory_budget.h"

#include <algorithm>
#include <cstdint>
#include <string>
#include <utility>

#include "absl/strings/str_cat.h"
#include "server/runtime/machine_limits.h"

namespace shapeid {
namespace {

constexpr double kMiB = 1024.0 * 1024.0;

std::string Mib(size_t bytes) {
  return absl::StrCat(static_cast<int64_t>(static_cast<double>(bytes) / kMiB + 0.5), " MiB");
}

}  // namespace

size_t DefaultMemoryBudgetBytes() { return MemoryLimitBytes() / 2; }

MemoryBudget::MemoryBudget(MemoryBudgetOptions options)
    : total_(options.total_bytes),
      per_caller_(static_cast<size_t>(
          static_cast<double>(options.total_bytes) *
          std::clamp(options.caller_share > 0 ? options.caller_share : 1.0, 0.0, 1.0))) {}

bool MemoryBudget::FitsLocked(absl::string_view caller, size_t bytes) const {
  if (total_ == 0) return true;
  if (bytes > total_ - std::min(held_, total_)) return false;
  const auto it = by_caller_.find(caller);
  const size_t mine = it == by_caller_.end() ? 0 : it->second;
  return bytes <= per_caller_ - std::min(mine, per_caller_);
}

bool MemoryBudget::FitsTotal(size_t bytes) const {
  std::lock_guard<std::mutex> lock(mu_);
  return total_ == 0 || bytes <= total_ - std::min(held_, total_);
}

bool MemoryBudget::Fits(absl::string_view caller, size_t bytes) const {
  std::lock_guard<std::mutex> lock(mu_);
  return FitsLocked(caller, bytes);
}

absl::Status MemoryBudget::RefusalLocked(absl::string_view caller, size_t bytes,
                                         absl::string_view what) const {
  const auto it = by_caller_.find(caller);
  const size_t mine = it == by_caller_.end() ? 0 : it->second;
  if (bytes > per_caller_) {
    return absl::ResourceExhaustedError(absl::StrCat(
        what, " needs ", Mib(bytes), " of server memory, more than one caller may hold (",
        Mib(per_caller_), " of the server's budget of ", Mib(total_),
        ", --memory_budget_mib); send a smaller cloud"));
  }
  if (mine + bytes > per_caller_) {
    return absl::ResourceExhaustedError(absl::StrCat(
        what, " needs ", Mib(bytes), " of server memory, but this caller's calls already hold ",
        Mib(mine), " of the ", Mib(per_caller_),
        " one caller may hold (a share of --memory_budget_mib); retry when they have ended"));
  }
  return absl::ResourceExhaustedError(absl::StrCat(
      what, " needs ", Mib(bytes), " of server memory, but calls hold ", Mib(held_),
      " of the server's budget of ", Mib(total_), " (--memory_budget_mib); retry shortly"));
}

absl::Status MemoryBudget::Refusal(absl::string_view caller, size_t bytes,
                                   absl::string_view what) const {
  std::lock_guard<std::mutex> lock(mu_);
  return RefusalLocked(caller, bytes, what);
}

void MemoryBudget::Take(const std::string& caller, size_t bytes) {
  held_ += bytes;
  peak_ = std::max(peak_, held_);
  by_caller_[caller] += bytes;
}

void MemoryBudget::Give(const std::string& caller, size_t bytes) {
  if (bytes == 0) return;
  std::lock_guard<std::mutex> lock(mu_);
  held_ -= bytes;
  const auto it = by_caller_.find(caller);
  if (it == by_caller_.end()) return;
  it->second -= bytes;
  if (it->second == 0) by_caller_.erase(it);
}

absl::StatusOr<MemoryBudget::Grant> MemoryBudget::Reserve(absl::string_view caller, size_t bytes,
                                                          absl::string_view what) {
  Grant grant;
  grant.budget_ = this;
  grant.caller_ = std::string(caller);
  if (bytes == 0) return grant;
  std::lock_guard<std::mutex> lock(mu_);
  if (!FitsLocked(caller, bytes)) return RefusalLocked(caller, bytes, what);
  Take(grant.caller_, bytes);
  grant.bytes_ = bytes;
  return grant;
}

absl::Status MemoryBudget::Grant::Grow(size_t more, absl::string_view what) {
  if (more == 0) return absl::OkStatus();
  if (budget_ == nullptr) return absl::FailedPreconditionError("an empty memory grant cannot grow");
  std::lock_guard<std::mutex> lock(budget_->mu_);
  if (!budget_->FitsLocked(caller_, more)) {
    return budget_->RefusalLocked(caller_, more,
                                  absl::StrCat(what, " (", Mib(bytes_), " held so far)"));
  }
  budget_->Take(caller_, more);
  bytes_ += more;
  return absl::OkStatus();
}

void MemoryBudget::Grant::Release() {
  if (budget_ != nullptr) budget_->Give(caller_, bytes_);
  bytes_ = 0;
}

MemoryBudget::Grant& MemoryBudget::Grant::operator=(Grant&& other) noexcept {
  if (this != &other) {
    Release();
    budget_ = std::exchange(other.budget_, nullptr);
    caller_ = std::move(other.caller_);
    bytes_ = std::exchange(other.bytes_, 0);
  }
  return *this;
}

size_t MemoryBudget::held_bytes() const {
  std::lock_guard<std::mutex> lock(mu_);
  return held_;
}

size_t MemoryBudget::held_bytes(absl::string_view caller) const {
  std::lock_guard<std::mutex> lock(mu_);
  const auto it = by_caller_.find(caller);
  return it == by_caller_.end() ? 0 : it->second;
}

size_t MemoryBudget::peak_bytes() const {
  std::lock_guard<std::mutex> lock(mu_);
  return peak_;
}

}  // namespace shapeid
