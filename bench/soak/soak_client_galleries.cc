// The gallery requests of a SoakClient (create, read, list, export, delete, import) and the
// resync after an error; the sample requests are in soak_client.cc.

#include <algorithm>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "bench/soak/soak_client.h"
#include "client/client.h"

namespace shapeid::soak {

absl::Status SoakClient::Resync() {
  pending_.clear();
  train_scratch_next_ = false;
  std::vector<v1::GalleryExportChunk> chunks;
  if (absl::Status s = ReadExport(&chunks); !s.ok()) return s;
  held_.clear();
  for (const v1::GalleryExportChunk& chunk : chunks) {
    if (!chunk.has_samples()) continue;
    for (int i = 0; i < chunk.samples().sample_ids_size(); ++i) {
      held_.push_back({chunk.samples().sample_ids(i), chunk.samples().labels(i), SIZE_MAX});
      next_id_ = std::max(next_id_, chunk.samples().sample_ids(i) + 1);
    }
  }
  grpc::ClientContext context;
  SetDeadline(context);
  v1::GetGalleryRequest request;
  request.set_name(scratch_);
  v1::Gallery gallery;
  const grpc::Status status = stub_->GetGallery(&context, request, &gallery);
  scratch_exists_ = status.ok();
  scratch_count_ = status.ok() ? gallery.sample_count() : 0;
  if (!status.ok() && status.error_code() != grpc::StatusCode::NOT_FOUND) {
    return FromGrpcStatus(status);
  }
  if (!scratch_exists_) pending_.push_back(kCreateGallery);
  return absl::OkStatus();
}

absl::Status SoakClient::CreateGallery(const std::string& name, uint32_t k) {
  grpc::ClientContext context;
  SetDeadline(context);
  v1::CreateGalleryRequest request;
  request.set_name(name);
  request.mutable_knn()->set_k(k);
  v1::Gallery gallery;
  const grpc::Status status = stub_->CreateGallery(&context, request, &gallery);
  if (!status.ok()) return FromGrpcStatus(status);
  if (name == scratch_) {
    scratch_exists_ = true;
    scratch_count_ = 0;
    train_scratch_next_ = true;
    pending_.push_back(kTrain);
  } else {
    spec_ = gallery.descriptor_spec();
    dimension_ = gallery.dimension();
  }
  return Check(gallery.name() == name && gallery.sample_count() == 0 && gallery.knn().k() == k &&
                   gallery.dimension() > 0,
               absl::StrCat("CreateGallery answer for ", name));
}

absl::Status SoakClient::CheckGallery(const v1::Gallery& gallery) const {
  std::map<std::string, uint64_t> counts;
  for (const Held& h : held_) ++counts[h.label];
  bool counts_ok = gallery.label_counts_size() == static_cast<int>(counts.size());
  for (const v1::LabelCount& c : gallery.label_counts()) {
    counts_ok = counts_ok && counts[c.label()] == c.count();
  }
  return Check(
      gallery.name() == name_ && gallery.sample_count() == held_.size() &&
          gallery.vector_count() == held_.size() && gallery.dimension() == dimension_ && counts_ok,
      absl::StrCat("gallery ", gallery.name(), ": ", gallery.sample_count(), " samples (expected ",
                   held_.size(), "), label counts ", counts_ok ? "right" : "wrong"));
}

absl::Status SoakClient::GetGallery() {
  grpc::ClientContext context;
  SetDeadline(context);
  v1::GetGalleryRequest request;
  request.set_name(name_);
  v1::Gallery gallery;
  const grpc::Status status = stub_->GetGallery(&context, request, &gallery);
  if (!status.ok()) return FromGrpcStatus(status);
  return CheckGallery(gallery);
}

absl::Status SoakClient::ListGalleries() {
  grpc::ClientContext context;
  SetDeadline(context);
  v1::ListGalleriesResponse response;
  const grpc::Status status = stub_->ListGalleries(&context, v1::ListGalleriesRequest(), &response);
  if (!status.ok()) return FromGrpcStatus(status);
  bool sorted = true;
  const v1::Gallery* own = nullptr;
  for (int i = 0; i < response.galleries_size(); ++i) {
    if (i > 0) sorted = sorted && response.galleries(i - 1).name() < response.galleries(i).name();
    if (response.galleries(i).name() == name_) own = &response.galleries(i);
  }
  if (!sorted || own == nullptr) {
    return Check(false, absl::StrCat("ListGalleries: ", response.galleries_size(),
                                     " galleries, sorted: ", sorted ? "yes" : "no", ", ", name_,
                                     own ? " listed" : " missing"));
  }
  return CheckGallery(*own);
}

absl::Status SoakClient::ReadExport(std::vector<v1::GalleryExportChunk>* chunks) {
  grpc::ClientContext context;
  SetDeadline(context);
  v1::ExportGalleryRequest request;
  request.set_name(name_);
  auto reader = stub_->ExportGallery(&context, request);
  v1::GalleryExportChunk chunk;
  while (reader->Read(&chunk)) chunks->push_back(chunk);
  return FromGrpcStatus(reader->Finish());
}

// The whole gallery: header, samples in training order, trailer; kept for ImportScratch.
absl::Status SoakClient::Export() {
  std::vector<v1::GalleryExportChunk> chunks;
  if (absl::Status s = ReadExport(&chunks); !s.ok()) return s;
  std::vector<uint64_t> ids;
  for (const v1::GalleryExportChunk& chunk : chunks) {
    if (chunk.has_samples()) {
      ids.insert(ids.end(), chunk.samples().sample_ids().begin(),
                 chunk.samples().sample_ids().end());
    }
  }
  bool ids_ok = ids.size() == held_.size();
  for (size_t i = 0; ids_ok && i < ids.size(); ++i) ids_ok = ids[i] == held_[i].id;
  const bool framed = chunks.size() >= 2 && chunks.front().has_header() &&
                      chunks.back().has_trailer() &&
                      chunks.front().header().sample_count() == held_.size() &&
                      chunks.back().trailer().sample_count() == held_.size();
  if (framed && ids_ok) last_export_ = std::move(chunks);
  return Check(framed && ids_ok,
               absl::StrCat("ExportGallery: ", ids.size(), " samples (expected ", held_.size(),
                            "), in order: ", ids_ok ? "yes" : "no"));
}

// Deletes the scratch gallery; a CreateGallery (then a Train) or, when there is an export
// to import, every other time an ImportGallery recreates it.
absl::Status SoakClient::DeleteScratch() {
  if (!scratch_exists_) {
    pending_.push_back(kCreateGallery);
    return absl::OkStatus();
  }
  grpc::ClientContext context;
  SetDeadline(context);
  v1::DeleteGalleryRequest request;
  request.set_name(scratch_);
  v1::DeleteGalleryResponse response;
  const grpc::Status status = stub_->DeleteGallery(&context, request, &response);
  if (!status.ok()) return FromGrpcStatus(status);
  scratch_exists_ = false;
  const bool import = !last_export_.empty() && ++recreations_ % 2 == 0;
  pending_.push_back(import ? kImportGallery : kCreateGallery);
  return Check(response.samples_deleted() == scratch_count_,
               absl::StrCat("DeleteGallery: ", response.samples_deleted(),
                            " samples deleted, expected ", scratch_count_));
}

absl::Status SoakClient::ImportScratch() {
  grpc::ClientContext context;
  SetDeadline(context);
  v1::Gallery gallery;
  auto writer = stub_->ImportGallery(&context, &gallery);
  bool open = true;
  for (size_t i = 0; open && i < last_export_.size(); ++i) {
    v1::ImportGalleryRequest request;
    if (i == 0) request.set_name(scratch_);
    *request.mutable_chunk() = last_export_[i];
    open = writer->Write(request);
  }
  writer->WritesDone();
  const grpc::Status status = writer->Finish();
  if (!status.ok()) return FromGrpcStatus(status);
  const uint64_t expected = last_export_.front().header().sample_count();
  scratch_exists_ = true;
  scratch_count_ = gallery.sample_count();
  return Check(gallery.name() == scratch_ && gallery.sample_count() == expected,
               absl::StrCat("ImportGallery: ", gallery.name(), " with ", gallery.sample_count(),
                            " samples, expected ", scratch_, " with ", expected));
}

}  // namespace shapeid::soak
