#ifndef SHAPEID_SERVER_CALLS_TRANSFER_RPCS_H_
#define SHAPEID_SERVER_CALLS_TRANSFER_RPCS_H_

// The RPCs that move a whole gallery: ExportGallery (a server stream of chunks) and
// ImportGallery (a client stream of them). Chunks are made and checked on gRPC's threads (they
// only copy and checksum bytes); an import's building and storing runs on the scheduler's
// store lane.

#include "absl/strings/string_view.h"
#include "grpcpp/grpcpp.h"
#include "server/calls/admitted_call.h"
#include "shapeid/v1/shapeid.pb.h"

namespace shapeid {

// Streams one snapshot of the gallery (server/wire/gallery_export.h), so training during the
// export does not tear it; stops at the first failed write (client gone, deadline).
struct ExportGalleryRpc {
  using Request = v1::ExportGalleryRequest;
  using Response = v1::GalleryExportChunk;
  static grpc::ServerWriteReactor<v1::GalleryExportChunk>* Start(
      grpc::CallbackServerContext* context, const ServiceRuntime& runtime, absl::string_view method,
      const v1::ExportGalleryRequest& request);
};

// Assembles and checks the export as it arrives (the first error ends the call; what it
// holds counts against the memory budget), then GalleryRegistry::Import: all-or-nothing.
// Messages v1::ImportGalleryRequest; answer v1::Gallery.
struct ImportGalleryRpc {
  static grpc::ServerReadReactor<grpc::ByteBuffer>* Start(grpc::CallbackServerContext* context,
                                                          const ServiceRuntime& runtime,
                                                          absl::string_view method,
                                                          grpc::ByteBuffer* response);
};

}  // namespace shapeid

#endif  // SHAPEID_SERVER_CALLS_TRANSFER_RPCS_H_
