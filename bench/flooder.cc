#include "bench/flooder.h"

#include <utility>

#include "absl/strings/str_cat.h"

namespace shapeid::bench {

Flooder::Flooder(const std::string& address, std::function<void(grpc::ClientContext&)> prepare,
                 Send send, int in_flight)
    : prepare_(std::move(prepare)), send_(std::move(send)), in_flight_(in_flight) {
  grpc::ChannelArguments args;
  args.SetInt(GRPC_ARG_USE_LOCAL_SUBCHANNEL_POOL, 1);  // a TCP connection of its own
  args.SetMaxReceiveMessageSize(-1);
  stub_ = v1::ShapeId::NewStub(
      grpc::CreateCustomChannel(address, grpc::InsecureChannelCredentials(), args));
}

void Flooder::Start() {
  thread_ = std::thread([this] {
    std::unique_lock<std::mutex> lock(mu_);
    while (true) {
      changed_.wait(lock, [this] { return stopping_ || open_ < in_flight_; });
      if (stopping_) break;
      ++open_;
      lock.unlock();
      SendOne();
      lock.lock();
    }
    changed_.wait(lock, [this] { return open_ == 0; });
  });
}

void Flooder::SendOne() {
  auto context = std::make_shared<grpc::ClientContext>();
  prepare_(*context);
  send_(*stub_, context.get(), [this, context](grpc::Status status) {
    std::lock_guard<std::mutex> lock(mu_);
    if (status.ok()) {
      ++counts_.ok;
    } else if (status.error_code() == grpc::StatusCode::RESOURCE_EXHAUSTED) {
      ++counts_.refused;
    } else {
      if (counts_.other++ == 0) {
        counts_.first_other = absl::StrCat(status.error_code(), ": ", status.error_message());
      }
    }
    --open_;
    changed_.notify_all();
  });
}

void Flooder::Stop() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    stopping_ = true;
    changed_.notify_all();
  }
  if (thread_.joinable()) thread_.join();
}

FloodCounts Flooder::counts() const {
  std::lock_guard<std::mutex> lock(mu_);
  return counts_;
}

}  // namespace shapeid::bench
