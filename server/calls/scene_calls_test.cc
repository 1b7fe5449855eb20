// RecognizeScene and RecognizeSceneCloud through a real gRPC server on a loopback port: the
// objects of a table frame with their labels, geometry and indices; one message and the stream
// answering alike; organized frames with missing returns; the sensor frame's up; and every
// error the proto names for scenes (empty frame, all plane, over the point limit, bad
// parameters, empty or unknown gallery).

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "Eigen/Geometry"
#include "core/testing/test_clouds.h"
#include "gmock/gmock.h"
#include "grpcpp/grpcpp.h"
#include "gtest/gtest.h"
#include "server/server.h"
#include "shapeid/v1/shapeid.grpc.pb.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;
using testing_clouds::kShapeNames;
using testing_clouds::kTableHeight;
using testing_clouds::ShapeCloud;
using testing_clouds::TableWithShapes;

constexpr uint32_t kMaxPoints = 60000;

std::string Bytes(const PointCloud& cloud) {
  std::string bytes(cloud.size() * 12, '\0');
  std::memcpy(bytes.data(), cloud.data(), bytes.size());
  return bytes;
}

class SceneCallsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ServerOptions options;
    options.listen = "127.0.0.1:0";
    options.gallery_limits.max_points_per_cloud = kMaxPoints;
    auto server = ShapeIdServer::Start(options);
    ASSERT_TRUE(server.ok()) << server.status();
    server_ = std::move(server).value();
    stub_ = v1::ShapeId::NewStub(
        grpc::CreateChannel(server_->address(), grpc::InsecureChannelCredentials()));
  }

  // A gallery of the three shapes, 3 samples each (rphsd: fast, and reads the frame's axes).
  void CreateShapes(const std::string& name, bool train = true) {
    grpc::ClientContext create_context;
    v1::CreateGalleryRequest create;
    create.set_name(name);
    create.set_descriptor_spec("rphsd");
    create.mutable_knn()->set_k(1);
    v1::Gallery gallery;
    ASSERT_TRUE(stub_->CreateGallery(&create_context, create, &gallery).ok());
    if (!train) return;
    grpc::ClientContext context;
    v1::TrainResponse response;
    auto writer = stub_->Train(&context, &response);
    v1::TrainRequest header;
    header.mutable_header()->set_gallery(name);
    writer->Write(header);
    for (int kind = 0; kind < 3; ++kind) {
      for (uint32_t seed = 1; seed <= 3; ++seed) {
        v1::TrainRequest sample;
        sample.mutable_sample()->set_label(kShapeNames[kind]);
        writer->Write(sample);
        v1::TrainRequest points;
        points.mutable_points()->set_xyz(Bytes(ShapeCloud(kind, seed, 2000)));
        writer->Write(points);
      }
    }
    writer->WritesDone();
    const grpc::Status status = writer->Finish();
    ASSERT_TRUE(status.ok()) << status.error_message();
  }

  grpc::Status SceneCloud(const v1::SceneHeader& header, const std::string& xyz,
                          v1::RecognizeSceneResponse* response) {
    grpc::ClientContext context;
    v1::RecognizeSceneCloudRequest request;
    *request.mutable_header() = header;
    request.mutable_points()->set_xyz(xyz);
    return stub_->RecognizeSceneCloud(&context, request, response);
  }

  // The stream, `chunk` bytes per PointChunk.
  grpc::Status SceneStream(const v1::SceneHeader& header, const std::string& xyz, size_t chunk,
                           v1::RecognizeSceneResponse* response) {
    grpc::ClientContext context;
    auto writer = stub_->RecognizeScene(&context, response);
    v1::RecognizeSceneRequest first;
    *first.mutable_header() = header;
    bool open = writer->Write(first);
    for (size_t at = 0; open && at < xyz.size(); at += chunk) {
      v1::RecognizeSceneRequest points;
      points.mutable_points()->set_xyz(xyz.substr(at, chunk));
      open = writer->Write(points);
    }
    writer->WritesDone();
    return writer->Finish();
  }

  static v1::SceneHeader Header(const std::string& gallery, bool indices = true) {
    v1::SceneHeader header;
    header.set_gallery(gallery);
    header.set_return_indices(indices);
    return header;
  }

  std::unique_ptr<ShapeIdServer> server_;
  std::unique_ptr<v1::ShapeId::Stub> stub_;
};

std::vector<uint32_t> Indices(const v1::SceneObject& object) {
  return {object.indices().begin(), object.indices().end()};
}

