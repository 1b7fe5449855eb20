#include "server/calls/gallery_rpcs.h"

#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "absl/strings/escaping.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "core/descriptor_registry.h"
#include "core/gallery/gallery.h"
#include "core/gallery/gallery_registry.h"
#include "core/status_macros.h"
#include "google/protobuf/io/coded_stream.h"
#include "server/calls/service_options.h"
#include "server/runtime/work_costs.h"
#include "server/wire/proto_convert.h"

namespace shapeid {
namespace {

// A store write of a gallery's metadata or samples: cheap for the CPU, slow on the disk.
constexpr absl::Duration kStoreWriteCost = absl::Milliseconds(1);

constexpr uint32_t kDefaultPageSize = 1000;
constexpr uint32_t kMaxPageSize = 10000;

// A ListSamples page token: the gallery's incarnation and the last id returned, so that a
// token from another gallery (or an earlier one of the same name) is refused, not misread.
std::string PageToken(uint64_t incarnation, uint64_t last_id) {
  return absl::StrCat(incarnation, ".", last_id);
}

// What a ListSamplesResponse holds besides its samples: the page token (two uint64s and a
// dot, 41 characters at most) and the gallery version, with their tags and lengths.
constexpr size_t kPageOverheadBytes = 64;

// `page`'s samples into `response`, in order, while the response stays within `max_bytes`
// (but at least one sample), and the token of the next page: after the last sample sent,
// whether the page was cut by its size in bytes or by its count.
void FillSamplePage(const SamplePage& page, uint64_t incarnation, size_t max_bytes,
                    v1::ListSamplesResponse* response) {
  size_t bytes = kPageOverheadBytes;
  bool cut = false;
  for (const SampleInfo& sample : page.samples) {
    v1::SampleInfo* out = response->add_samples();
    ToProto(sample, out);
    const size_t size = out->ByteSizeLong();
    // The repeated field's tag (one byte) and length, then the message.
    const size_t entry = 1 + google::protobuf::io::CodedOutputStream::VarintSize64(size) + size;
    if (response->samples_size() > 1 && bytes + entry > max_bytes) {
      response->mutable_samples()->RemoveLast();
      cut = true;
      break;
    }
    bytes += entry;
  }
  if (cut || page.more) {
    response->set_next_page_token(
        PageToken(incarnation, response->samples(response->samples_size() - 1).sample_id()));
  }
}

absl::StatusOr<uint64_t> LastIdOfToken(absl::string_view token, uint64_t incarnation) {
  const std::vector<absl::string_view> parts = absl::StrSplit(token, '.');
  uint64_t token_incarnation = 0, last_id = 0;
  if (parts.size() != 2 || !absl::SimpleAtoi(parts[0], &token_incarnation) ||
      !absl::SimpleAtoi(parts[1], &last_id) || token_incarnation != incarnation) {
    return absl::InvalidArgumentError(
        absl::StrCat("ListSamples: page_token \"", absl::CHexEscape(token.substr(0, 64)),
                     "\" was not given by this gallery; start again with an empty token"));
  }
  return last_id;
}

}  // namespace

absl::StatusOr<Work> CreateGalleryRpc::Handle(const ServiceRuntime& runtime, const Request& request,
                                              Response* response, AdmittedCall& call) {
  call.record().gallery = request.name();
  SHAPEID_ASSIGN_OR_RETURN(const GalleryOptions options, GalleryOptionsFromProto(request));
  return Work::Store(kStoreWriteCost, [&runtime, &request, response, options] {
    SHAPEID_ASSIGN_OR_RETURN(const std::shared_ptr<Gallery> gallery,
                             runtime.registry->Create(request.name(), options));
    ToProto(*gallery->Snapshot(), response);
    return absl::OkStatus();
  });
}

absl::Status GetGalleryRpc::Handle(const ServiceRuntime& runtime, const Request& request,
                                   Response* response, AdmittedCall& call) {
  SHAPEID_ASSIGN_OR_RETURN(const std::shared_ptr<Gallery> gallery,
                           NamedGallery(runtime, call.record(), request.name()));
  ToProto(*gallery->Snapshot(), response);
  return absl::OkStatus();
}

absl::Status ListGalleriesRpc::Handle(const ServiceRuntime& runtime, const Request& /*request*/,
                                      Response* response, AdmittedCall& /*call*/) {
  for (const std::shared_ptr<Gallery>& gallery : runtime.registry->All()) {
    ToProto(*gallery->Snapshot(), response->add_galleries());
  }
  return absl::OkStatus();
}

absl::StatusOr<Work> DeleteGalleryRpc::Handle(const ServiceRuntime& runtime, const Request& request,
                                              Response* response, AdmittedCall& call) {
  SHAPEID_ASSIGN_OR_RETURN(const std::shared_ptr<Gallery> gallery,
                           NamedGallery(runtime, call.record(), request.name()));
  return Work::Store(kStoreWriteCost, [&runtime, &request, response, &call, gallery] {
    const int64_t samples = gallery->Snapshot()->num_samples();
    SHAPEID_RETURN_IF_ERROR(runtime.registry->Delete(request.name()));
    response->set_samples_deleted(static_cast<uint64_t>(samples));
    call.record().samples = samples;
    return absl::OkStatus();
  });
}

absl::StatusOr<Work> RemoveSamplesRpc::Handle(const ServiceRuntime& runtime, const Request& request,
                                              Response* response, AdmittedCall& call) {
  SHAPEID_ASSIGN_OR_RETURN(const std::shared_ptr<Gallery> gallery,
                           NamedGallery(runtime, call.record(), request.gallery()));
  if (request.sample_ids().empty() && request.labels().empty()) {
    return absl::InvalidArgumentError("RemoveSamples: give sample_ids, labels or both");
  }
  return Work::Store(EstimateRemove(*gallery->Snapshot()), [&request, response, &call, gallery] {
    const std::vector<std::string> labels(request.labels().begin(), request.labels().end());
    SHAPEID_ASSIGN_OR_RETURN(
        const int64_t removed,
        gallery->RemoveSamples(
            absl::MakeConstSpan(request.sample_ids().data(), request.sample_ids().size()), labels));
    response->set_removed(static_cast<uint64_t>(removed));
    call.record().samples = removed;
    response->set_remaining(static_cast<uint64_t>(gallery->Snapshot()->num_samples()));
    return absl::OkStatus();
  });
}

absl::StatusOr<Work> ListSamplesRpc::Handle(const ServiceRuntime& runtime, const Request& request,
                                            Response* response, AdmittedCall& call) {
  // The page size is checked before the gallery is looked up, as a request's own fault.
  if (request.page_size() > kMaxPageSize && !request.gallery().empty()) {
    call.record().gallery = request.gallery();
    return absl::InvalidArgumentError(
        absl::StrCat("ListSamples: page_size ", request.page_size(), " is over ", kMaxPageSize));
  }
  SHAPEID_ASSIGN_OR_RETURN(const std::shared_ptr<Gallery> gallery,
                           NamedGallery(runtime, call.record(), request.gallery()));
  std::shared_ptr<const GallerySnapshot> snapshot = gallery->Snapshot();
  uint64_t after = 0;
  if (!request.page_token().empty()) {
    SHAPEID_ASSIGN_OR_RETURN(after, LastIdOfToken(request.page_token(), snapshot->incarnation()));
  }
  // A scan of the gallery's ids: priced like a removal's pass over its rows.
  const absl::Duration cost = EstimateRemove(*snapshot);
  return Work::Compute(cost, 0,
                       [&request, response, &call, after, snapshot = std::move(snapshot),
                        max_bytes = runtime.options->max_answer_bytes] {
                         const uint32_t page_size =
                             request.page_size() == 0 ? kDefaultPageSize : request.page_size();
                         const SamplePage page =
                             snapshot->ListSamples(request.label(), after, page_size);
                         FillSamplePage(page, snapshot->incarnation(), max_bytes, response);
                         response->set_gallery_version(snapshot->version());
                         call.record().samples = response->samples_size();
                         // Cut to max_answer_bytes above, but for a single sample: held, never
                         // refused.
                         return call.HoldMemory(2 * response->ByteSizeLong(), "the page");
                       });
}

absl::Status ListDescriptorsRpc::Handle(const ServiceRuntime& /*runtime*/,
                                        const Request& /*request*/, Response* response,
                                        AdmittedCall& /*call*/) {
  return ToProto(RegisteredDescriptors(), response);
}

}  // namespace shapeid
