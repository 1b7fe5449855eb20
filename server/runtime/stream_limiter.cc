#include "server/runtime/stream_limiter.h"

#include <utility>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_replace.h"
#include "absl/strings/strip.h"

namespace shapeid {

std::string ClientOfPeer(absl::string_view peer) {
  absl::string_view rest = peer;
  if (!absl::ConsumePrefix(&rest, "ipv4:") && !absl::ConsumePrefix(&rest, "ipv6:")) {
    return std::string(peer);
  }
  // Newer gRPC releases percent-encode the brackets of an IPv6 address.
  std::string host = absl::StrReplaceAll(rest, {{"%5B", "["}, {"%5D", "]"}});
  if (!host.empty() && host.front() == '[') {
    const size_t close = host.find(']');
    return close == std::string::npos ? host : host.substr(1, close - 1);
  }
  if (const size_t colon = host.rfind(':'); colon != std::string::npos) host.resize(colon);
  return host;
}

StreamLimiter::Slot& StreamLimiter::Slot::operator=(Slot&& other) noexcept {
  if (this != &other) {
    Release();
    limiter_ = std::exchange(other.limiter_, nullptr);
    client_ = std::move(other.client_);
  }
  return *this;
}

void StreamLimiter::Slot::Release() {
  if (limiter_ == nullptr) return;
  std::lock_guard<std::mutex> lock(limiter_->mu_);
  auto it = limiter_->open_.find(client_);
  if (it != limiter_->open_.end() && --it->second == 0) limiter_->open_.erase(it);
  limiter_ = nullptr;
}

absl::StatusOr<StreamLimiter::Slot> StreamLimiter::Acquire(absl::string_view client) {
  Slot slot;
  if (max_per_client_ <= 0) return slot;
  std::lock_guard<std::mutex> lock(mu_);
  auto it = open_.find(client);
  const int open = it == open_.end() ? 0 : it->second;
  if (open >= max_per_client_) {
    return absl::ResourceExhaustedError(absl::StrCat(
        "client ", client, " has ", open, " streams open, the limit (max_streams_per_client) is ",
        max_per_client_, "; wait for one to end"));
  }
  if (it == open_.end()) {
    open_.emplace(std::string(client), 1);
  } else {
    ++it->second;
  }
  slot.limiter_ = this;
  slot.client_ = std::string(client);
  return slot;
}

int StreamLimiter::open(absl::string_view client) const {
  std::lock_guard<std::mutex> lock(mu_);
  auto it = open_.find(client);
  return it == open_.end() ? 0 : it->second;
}

}  // namespace shapeid