TEST_F(SceneCallsTest, FindsNamesAndLocatesEachObjectAndAccountsForEveryPoint) {
  CreateShapes("shapes");
  std::vector<std::vector<uint32_t>> truth;
  const PointCloud frame = TableWithShapes(&truth);
  v1::RecognizeSceneResponse answer;
  const grpc::Status status = SceneCloud(Header("shapes"), Bytes(frame), &answer);
  ASSERT_TRUE(status.ok()) << status.error_message();
  ASSERT_EQ(answer.objects_size(), 3);
  ASSERT_EQ(answer.planes_size(), 1);
  EXPECT_NEAR(answer.planes(0).coefficients(2), 1.0, 1e-4);  // towards the origin: up
  EXPECT_NEAR(answer.planes(0).coefficients(3), 0.5, 1e-4);
  uint64_t accounted = answer.planes(0).num_points() + answer.non_finite_points() +
                       answer.outside_region() + answer.in_small_clusters() +
                       answer.in_large_clusters();
  std::map<std::string, int> labels;
  for (const v1::SceneObject& object : answer.objects()) {
    accounted += object.classification().num_points();
    EXPECT_EQ(object.classification().num_points(), static_cast<uint64_t>(object.indices_size()));
    EXPECT_TRUE(object.error().empty());
    ++labels[object.classification().label()];
    // Which truth object these are; its label, centroid and box.
    const std::vector<uint32_t> indices = Indices(object);
    const auto kind = std::find(truth.begin(), truth.end(), indices);
    ASSERT_NE(kind, truth.end());
    const int k = static_cast<int>(kind - truth.begin());
    EXPECT_EQ(object.classification().label(), kShapeNames[k]);
    ASSERT_EQ(object.classification().neighbors_size(), 1);
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (const uint32_t i : indices) mean += frame.point(i).cast<double>();
    mean /= static_cast<double>(indices.size());
    EXPECT_NEAR(object.centroid().x(), mean.x(), 1e-4);
    EXPECT_NEAR(object.centroid().y(), mean.y(), 1e-4);
    EXPECT_NEAR(object.centroid().z(), mean.z(), 1e-4);
    const v1::Quaternion& q = object.box().orientation();
    EXPECT_NEAR(q.x() * q.x() + q.y() * q.y() + q.z() * q.z() + q.w() * q.w(), 1.0, 1e-5);
    if (k == 0) {  // the box, 20 x 15 x 1 cm: its full extents, longest first
      EXPECT_NEAR(object.box().size().x(), 0.20, 0.01);
      EXPECT_NEAR(object.box().size().y(), 0.15, 0.01);
      EXPECT_NEAR(object.box().size().z(), 0.01, 0.005);
    }
  }
  EXPECT_EQ(labels.size(), 3u);
  EXPECT_EQ(accounted, frame.size());
  EXPECT_EQ(answer.num_points(), frame.size());
  EXPECT_GT(answer.segment_time().nanos() + answer.segment_time().seconds(), 0);

  v1::RecognizeSceneResponse without;
  ASSERT_TRUE(SceneCloud(Header("shapes", false), Bytes(frame), &without).ok());
  ASSERT_EQ(without.objects_size(), 3);
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(without.objects(i).indices_size(), 0);
    EXPECT_EQ(without.objects(i).classification().label(),
              answer.objects(i).classification().label());
  }
}

TEST_F(SceneCallsTest, TheStreamAnswersAsOneMessageDoesWhateverTheChunks) {
  CreateShapes("shapes");
  std::vector<std::vector<uint32_t>> truth;
  const std::string xyz = Bytes(TableWithShapes(&truth));
  v1::RecognizeSceneResponse one;
  ASSERT_TRUE(SceneCloud(Header("shapes"), xyz, &one).ok());
  for (const size_t chunk : {size_t{12} * 1000, size_t{12} * 16384}) {
    v1::RecognizeSceneResponse streamed;
    const grpc::Status status = SceneStream(Header("shapes"), xyz, chunk, &streamed);
    ASSERT_TRUE(status.ok()) << status.error_message();
    ASSERT_EQ(streamed.objects_size(), one.objects_size());
    for (int i = 0; i < one.objects_size(); ++i) {
      EXPECT_EQ(Indices(streamed.objects(i)), Indices(one.objects(i)));
      EXPECT_EQ(streamed.objects(i).classification().label(),
                one.objects(i).classification().label());
      EXPECT_EQ(streamed.objects(i).classification().neighbors(0).distance(),
                one.objects(i).classification().neighbors(0).distance());
    }
    EXPECT_EQ(streamed.planes(0).coefficients(3), one.planes(0).coefficients(3));
  }
}

