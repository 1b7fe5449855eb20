#ifndef SHAPEID_SERVER_TESTING_RAW_CALL_H_
#define SHAPEID_SERVER_TESTING_RAW_CALL_H_

// For tests: a call whose request messages are arbitrary bytes, as a buggy or hostile client
// would send them, which the generated stubs cannot do (they serialize valid messages only).

#include <chrono>
#include <memory>
#include <string>
#include <vector>

#include "grpcpp/generic/generic_stub.h"
#include "grpcpp/grpcpp.h"

namespace shapeid::testing_raw {

// Calls `method` ("/shapeid.v1.ShapeId/Train") on `channel`, writing each of `messages` as
// one message, then half-closing (where the server has not answered yet), and returns the
// status. `reply`, when given, receives the answer's bytes. Works for unary and client-
// streaming methods alike.
inline grpc::Status RawCall(const std::shared_ptr<grpc::Channel>& channel,
                            const std::string& method, const std::vector<std::string>& messages,
                            std::string* reply = nullptr,
                            std::chrono::seconds timeout = std::chrono::seconds(30)) {
  grpc::GenericStub generic(channel);
  grpc::CompletionQueue queue;
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + timeout);
  const auto wait = [&queue] {  // one operation at a time: the next event is its own
    void* tag = nullptr;
    bool ok = false;
    return queue.Next(&tag, &ok) && ok;
  };
  std::unique_ptr<grpc::GenericClientAsyncReaderWriter> call =
      generic.PrepareCall(&context, method, &queue);
  call->StartCall(nullptr);
  bool open = wait();
  for (size_t i = 0; open && i < messages.size(); ++i) {
    grpc::Slice slice(messages[i]);
    grpc::ByteBuffer buffer(&slice, 1);
    call->Write(buffer, nullptr);
    open = wait();
  }
  if (open) {
    call->WritesDone(nullptr);
    wait();
  }
  grpc::ByteBuffer answer;
  call->Read(&answer, nullptr);
  std::vector<grpc::Slice> slices;
  if (wait() && reply != nullptr && answer.Dump(&slices).ok()) {
    reply->clear();
    for (const grpc::Slice& s : slices) {
      reply->append(reinterpret_cast<const char*>(s.begin()), s.size());
    }
  }
  grpc::Status status;
  call->Finish(&status, nullptr);
  wait();
  queue.Shutdown();
  for (void* tag = nullptr; queue.Next(&tag, &open);) {
  }
  return status;
}

}  // namespace shapeid::testing_raw

#endif  // SHAPEID_SERVER_TESTING_RAW_CALL_H_
