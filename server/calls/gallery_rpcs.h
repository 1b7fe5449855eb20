#ifndef SHAPEID_SERVER_CALLS_GALLERY_RPCS_H_
#define SHAPEID_SERVER_CALLS_GALLERY_RPCS_H_

// The one-message RPCs on galleries and descriptors (server/calls/rpc_list.h, shape kUnary), each
// declared by its request, its response and a handler served by server/calls/unary_call.h: one that
// returns absl::Status answers on gRPC's thread (microseconds); one that returns Work hands
// its store write or scan to the scheduler.

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "server/calls/admitted_call.h"
#include "shapeid/v1/shapeid.pb.h"

namespace shapeid {

// A new, empty gallery (ALREADY_EXISTS if the name is taken).
struct CreateGalleryRpc {
  using Request = v1::CreateGalleryRequest;
  using Response = v1::Gallery;
  static absl::StatusOr<Work> Handle(const ServiceRuntime& runtime, const Request& request,
                                     Response* response, AdmittedCall& call);
};

struct GetGalleryRpc {
  using Request = v1::GetGalleryRequest;
  using Response = v1::Gallery;
  static absl::Status Handle(const ServiceRuntime& runtime, const Request& request,
                             Response* response, AdmittedCall& call);
};

struct ListGalleriesRpc {
  using Request = v1::ListGalleriesRequest;
  using Response = v1::ListGalleriesResponse;
  static absl::Status Handle(const ServiceRuntime& runtime, const Request& request,
                             Response* response, AdmittedCall& call);
};

// Deletes a gallery and its samples from the store.
struct DeleteGalleryRpc {
  using Request = v1::DeleteGalleryRequest;
  using Response = v1::DeleteGalleryResponse;
  static absl::StatusOr<Work> Handle(const ServiceRuntime& runtime, const Request& request,
                                     Response* response, AdmittedCall& call);
};

// Removes samples by id, by label, or both.
struct RemoveSamplesRpc {
  using Request = v1::RemoveSamplesRequest;
  using Response = v1::RemoveSamplesResponse;
  static absl::StatusOr<Work> Handle(const ServiceRuntime& runtime, const Request& request,
                                     Response* response, AdmittedCall& call);
};

// One page of a gallery's samples, in id order, cut at the service's answer size; its page
// token names the gallery's incarnation, so a token from another gallery is refused.
struct ListSamplesRpc {
  using Request = v1::ListSamplesRequest;
  using Response = v1::ListSamplesResponse;
  static absl::StatusOr<Work> Handle(const ServiceRuntime& runtime, const Request& request,
                                     Response* response, AdmittedCall& call);
};

struct ListDescriptorsRpc {
  using Request = v1::ListDescriptorsRequest;
  using Response = v1::ListDescriptorsResponse;
  static absl::Status Handle(const ServiceRuntime& runtime, const Request& request,
                             Response* response, AdmittedCall& call);
};

}  // namespace shapeid

#endif  // SHAPEID_SERVER_CALLS_GALLERY_RPCS_H_