// An organized frame in a PointCloud2 layout (16-byte points with intensity, padded rows),
// its missing returns NaN: they are skipped and counted, and indices stay pixel numbers even
// when the layout asks to drop them.
TEST_F(SceneCallsTest, OrganisedFramesKeepPixelIndicesThroughMissingReturns) {
  CreateShapes("shapes");
  std::vector<std::vector<uint32_t>> truth;
  const PointCloud dense = TableWithShapes(&truth);
  const uint32_t width = 200;
  const size_t rows = (2 * dense.size() + width - 1) / width;
  const uint32_t point_step = 16, row_step = width * point_step + 8;
  std::string bytes(rows * row_step, '\0');
  const float nan = std::numeric_limits<float>::quiet_NaN();
  // Pixels alternate: the frame's points on even pixels, NaN on odd ones, so point i is pixel
  // 2 i.
  size_t missing = 0;
  for (size_t pixel = 0; pixel < rows * width; ++pixel) {
    float p[4] = {nan, nan, nan, 7.0f};
    if (pixel % 2 == 0 && pixel / 2 < dense.size()) {
      std::memcpy(p, dense.data() + 3 * (pixel / 2), 12);
    } else {
      ++missing;
    }
    std::memcpy(&bytes[(pixel / width) * row_step + (pixel % width) * point_step], p, 16);
  }
  v1::SceneHeader header = Header("shapes");
  v1::PointLayout* layout = header.mutable_layout();
  layout->set_point_step(point_step);
  layout->mutable_x()->set_datatype(v1::FLOAT32);
  layout->mutable_y()->set_offset(4);
  layout->mutable_y()->set_datatype(v1::FLOAT32);
  layout->mutable_z()->set_offset(8);
  layout->mutable_z()->set_datatype(v1::FLOAT32);
  layout->set_width(width);
  layout->set_row_step(row_step);
  layout->set_drop_nonfinite(true);  // ignored by scenes
  v1::RecognizeSceneResponse answer;
  const grpc::Status status = SceneStream(header, bytes, 10007, &answer);
  ASSERT_TRUE(status.ok()) << status.error_message();
  EXPECT_EQ(answer.num_points(), rows * width);
  EXPECT_EQ(answer.non_finite_points(), missing);
  ASSERT_EQ(answer.objects_size(), 3);
  for (const v1::SceneObject& object : answer.objects()) {
    std::vector<uint32_t> points;
    for (const uint32_t pixel : object.indices()) {
      ASSERT_EQ(pixel % 2, 0u);
      points.push_back(pixel / 2);
    }
    EXPECT_NE(std::find(truth.begin(), truth.end(), points), truth.end());
  }
}

// A sensor frame: the floor is the support even beside a larger wall, its normal points up,
// and the objects are described turned into the gallery's frame.
TEST_F(SceneCallsTest, TheSensorFramesUpKeepsWallsFromBeingSupports) {
  CreateShapes("shapes");
  std::vector<std::vector<uint32_t>> truth;
  PointCloud frame = TableWithShapes(&truth);
  size_t table_points = frame.size();
  for (const auto& object : truth) table_points -= object.size();
  for (float x = -1.2f; x <= 1.2f; x += 0.01f) {  // a wall at y = 0.75, larger than the table
    for (float z = -0.4f; z <= 0.4f; z += 0.01f) frame.Add(x, 0.75f, z);
  }
  v1::SceneHeader header = Header("shapes");
  for (const double u : {0.0, 0.0, 2.0}) header.mutable_sensor_frame()->add_up(u);
  v1::RecognizeSceneResponse answer;
  const grpc::Status status = SceneCloud(header, Bytes(frame), &answer);
  ASSERT_TRUE(status.ok()) << status.error_message();
  ASSERT_EQ(answer.planes_size(), 1);
  EXPECT_EQ(answer.planes(0).num_points(), table_points);
  EXPECT_NEAR(answer.planes(0).coefficients(2), 1.0, 1e-4);

  v1::RecognizeSceneResponse any_plane;
  ASSERT_TRUE(SceneCloud(Header("shapes"), Bytes(frame), &any_plane).ok());
  ASSERT_EQ(any_plane.planes_size(), 1);
  EXPECT_NEAR(std::fabs(any_plane.planes(0).coefficients(1)), 1.0, 1e-4);  // the wall
}

