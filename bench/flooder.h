#ifndef SHAPEID_BENCH_FLOODER_H_
#define SHAPEID_BENCH_FLOODER_H_

// A hostile caller for the benches of a shared server (soak_bench, fair_server_bench): one
// channel and TCP connection of its own that keeps `in_flight` calls open at all times,
// starting the next as soon as one is answered or refused, so that its own share of the
// server is always full. It should be refused (RESOURCE_EXHAUSTED) itself while others are
// served; it counts what it got.

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "grpcpp/grpcpp.h"
#include "shapeid/v1/shapeid.grpc.pb.h"

namespace shapeid::bench {

struct FloodCounts {
  int64_t ok = 0;
  int64_t refused = 0;  // RESOURCE_EXHAUSTED: what a flooder should get
  int64_t other = 0;    // anything else
  std::string first_other;
};

class Flooder {
 public:
  // Starts one call on `stub` with `context` (prepared: deadline, key, caller id) and runs
  // `done` with its status when it ends; what the call sends and receives must live until
  // then (the function's closure may own it).
  using Send = std::function<void(v1::ShapeId::Stub& stub, grpc::ClientContext* context,
                                  std::function<void(grpc::Status)> done)>;

  Flooder(const std::string& address, std::function<void(grpc::ClientContext&)> prepare, Send send,
          int in_flight);
  ~Flooder() { Stop(); }
  Flooder(const Flooder&) = delete;
  Flooder& operator=(const Flooder&) = delete;

  void Start();
  // Stops sending and waits for the calls in flight.
  void Stop();
  FloodCounts counts() const;

 private:
  void SendOne();

  const std::function<void(grpc::ClientContext&)> prepare_;
  const Send send_;
  const int in_flight_;
  std::unique_ptr<v1::ShapeId::Stub> stub_;
  mutable std::mutex mu_;
  std::condition_variable changed_;
  bool stopping_ = false;
  int open_ = 0;
  FloodCounts counts_;
  std::thread thread_;
};

}  // namespace shapeid::bench

#endif  // SHAPEID_BENCH_FLOODER_H_
