#include "bench/soak/soak_client.h"

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <set>
#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "client/client.h"

namespace shapeid::soak {
namespace {

// Streamed calls send 1,024-point clouds in chunks of 256 points.
constexpr size_t kChunkBytes = 256 * 12;

// Sends `header`, then `xyz` in chunks of kChunkBytes, on a client stream; the call's status.
template <typename Request, typename Header>
grpc::Status StreamInChunks(grpc::ClientWriter<Request>& writer, const Header& header,
                            const std::string& xyz) {
  Request request;
  *request.mutable_header() = header;
  bool open = writer.Write(request);
  for (size_t first = 0; open && first < xyz.size(); first += kChunkBytes) {
    request.Clear();
    request.mutable_points()->set_xyz(xyz.substr(first, kChunkBytes));
    open = writer.Write(request);
  }
  writer.WritesDone();
  return writer.Finish();
}

}  // namespace

absl::Status SoakClient::Check(bool ok, const std::string& what) {
  return ok ? absl::OkStatus() : absl::InternalError(absl::StrCat("check failed: ", what));
}

SoakClient::SoakClient(int index, const std::string& address, const Pool& pool,
                       ClientSettings settings)
    : pool_(pool),
      settings_(settings),
      rng_(7919u * static_cast<uint32_t>(index) + 1),
      name_(absl::StrFormat("soak-%02d", index)),
      scratch_(absl::StrCat(name_, "-scratch")),
      next_id_(1) {
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(64 << 20);
  args.SetInt(GRPC_ARG_USE_LOCAL_SUBCHANNEL_POOL, 1);  // a TCP connection of its own
  channel_ = grpc::CreateCustomChannel(address, grpc::InsecureChannelCredentials(), args);
  stub_ = v1::ShapeId::NewStub(channel_);
}

absl::Status SoakClient::SetUp() {
  channel_->WaitForConnected(std::chrono::system_clock::now() + std::chrono::seconds(10));
  if (absl::Status s = CreateGallery(name_, 3); !s.ok()) return s;
  if (absl::Status s = CreateGallery(scratch_, 1); !s.ok()) return s;
  scratch_exists_ = true;
  while (held_.size() < settings_.gallery_samples / 2) {
    if (absl::Status s = Train(false, 4); !s.ok()) return s;
  }
  return Train(true, 2);
}

Kind SoakClient::Next() {
  if (!pending_.empty()) {
    const Kind kind = pending_.front();
    pending_.pop_front();
    return kind;
  }
  // Percent of the free draws; RemoveSamples, CreateGallery, ImportGallery (and a scratch
  // Train) follow from Train and DeleteGallery.
  static constexpr std::pair<Kind, int> kWeights[] = {
      {kClassifyCloud, 29}, {kClassifyStream, 14}, {kDescribeCloud, 12}, {kDescribeStream, 6},
      {kTrain, 18},         {kGetGallery, 7},      {kListGalleries, 3},  {kExportGallery, 3},
      {kDeleteGallery, 3},  {kRecognizeScene, 5}};
  int draw = std::uniform_int_distribution<int>(0, 99)(rng_);
  for (const auto& [kind, weight] : kWeights) {
    if (draw < weight) return kind;
    draw -= weight;
  }
  return kClassifyCloud;
}

absl::Status SoakClient::Run(Kind kind) {
  switch (kind) {
    case kTrain:
      if (train_scratch_next_) {
        train_scratch_next_ = false;
        return Train(true, 2);
      }
      return Train(false, 1 + std::uniform_int_distribution<int>(0, 3)(rng_));
    case kClassifyCloud:
      return Classify(false);
    case kClassifyStream:
      return Classify(true);
    case kDescribeCloud:
      return Describe(false);
    case kDescribeStream:
      return Describe(true);
    case kCreateGallery:
      return CreateGallery(scratch_, 1);
    case kGetGallery:
      return GetGallery();
    case kListGalleries:
      return ListGalleries();
    case kRemoveSamples:
      return RemoveSamples();
    case kDeleteGallery:
      return DeleteScratch();
    case kExportGallery:
      return Export();
    case kImportGallery:
      return ImportScratch();
    case kRecognizeScene:
      return RecognizeScene();
    case kNumKinds:
      break;
  }
  return absl::InternalError("no such request kind");
}

void PrepareContext(const ClientSettings& settings, grpc::ClientContext& context) {
  context.set_deadline(absl::ToChronoTime(absl::Now() + settings.deadline));
  if (!settings.api_key.empty()) {
    context.AddMetadata("authorization", absl::StrCat("Bearer ", settings.api_key));
  }
  if (!settings.caller_id.empty()) context.AddMetadata("shapeid-caller-id", settings.caller_id);
}

size_t SoakClient::RandomCloud() {
  return std::uniform_int_distribution<size_t>(0, pool_.xyz.size() - 1)(rng_);
}

// One stream of `n` samples (client-chosen ids), each cloud in one or two chunks.
absl::Status SoakClient::Train(bool scratch, int n) {
  grpc::ClientContext context;
  SetDeadline(context);
  v1::TrainResponse response;
  auto writer = stub_->Train(&context, &response);
  v1::TrainRequest request;
  request.mutable_header()->set_gallery(scratch ? scratch_ : name_);
  bool open = writer->Write(request);
  std::vector<Held> added;
  for (int i = 0; i < n && open; ++i) {
    const size_t cloud = RandomCloud();
    const std::string& xyz = pool_.xyz[cloud];
    added.push_back({next_id_++, pool_.labels[cloud], cloud});
    request.Clear();
    request.mutable_sample()->set_label(added.back().label);
    request.mutable_sample()->set_sample_id(added.back().id);
    request.mutable_sample()->set_expected_points(xyz.size() / 12);
    open = writer->Write(request);
    const size_t half = xyz.size() / 24 * 12;  // two chunks, split on a point boundary
    for (const std::string& part : {xyz.substr(0, half), xyz.substr(half)}) {
      request.Clear();
      request.mutable_points()->set_xyz(part);
      open = open && writer->Write(request);
    }
  }
  writer->WritesDone();
  const grpc::Status status = writer->Finish();
  if (!status.ok()) return FromGrpcStatus(status);
  const uint64_t before = scratch ? scratch_count_ : held_.size();
  bool ids_ok = response.sample_ids_size() == n;
  for (int i = 0; ids_ok && i < n; ++i) ids_ok = response.sample_ids(i) == added[i].id;
  if (scratch) {
    scratch_count_ += static_cast<uint64_t>(n);
  } else {
    held_.insert(held_.end(), added.begin(), added.end());
    if (held_.size() > settings_.gallery_samples) pending_.push_back(kRemoveSamples);
  }
  return Check(ids_ok && response.gallery_sample_count() == before + static_cast<uint64_t>(n),
               absl::StrCat("Train answer: ", response.sample_ids_size(), " ids, gallery of ",
                            response.gallery_sample_count(), " samples; expected ", n, " ids, ",
                            before + n));
}

// The oldest samples, down to 3/4 of the bound; every fourth time also every sample of the
// oldest one's label (the union), as long as a quarter of the bound remains.
absl::Status SoakClient::RemoveSamples() {
  const size_t target = settings_.gallery_samples * 3 / 4;
  if (held_.size() <= target) return absl::OkStatus();
  v1::RemoveSamplesRequest request;
  request.set_gallery(name_);
  std::set<uint64_t> removed;
  for (size_t i = 0; i < held_.size() - target; ++i) {
    request.add_sample_ids(held_[i].id);
    removed.insert(held_[i].id);
  }
  if (++removals_ % 4 == 0) {
    const std::string& label = held_.front().label;
    size_t with_label = removed.size();
    for (const Held& h : held_) with_label += h.label == label && !removed.count(h.id);
    if (held_.size() - with_label >= settings_.gallery_samples / 4) {
      request.add_labels(label);
      for (const Held& h : held_) {
        if (h.label == label) removed.insert(h.id);
      }
    }
  }
  grpc::ClientContext context;
  SetDeadline(context);
  v1::RemoveSamplesResponse response;
  const grpc::Status status = stub_->RemoveSamples(&context, request, &response);
  if (!status.ok()) return FromGrpcStatus(status);
  std::deque<Held> kept;
  for (Held& h : held_) {
    if (!removed.count(h.id)) kept.push_back(std::move(h));
  }
  held_ = std::move(kept);
  return Check(
      response.removed() == removed.size() && response.remaining() == held_.size(),
      absl::StrCat("RemoveSamples answer: removed ", response.removed(), ", remaining ",
                   response.remaining(), "; expected ", removed.size(), ", ", held_.size()));
}

// Half the time the cloud of a sample held now (k = 1: it must find itself, or a copy: a
// cloud always trains under one label), half the time an unseen one (the gallery's k = 3).
// Either way the label and every neighbor must be among the samples held now.
absl::Status SoakClient::Classify(bool stream) {
  const Held* self = nullptr;
  if (std::uniform_int_distribution<int>(0, 1)(rng_) == 1 && !held_.empty()) {
    self = &held_[std::uniform_int_distribution<size_t>(0, held_.size() - 1)(rng_)];
    if (self->cloud >= pool_.xyz.size()) self = nullptr;  // unknown since a resync
  }
  const std::string& xyz =
      self != nullptr
          ? pool_.xyz[self->cloud]
          : pool_.queries[std::uniform_int_distribution<size_t>(0, pool_.queries.size() - 1)(rng_)];
  v1::ClassifyHeader header;
  header.set_gallery(name_);
  header.set_expected_points(xyz.size() / 12);
  if (self != nullptr) header.set_k(1);
  v1::ClassifyResponse response;
  grpc::ClientContext context;
  SetDeadline(context);
  grpc::Status status;
  if (stream) {
    status = StreamInChunks(*stub_->Classify(&context, &response), header, xyz);
  } else {
    v1::ClassifyCloudRequest request;
    *request.mutable_header() = header;
    request.mutable_points()->set_xyz(xyz);
    status = stub_->ClassifyCloud(&context, request, &response);
  }
  if (!status.ok()) return FromGrpcStatus(status);
  std::map<uint64_t, const std::string*> held_labels;
  for (const Held& h : held_) held_labels[h.id] = &h.label;
  const size_t k = self != nullptr ? 1 : 3;
  bool neighbors_ok = response.neighbors_size() == static_cast<int>(std::min(k, held_.size()));
  for (const v1::Neighbor& n : response.neighbors()) {
    auto it = held_labels.find(n.sample_id());
    neighbors_ok = neighbors_ok && it != held_labels.end() && *it->second == n.label();
  }
  const bool label_ok =
      self != nullptr ? response.label() == self->label
                      : std::any_of(held_.begin(), held_.end(),
                                    [&](const Held& h) { return h.label == response.label(); });
  const bool ok = neighbors_ok && label_ok && !response.unknown() && response.confidence() > 0 &&
                  response.confidence() <= 1 && response.num_points() == xyz.size() / 12;
  return Check(
      ok,
      absl::StrCat(stream ? "Classify" : "ClassifyCloud", " answer: label '", response.label(), "'",
                   self != nullptr ? absl::StrCat(" for a held '", self->label, "' cloud")
                                   : " for an unseen cloud",
                   ", ", response.neighbors_size(),
                   " neighbors (all held: ", neighbors_ok ? "yes" : "no", ", nearest at ",
                   response.neighbors_size() > 0 ? response.neighbors(0).distance() : -1.0,
                   "), confidence ", response.confidence()));
}

// The descriptor of a pool cloud, by the gallery's spec; the same cloud must always give
// the same values.
absl::Status SoakClient::Describe(bool stream) {
  const size_t cloud = RandomCloud();
  const std::string& xyz = pool_.xyz[cloud];
  v1::DescribeHeader header;
  header.set_gallery(name_);
  header.set_expected_points(xyz.size() / 12);
  v1::DescribeResponse response;
  grpc::ClientContext context;
  SetDeadline(context);
  grpc::Status status;
  if (stream) {
    status = StreamInChunks(*stub_->Describe(&context, &response), header, xyz);
  } else {
    v1::DescribeCloudRequest request;
    *request.mutable_header() = header;
    request.mutable_points()->set_xyz(xyz);
    status = stub_->DescribeCloud(&context, request, &response);
  }
  if (!status.ok()) return FromGrpcStatus(status);
  std::vector<float> values(response.values().begin(), response.values().end());
  auto [seen, first_time] = descriptors_.emplace(cloud, values);
  return Check(response.descriptor_spec() == spec_ && values.size() == dimension_ &&
                   response.num_points() == xyz.size() / 12 &&
                   (first_time || seen->second == values),
               absl::StrCat("Describe answer: spec '", response.descriptor_spec(), "', ",
                            values.size(), " values, ", response.num_points(), " points",
                            first_time || seen->second == values
                                ? ""
                                : "; values differ from the same cloud's earlier ones"));
}

// A tabletop frame: a 1.2 m square of table, 2 cm apart, and two of the pool's clouds, each
// scaled to 30 cm and set on it 60 cm apart. The table is removed, both objects found, and
// every label is one the gallery holds (or unknown).
absl::Status SoakClient::RecognizeScene() {
  std::vector<float> frame;
  for (int i = 0; i < 60; ++i) {
    for (int j = 0; j < 60; ++j) {
      frame.insert(frame.end(), {-0.6f + 0.02f * i, -0.6f + 0.02f * j, 0.0f});
    }
  }
  for (const float x : {-0.3f, 0.3f}) {
    const std::string& xyz = pool_.xyz[RandomCloud()];
    std::vector<float> object(xyz.size() / 4);
    std::memcpy(object.data(), xyz.data(), object.size() * 4);
    float low[3] = {1e30f, 1e30f, 1e30f}, high[3] = {-1e30f, -1e30f, -1e30f};
    for (size_t i = 0; i < object.size(); ++i) {
      low[i % 3] = std::min(low[i % 3], object[i]);
      high[i % 3] = std::max(high[i % 3], object[i]);
    }
    const float scale =
        0.3f / std::max({high[0] - low[0], high[1] - low[1], high[2] - low[2], 1e-6f});
    for (size_t i = 0; i < object.size(); i += 3) {
      frame.insert(frame.end(), {x + (object[i] - (low[0] + high[0]) / 2) * scale,
                                 (object[i + 1] - (low[1] + high[1]) / 2) * scale,
                                 0.02f + (object[i + 2] - low[2]) * scale});
    }
  }
  v1::RecognizeSceneCloudRequest request;
  request.mutable_header()->set_gallery(name_);
  request.mutable_header()->set_expected_points(frame.size() / 3);
  request.mutable_header()->mutable_segmentation()->set_cluster_tolerance(0.06f);
  request.mutable_header()->mutable_segmentation()->set_min_cluster_points(100);
  request.mutable_points()->set_xyz(frame.data(), frame.size() * 4);
  grpc::ClientContext context;
  SetDeadline(context);
  v1::RecognizeSceneResponse response;
  const grpc::Status status = stub_->RecognizeSceneCloud(&context, request, &response);
  if (!status.ok()) return FromGrpcStatus(status);
  bool labels_ok = true;
  for (const v1::SceneObject& object : response.objects()) {
    const std::string& label = object.classification().label();
    labels_ok = labels_ok && (label == "unknown" ||
                              std::any_of(held_.begin(), held_.end(),
                                          [&](const Held& h) { return h.label == label; }));
  }
  return Check(response.planes_size() == 1 && response.objects_size() >= 2 && labels_ok,
               absl::StrCat("RecognizeScene answer: ", response.planes_size(), " planes, ",
                            response.objects_size(), " objects (expected 1 and at least 2), ",
                            labels_ok ? "labels held" : "a label the gallery does not hold"));
}

}  // namespace shapeid::soak
