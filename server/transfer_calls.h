#ifndef SHAPEID_SERVER_TRANSFER_CALLS_H_
#define SHAPEID_SERVER_TRANSFER_CALLS_H_

// The calls that move a whole gallery: ExportGallery (a server stream of chunks) and
// ImportGallery (a client stream of them). Chunks are made and checked on gRPC's threads (they
// only copy and checksum bytes); an import's building and storing runs on the scheduler's
// store lane.

#include "grpcpp/grpcpp.h"
#include "server/admitted_call.h"
#include "shapeid/v1/shapeid.pb.h"

namespace shapeid {

// Streams one snapshot of the gallery (server/gallery_export.h), so training during the
// export does not tear it; stops at the first failed write (client gone, deadline).
grpc::ServerWriteReactor<v1::GalleryExportChunk>* StartExport(
    grpc::CallbackServerContext* context, const ServiceRuntime& runtime,
    const v1::ExportGalleryRequest& request);

// Assembles and checks the export as it arrives (the first error ends the call; what it
// holds counts against the memory budget), then GalleryRegistry::Import: all-or-nothing.
// Messages v1::ImportGalleryRequest; answer v1::Gallery.
grpc::ServerReadReactor<grpc::ByteBuffer>* StartImport(grpc::CallbackServerContext* context,
                                                       const ServiceRuntime& runtime,
                                                       grpc::ByteBuffer* response);

}  // namespace shapeid

#endif  // SHAPEID_SERVER_TRANSFER_CALLS_H_
