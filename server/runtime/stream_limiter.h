#ifndef SHAPEID_SERVER_RUNTIME_STREAM_LIMITER_H_
#define SHAPEID_SERVER_RUNTIME_STREAM_LIMITER_H_

// Streams open per client, bounded (ServiceOptions::max_streams_per_client). gRPC-free.

#include <map>
#include <mutex>
#include <string>

#include "absl/base/thread_annotations.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"

namespace shapeid {

// The client a gRPC peer string names, for counting: its host without the port
// ("ipv4:10.1.2.3:5555" -> "10.1.2.3", "ipv6:[::1]:5555" or "ipv6:%5B::1%5D:5555" -> "::1").
// Any other form ("unix:/run/s.sock") is returned as it is: one client.
std::string ClientOfPeer(absl::string_view peer);

// Counts the streams each client has open and refuses one over the limit. Thread-safe.
class StreamLimiter {
 public:
  // A stream's place in its client's count; released when destroyed. Move-only.
  class Slot {
   public:
    Slot() = default;
    Slot(Slot&& other) noexcept { *this = std::move(other); }
    Slot& operator=(Slot&& other) noexcept;
    Slot(const Slot&) = delete;
    Slot& operator=(const Slot&) = delete;
    ~Slot() { Release(); }

   private:
    friend class StreamLimiter;
    void Release();
    StreamLimiter* limiter_ = nullptr;
    std::string client_;
  };

  // `max_per_client` 0: no limit (every Acquire succeeds, nothing is counted).
  explicit StreamLimiter(int max_per_client) : max_per_client_(max_per_client) {}

  // A slot for one more stream of `client`, or ResourceExhausted naming the client, the
  // limit and the flag that sets it.
  absl::StatusOr<Slot> Acquire(absl::string_view client);

  int open(absl::string_view client) const;  // streams `client` has open now

 private:
  const int max_per_client_;
  mutable std::mutex mu_;
  std::map<std::string, int, std::less<>> open_ ABSL_GUARDED_BY(mu_);
};

}  // namespace shapeid

#endif  // SHAPEID_SERVER_RUNTIME_STREAM_LIMITER_H_