TEST_F(SceneCallsTest, EmptyAndAllPlaneFramesAnswerNoObjects) {
  CreateShapes("shapes");
  v1::RecognizeSceneResponse empty;
  ASSERT_TRUE(SceneCloud(Header("shapes"), "", &empty).ok());
  EXPECT_EQ(empty.objects_size(), 0);
  EXPECT_EQ(empty.planes_size(), 0);
  EXPECT_EQ(empty.num_points(), 0u);
  PointCloud floor;
  for (float x = -0.5f; x <= 0.5f; x += 0.01f) {
    for (float y = -0.5f; y <= 0.5f; y += 0.01f) floor.Add(x, y, -1.0f);
  }
  v1::RecognizeSceneResponse plane;
  ASSERT_TRUE(SceneStream(Header("shapes"), Bytes(floor), 12 * 4096, &plane).ok());
  EXPECT_EQ(plane.objects_size(), 0);
  ASSERT_EQ(plane.planes_size(), 1);
  EXPECT_EQ(plane.planes(0).num_points(), floor.size());
  // All NaN: every point counted as skipped, nothing else.
  const std::vector<float> nans(3 * 1000, std::numeric_limits<float>::quiet_NaN());
  v1::RecognizeSceneResponse missing;
  ASSERT_TRUE(SceneCloud(Header("shapes"),
                         std::string(reinterpret_cast<const char*>(nans.data()), nans.size() * 4),
                         &missing)
                  .ok());
  EXPECT_EQ(missing.non_finite_points(), 1000u);
  EXPECT_EQ(missing.objects_size(), 0);
}

TEST_F(SceneCallsTest, ErrorsAreNamedWithTheirCodes) {
  CreateShapes("shapes");
  CreateShapes("untrained", /*train=*/false);
  std::vector<std::vector<uint32_t>> truth;
  const std::string xyz = Bytes(TableWithShapes(&truth));
  v1::RecognizeSceneResponse answer;

  grpc::Status s = SceneCloud(Header("untrained"), xyz, &answer);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  EXPECT_THAT(s.error_message(), HasSubstr("no samples"));
  s = SceneStream(Header("untrained"), xyz, 12 * 4096, &answer);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  EXPECT_EQ(SceneCloud(Header("missing"), xyz, &answer).error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_EQ(SceneCloud(Header(""), xyz, &answer).error_code(), grpc::StatusCode::INVALID_ARGUMENT);

  // Parameters out of range name the field, before any point is read.
  v1::SceneHeader bad = Header("shapes");
  bad.mutable_segmentation()->set_cluster_tolerance(0);  // set: not the default
  s = SceneStream(bad, xyz, 12 * 4096, &answer);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(s.error_message(), HasSubstr("cluster_tolerance"));
  bad = Header("shapes");
  bad.mutable_segmentation()->set_max_planes(17);
  s = SceneCloud(bad, xyz, &answer);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(s.error_message(), HasSubstr("max_planes"));
  bad = Header("shapes");
  bad.mutable_region()->mutable_min()->set_x(1);
  s = SceneCloud(bad, xyz, &answer);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(s.error_message(), HasSubstr("region"));
  bad = Header("shapes");
  bad.mutable_sensor_frame()->add_up(0);
  bad.mutable_sensor_frame()->add_up(0);
  bad.mutable_sensor_frame()->add_up(0);
  EXPECT_EQ(SceneCloud(bad, xyz, &answer).error_code(), grpc::StatusCode::INVALID_ARGUMENT);

  // A frame over the point limit, in one message or streamed.
  const std::string over((kMaxPoints + 1) * 12, '\0');
  s = SceneCloud(Header("shapes"), over, &answer);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_THAT(s.error_message(), HasSubstr(std::to_string(kMaxPoints)));
  s = SceneStream(Header("shapes"), over, 12 * 16384, &answer);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);

  // A stream's order.
  grpc::ClientContext context;
  auto writer = stub_->RecognizeScene(&context, &answer);
  v1::RecognizeSceneRequest points;
  points.mutable_points()->set_xyz(xyz.substr(0, 120));
  writer->Write(points);
  writer->WritesDone();
  s = writer->Finish();
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(s.error_message(), HasSubstr("SceneHeader"));
}

// An object the descriptor cannot describe (all its points at one place) is answered unknown
// with its reason; the others are answered as usual.
TEST_F(SceneCallsTest, AnObjectThatCannotBeDescribedCarriesItsError) {
  CreateShapes("shapes");
  std::vector<std::vector<uint32_t>> truth;
  PointCloud frame = TableWithShapes(&truth);
  for (int i = 0; i < 200; ++i) frame.Add(-0.4f, 0.4f, kTableHeight + 0.2f);
  v1::RecognizeSceneResponse answer;
  ASSERT_TRUE(SceneCloud(Header("shapes"), Bytes(frame), &answer).ok());
  ASSERT_EQ(answer.objects_size(), 4);
  int failed = 0;
  for (const v1::SceneObject& object : answer.objects()) {
    if (object.error().empty()) continue;
    ++failed;
    EXPECT_EQ(object.classification().label(), "unknown");
    EXPECT_TRUE(object.classification().unknown());
    EXPECT_EQ(object.classification().neighbors_size(), 0);
    EXPECT_EQ(object.indices_size(), 200);
  }
  EXPECT_EQ(failed, 1);
}

}  // namespace
}  // namespace shapeid
