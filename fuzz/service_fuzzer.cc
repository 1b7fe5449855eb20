// libFuzzer target: the ShapeId service's request validation. Each input is a ServiceSession
// (fuzz/service_session.proto, protobuf wire format): a sequence of calls with arbitrary
// messages, run on a fresh in-process server by RunSession (fuzz/fuzz_service.h), which
// checks the proto's promises after every call. Inputs that are not a ServiceSession are
// skipped: the wire format gives most byte strings some parse, so little is lost.

#include <cstddef>
#include <cstdint>

#include "fuzz/fuzz_service.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  shapeid::fuzz::ServiceSession session;
  if (!session.ParseFromArray(data, static_cast<int>(size))) return 0;
  shapeid::fuzz::RunSession(session);
  return 0;
}
