#ifndef SHAPEID_FUZZ_FUZZ_SERVICE_H_
#define SHAPEID_FUZZ_FUZZ_SERVICE_H_

#include <memory>
#include <string>

#include "core/gallery/gallery_registry.h"
#include "grpcpp/grpcpp.h"
#include "server/calls/shapeid_service.h"
#include "service_session.pb.h"
#include "shapeid/v1/shapeid.grpc.pb.h"

namespace shapeid::fuzz {

// A fresh ShapeId service on an in-process channel (no socket), with small limits so that
// every limit is within a fuzzer's reach and an iteration stays in the milliseconds, and one
// trained gallery "base" (three samples, labels box / sphere / rod), so that Classify,
// RemoveSamples and ExportGallery have something to work on.
class FuzzServer {
 public:
  FuzzServer();
  ~FuzzServer();
  FuzzServer(const FuzzServer&) = delete;
  FuzzServer& operator=(const FuzzServer&) = delete;

  v1::ShapeId::Stub& stub() { return *stub_; }

  // Runs one call of a session and returns its status (the client's view: CANCELLED when
  // the call's cancel_after made the client give up).
  grpc::Status Run(const Call& call);

  // Every gallery, as the service reports it (ListGalleries), in one comparable string.
  std::string GalleriesState();

 private:
  std::shared_ptr<GalleryRegistry> registry_;
  std::unique_ptr<ShapeIdService> service_;
  std::unique_ptr<grpc::Server> server_;
  std::unique_ptr<v1::ShapeId::Stub> stub_;
};

// Runs `session` (at most 16 calls, streams cut at 64 messages) and checks, after every call,
// what the proto promises every client (proto/shapeid/v1/shapeid.proto):
//  - the status is OK or one of the documented codes (INVALID_ARGUMENT, NOT_FOUND,
//    ALREADY_EXISTS, FAILED_PRECONDITION, RESOURCE_EXHAUSTED, DATA_LOSS), or CANCELLED when
//    the client cancelled: never UNKNOWN, INTERNAL or a deadline;
//  - a failed call changes no gallery;
//  - an OK answer is well formed (finite descriptor values, neighbors sorted by distance, a
//    scene's points all accounted for and its indices ascending within the frame);
// and at the end that the server still answers and the surviving "base" still classifies.
// A broken promise aborts, so libFuzzer keeps the input.
void RunSession(const ServiceSession& session);

}  // namespace shapeid::fuzz

#endif  // SHAPEID_FUZZ_FUZZ_SERVICE_H_
