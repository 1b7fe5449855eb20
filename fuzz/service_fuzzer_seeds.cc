// Writes service_fuzzer's seed corpus: one ServiceSession per file, each a realistic client
// conversation (the happy path of every RPC, and the mistakes clients make), so that
// libFuzzer starts from inputs that reach deep into the service rather than from bytes that
// fail the first check. Usage: service_fuzzer_seeds OUTPUT_DIR.

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "core/point_cloud.h"
#include "core/testing/test_clouds.h"
#include "fuzz/fuzz_service.h"

namespace shapeid::fuzz {
namespace {

std::string Xyz(const PointCloud& cloud, size_t first = 0, size_t count = SIZE_MAX) {
  count = std::min(count, cloud.size() - first);
  std::string bytes(count * 12, '\0');
  std::memcpy(bytes.data(), cloud.data() + 3 * first, bytes.size());
  return bytes;
}

PointCloud Shape(int kind, uint32_t seed, size_t n = 64) {
  return testing_clouds::ShapeCloud(kind, seed, n);
}

template <typename Stream>
void AddChunks(Stream* stream, const PointCloud& cloud, size_t per_chunk) {
  for (size_t i = 0; i < cloud.size(); i += per_chunk) {
    stream->add_messages()->mutable_points()->set_xyz(Xyz(cloud, i, per_chunk));
  }
}

Call DescribeCall(const std::string& spec, const PointCloud& cloud, uint64_t expected = 0) {
  Call call;
  auto* header = call.mutable_describe()->add_messages()->mutable_header();
  header->set_descriptor_spec(spec);
  header->set_expected_points(expected);
  AddChunks(call.mutable_describe(), cloud, 40);
  return call;
}

Call TrainCall(const std::string& gallery,
               const std::vector<std::pair<std::string, PointCloud>>& samples) {
  Call call;
  call.mutable_train()->add_messages()->mutable_header()->set_gallery(gallery);
  for (const auto& [label, cloud] : samples) {
    auto* sample = call.mutable_train()->add_messages()->mutable_sample();
    sample->set_label(label);
    sample->set_expected_points(cloud.size());
    AddChunks(call.mutable_train(), cloud, 32);
  }
  return call;
}

Call ClassifyCall(const std::string& gallery, uint32_t k, const PointCloud& cloud) {
  Call call;
  auto* header = call.mutable_classify()->add_messages()->mutable_header();
  header->set_gallery(gallery);
  header->set_k(k);
  AddChunks(call.mutable_classify(), cloud, 50);
  return call;
}

Call CreateCall(const std::string& name, const std::string& spec) {
  Call call;
  call.mutable_create_gallery()->set_name(name);
  call.mutable_create_gallery()->set_descriptor_spec(spec);
  return call;
}

// The chunks of an export of a fresh server's "base" gallery.
std::vector<v1::GalleryExportChunk> ExportOfBase() {
  FuzzServer server;
  grpc::ClientContext context;
  v1::ExportGalleryRequest request;
  request.set_name("base");
  auto reader = server.stub().ExportGallery(&context, request);
  std::vector<v1::GalleryExportChunk> chunks;
  v1::GalleryExportChunk chunk;
  while (reader->Read(&chunk)) chunks.push_back(chunk);
  const grpc::Status status = reader->Finish();
  if (!status.ok()) {
    std::fprintf(stderr, "export failed: %s\n", status.error_message().c_str());
    std::exit(1);
  }
  return chunks;
}

std::vector<std::pair<std::string, ServiceSession>> Seeds() {
  std::vector<std::pair<std::string, ServiceSession>> seeds;
  auto add = [&](std::string name, std::vector<Call> calls) {
    ServiceSession session;
    for (Call& c : calls) *session.add_calls() = std::move(c);
    seeds.emplace_back(std::move(name), std::move(session));
  };

  add("describe_default", {DescribeCall("", Shape(0, 1), 64)});
  add("describe_specs",
      {DescribeCall("rphsd:bins=20", Shape(1, 2)), DescribeCall("comsd:grid=8", Shape(2, 3)),
       DescribeCall("cnsd", Shape(0, 4))});
  add("train_then_classify", {TrainCall("base", {{"box", Shape(0, 11)}, {"rod", Shape(2, 12)}}),
                              ClassifyCall("base", 3, Shape(0, 13))});
  {
    Call describe;
    describe.mutable_describe_cloud()->mutable_header()->set_descriptor_spec("dfsd");
    describe.mutable_describe_cloud()->mutable_points()->set_xyz(Xyz(Shape(1, 21)));
    Call classify;
    classify.mutable_classify_cloud()->mutable_header()->set_gallery("base");
    classify.mutable_classify_cloud()->mutable_header()->set_k(2);
    classify.mutable_classify_cloud()->mutable_points()->set_xyz(Xyz(Shape(2, 22)));
    add("one_message_calls", {describe, classify});
  }
  {
    Call get, list, remove, remove_label, del, descriptors;
    get.mutable_get_gallery()->set_name("g2");
    list.mutable_list_galleries();
    remove.mutable_remove_samples()->set_gallery("g2");
    remove.mutable_remove_samples()->add_sample_ids(1);
    remove_label.mutable_remove_samples()->set_gallery("base");
    remove_label.mutable_remove_samples()->add_labels("rod");
    del.mutable_delete_gallery()->set_name("g2");
    descriptors.mutable_list_descriptors();
    Call create = CreateCall("g2", "rphsd:refs=cubic27,bins=30");
    create.mutable_create_gallery()->mutable_knn()->set_k(3);
    create.mutable_create_gallery()->set_reject_distance(0.5);
    add("gallery_lifecycle",
        {create, TrainCall("g2", {{"a", Shape(0, 31)}, {"b", Shape(1, 32)}}), get, list, remove,
         remove_label, ClassifyCall("g2", 1, Shape(1, 33)), del, descriptors});
  }
  {
    Call create = CreateCall("views", "dfsd");
    auto* augmentation = create.mutable_create_gallery()->mutable_augmentation();
    augmentation->set_views(2);
    augmentation->set_seed(5);
    add("augmented_gallery", {create, TrainCall("views", {{"a", Shape(0, 41, 200)}}),
                              ClassifyCall("views", 1, Shape(0, 42, 200))});
  }
  {
    Call export_call;
    export_call.mutable_export_gallery()->set_name("base");
    Call import_call;
    bool first = true;
    for (const v1::GalleryExportChunk& chunk : ExportOfBase()) {
      auto* message = import_call.mutable_import_gallery()->add_messages();
      if (first) message->set_name("copy");
      first = false;
      *message->mutable_chunk() = chunk;
    }
    add("export_import", {export_call, import_call, ClassifyCall("copy", 1, Shape(2, 51))});
    Call cut = import_call;
    cut.set_cancel_after(2);
    add("import_cancelled", {cut});
  }
  {
    Call cancelled = TrainCall("base", {{"box", Shape(0, 61)}, {"sphere", Shape(1, 62)}});
    cancelled.set_cancel_after(3);
    add("train_cancelled", {cancelled, ClassifyCall("base", 1, Shape(1, 63))});
  }
  {
    // A table (1,681 points) with two shapes on it, within the fuzz server's 4,096 points:
    // one message with the defaults, then a stream with up, a region, indices and a NaN.
    PointCloud frame;
    for (int x = -20; x <= 20; ++x) {
      for (int y = -20; y <= 20; ++y) frame.Add(0.025f * x, 0.025f * y, 0);
    }
    for (int kind = 0; kind < 2; ++kind) {
      const PointCloud shape = Shape(kind, 81 + kind, 300);
      for (size_t i = 0; i < shape.size(); ++i) {
        frame.Add(0.05f * shape.point(i) + Eigen::Vector3f(kind == 0 ? -0.2f : 0.2f, 0, 0.06f));
      }
    }
    Call one;
    one.mutable_recognize_scene_cloud()->mutable_header()->set_gallery("base");
    one.mutable_recognize_scene_cloud()
        ->mutable_header()
        ->mutable_segmentation()
        ->set_min_cluster_points(50);
    one.mutable_recognize_scene_cloud()->mutable_points()->set_xyz(Xyz(frame));
    frame.data()[7] = std::numeric_limits<float>::quiet_NaN();
    Call stream;
    auto* header = stream.mutable_recognize_scene()->add_messages()->mutable_header();
    header->set_gallery("base");
    header->set_return_indices(true);
    header->mutable_sensor_frame()->add_up(0);
    header->mutable_sensor_frame()->add_up(0);
    header->mutable_sensor_frame()->add_up(1);
    header->mutable_segmentation()->set_min_cluster_points(50);
    header->mutable_segmentation()->set_max_planes(2);
    header->mutable_region()->mutable_min()->set_x(-0.4);
    header->mutable_region()->mutable_min()->set_y(-0.4);
    header->mutable_region()->mutable_min()->set_z(-0.1);
    header->mutable_region()->mutable_max()->set_x(0.4);
    header->mutable_region()->mutable_max()->set_y(0.4);
    header->mutable_region()->mutable_max()->set_z(0.5);
    AddChunks(stream.mutable_recognize_scene(), frame, 500);
    add("scenes", {one, stream});
  }
  {
    // Mistakes: points before the header, fewer points than announced, a NaN.
    Call early;
    early.mutable_classify()->add_messages()->mutable_points()->set_xyz(Xyz(Shape(0, 71)));
    Call short_cloud = DescribeCall("", Shape(0, 72), 100);
    PointCloud nan_cloud = Shape(1, 73);
    nan_cloud.data()[5] = std::numeric_limits<float>::quiet_NaN();
    add("mistakes", {early, short_cloud, TrainCall("base", {{"x", nan_cloud}})});
  }
  return seeds;
}

}  // namespace
}  // namespace shapeid::fuzz

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s OUTPUT_DIR\n", argv[0]);
    return 2;
  }
  const std::filesystem::path dir(argv[1]);
  std::filesystem::create_directories(dir);
  for (const auto& [name, session] : shapeid::fuzz::Seeds()) {
    std::ofstream out(dir / name, std::ios::binary | std::ios::trunc);
    out << session.SerializeAsString();
    if (!out) {
      std::fprintf(stderr, "cannot write %s\n", (dir / name).c_str());
      return 1;
    }
  }
  return 0;
}
