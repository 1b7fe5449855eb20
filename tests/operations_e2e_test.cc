// Operations (issue 12) through a real shapeid-server process: the Prometheus endpoint scraped
// before and after real calls (counters and histograms move by what the calls did), the JSON
// log lines (each parses, one per call, carrying the client's request id, never points or
// keys), the request id echoed to the client, GetServerStats, a live log-level change, and the
// Grafana dashboard's metrics all present in a real scrape.

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "client/client.h"
#include "core/point_cloud.h"
#include "core/testing/test_clouds.h"
#include "gmock/gmock.h"
#include "grpcpp/grpcpp.h"
#include "gtest/gtest.h"
#include "nlohmann/json.hpp"
#include "shapeid/v1/shapeid.grpc.pb.h"
#include "tests/server_process.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;
using testing_clouds::ShapeCloud;

constexpr char kRequestId[] = "robot-7/batch:42";

// GET http://`address`/metrics with a plain socket (HTTP/1.0: the server closes when done).
std::string HttpGet(const std::string& address, const std::string& path) {
  const size_t colon = address.rfind(':');
  sockaddr_in server{};
  server.sin_family = AF_INET;
  int port = 0;
  if (!absl::SimpleAtoi(address.substr(colon + 1), &port)) return "";
  server.sin_port = htons(static_cast<uint16_t>(port));
  if (inet_pton(AF_INET, address.substr(0, colon).c_str(), &server.sin_addr) != 1) return "";
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  if (fd < 0) return "";
  std::string response;
  if (connect(fd, reinterpret_cast<const sockaddr*>(&server), sizeof server) == 0) {
    const std::string request =
        absl::StrCat("GET ", path, " HTTP/1.0\r\nHost: ", address, "\r\n\r\n");
    if (write(fd, request.data(), request.size()) == static_cast<ssize_t>(request.size())) {
      char buffer[65536];
      ssize_t n;
      while ((n = read(fd, buffer, sizeof buffer)) > 0)
        response.append(buffer, static_cast<size_t>(n));
    }
  }
  close(fd);
  const size_t body = response.find("\r\n\r\n");
  return body == std::string::npos ? "" : response.substr(body + 4);
}

// A scrape: series (name with labels, as written) -> value.
using Scrape = std::map<std::string, double>;

Scrape Parse(const std::string& text) {
  Scrape series;
  for (absl::string_view line : absl::StrSplit(text, '\n')) {
    if (line.empty() || line[0] == '#') continue;
    const size_t space = line.rfind(' ');
    double value = 0;
    if (space == absl::string_view::npos || !absl::SimpleAtod(line.substr(space + 1), &value)) {
      continue;
    }
    series[std::string(line.substr(0, space))] = value;
  }
  return series;
}

double Get(const Scrape& scrape, const std::string& series) {
  const auto it = scrape.find(series);
  return it == scrape.end() ? 0 : it->second;
}

// Metric names (the part before '{') of a scrape.
std::set<std::string> Names(const Scrape& scrape) {
  std::set<std::string> names;
  for (const auto& [series, value] : scrape) names.insert(series.substr(0, series.find('{')));
  return names;
}

class OperationsE2ETest : public ::testing::Test {
 protected:
  void SetUp() override {
    server_ = std::make_unique<ServerProcess>(std::vector<std::string>{
        "--metrics_listen=127.0.0.1:0", "--log_format=json", "--log_level=info"});
    ASSERT_FALSE(server_->address().empty()) << server_->StderrText();
    for (const nlohmann::json& line : LogLines()) {
      if (line.contains("metrics_address")) metrics_ = line["metrics_address"];
    }
    ASSERT_FALSE(metrics_.empty()) << "no metrics address in the log:\n" << server_->StderrText();
    ClientOptions options;
    options.target = server_->address();
    options.deadline = absl::Seconds(30);
    options.request_id = kRequestId;
    auto client = Client::Connect(options);
    ASSERT_TRUE(client.ok()) << client.status();
    client_ = *std::move(client);
  }

  // Every line the server wrote to stderr, each parsed (a line that does not parse fails).
  std::vector<nlohmann::json> LogLines() const {
    std::vector<nlohmann::json> lines;
    std::istringstream text(server_->StderrText());
    std::string line;
    while (std::getline(text, line)) {
      if (line.empty()) continue;
      const nlohmann::json parsed =
          nlohmann::json::parse(line, nullptr, /*allow_exceptions=*/false);
      EXPECT_FALSE(parsed.is_discarded()) << "not JSON: " << line;
      if (!parsed.is_discarded()) lines.push_back(parsed);
    }
    return lines;
  }

  // The lines of calls of `method`.
  std::vector<nlohmann::json> RpcLines(const std::string& method) const {
    std::vector<nlohmann::json> rpcs;
    for (const nlohmann::json& line : LogLines()) {
      if (line.value("msg", "") == "rpc" && line.value("method", "") == method)
        rpcs.push_back(line);
    }
    return rpcs;
  }

  Scrape ScrapeNow() const { return Parse(HttpGet(metrics_, "/metrics")); }

  void TrainShelf(int samples_per_shape) {
    v1::CreateGalleryRequest create;
    create.set_name("shelf");
    ASSERT_TRUE(client_->CreateGallery(create).ok());
    std::vector<PointCloud> clouds;
    for (int kind = 0; kind < 3; ++kind) {
      for (int i = 0; i < samples_per_shape; ++i)
        clouds.push_back(ShapeCloud(kind, 10 * kind + i, 500));
    }
    std::vector<TrainSample> samples;
    for (size_t i = 0; i < clouds.size(); ++i) {
      samples.push_back({testing_clouds::kShapeNames[i / samples_per_shape], 0, &clouds[i]});
    }
    ASSERT_TRUE(client_->Train("shelf", samples).ok());
  }

  std::unique_ptr<ServerProcess> server_;
  std::string metrics_;
  std::unique_ptr<Client> client_;
};

TEST_F(OperationsE2ETest, CountersAndHistogramsMoveWithTheCalls) {
  const Scrape before = ScrapeNow();
  ASSERT_FALSE(before.empty());
  EXPECT_EQ(Get(before, "shapeid_serving"), 1);
  EXPECT_EQ(Get(before, "shapeid_galleries"), 0);

  TrainShelf(4);  // 12 samples of 500 points
  for (int q = 0; q < 5; ++q) {
    ASSERT_TRUE(client_->Classify("shelf", ShapeCloud(q % 3, 100 + q, 400)).ok());
  }
  EXPECT_EQ(client_->GetGallery("absent").status().code(), absl::StatusCode::kNotFound);
  const Scrape after = ScrapeNow();

  // One ClassifyCloud series per outcome; 5 calls, 2,000 points.
  EXPECT_EQ(
      Get(after, R"(shapeid_requests_total{code="OK",gallery="shelf",method="ClassifyCloud"})"), 5);
  EXPECT_EQ(Get(after, R"(shapeid_requests_total{code="OK",gallery="shelf",method="Train"})"), 1);
  EXPECT_EQ(
      Get(after, R"(shapeid_requests_total{code="OK",gallery="shelf",method="CreateGallery"})"), 1);
  EXPECT_EQ(
      Get(after,
          R"(shapeid_requests_total{code="NOT_FOUND",gallery="_unknown",method="GetGallery"})"),
      1);
  EXPECT_EQ(Get(after, R"(shapeid_points_received_total{method="ClassifyCloud"})"), 2000);
  EXPECT_EQ(Get(after, R"(shapeid_points_received_total{method="Train"})"), 6000);
  EXPECT_EQ(Get(after, R"(shapeid_samples_trained_total{gallery="shelf"})"), 12);
  EXPECT_EQ(Get(after, R"(shapeid_gallery_samples{gallery="shelf"})"), 12);
  EXPECT_EQ(Get(after, "shapeid_galleries"), 1);
  // Histograms: counts match the calls, sums are positive, the +Inf bucket holds every call
  // and the buckets never decrease.
  EXPECT_EQ(Get(after, R"(shapeid_request_duration_seconds_count{method="ClassifyCloud"})"), 5);
  EXPECT_GT(Get(after, R"(shapeid_request_duration_seconds_sum{method="ClassifyCloud"})"), 0);
  EXPECT_EQ(
      Get(after, R"(shapeid_request_duration_seconds_bucket{method="ClassifyCloud",le="+Inf"})"),
      5);
  std::map<double, double> buckets;  // le -> cumulative count
  const std::string bucket_prefix =
      R"(shapeid_request_duration_seconds_bucket{method="ClassifyCloud",le=")";
  for (const auto& [series, value] : after) {
    if (series.rfind(bucket_prefix, 0) != 0) continue;
    const std::string le =
        series.substr(bucket_prefix.size(), series.size() - bucket_prefix.size() - 2);
    buckets[le == "+Inf" ? std::numeric_limits<double>::infinity() : std::stod(le)] = value;
  }
  ASSERT_GT(buckets.size(), 10u);
  double previous = 0;
  for (const auto& [le, count] : buckets) {
    EXPECT_GE(count, previous) << "le=" << le;
    previous = count;
  }
  // The descriptor ran for 12 training clouds and 5 queries; the search for 5 queries.
  double described = 0;
  for (const auto& [series, value] : after) {
    if (series.rfind("shapeid_describe_duration_seconds_count{", 0) == 0) described += value;
  }
  EXPECT_EQ(described, 17);
  EXPECT_EQ(Get(after, R"(shapeid_search_duration_seconds_count{index="exact"})"), 5);
  // Durable writes: the create and the training batch.
  EXPECT_EQ(Get(after, R"(shapeid_store_write_duration_seconds_count{operation="save"})"), 1);
  EXPECT_EQ(Get(after, R"(shapeid_store_write_duration_seconds_count{operation="append"})"), 1);
  EXPECT_GT(Get(after, "process_resident_memory_bytes"), 1e6);
  EXPECT_GE(Get(after, "process_cpu_seconds_total"), Get(before, "process_cpu_seconds_total"));
}

TEST_F(OperationsE2ETest, EveryCallLogsOneJsonLineWithTheClientsRequestId) {
  TrainShelf(2);
  ASSERT_TRUE(client_->Classify("shelf", ShapeCloud(0, 500, 300)).ok());
  EXPECT_FALSE(client_->GetGallery("Not a name!").ok());
  const std::vector<nlohmann::json> classify = RpcLines("ClassifyCloud");
  ASSERT_EQ(classify.size(), 1u) << server_->StderrText();
  const nlohmann::json& line = classify[0];
  EXPECT_EQ(line["level"], "info");
  EXPECT_EQ(line["gallery"], "shelf");
  EXPECT_EQ(line["code"], "OK");
  EXPECT_EQ(line["points"], 300);
  EXPECT_EQ(line["request_id"], kRequestId);
  EXPECT_GT(line["us"].get<int64_t>(), 0);
  EXPECT_GT(line["describe_us"].get<int64_t>(), 0);
  EXPECT_THAT(line["peer"].get<std::string>(), HasSubstr("127.0.0.1"));
  EXPECT_FALSE(line.contains("error"));
  const std::vector<nlohmann::json> train = RpcLines("Train");
  ASSERT_EQ(train.size(), 1u);
  EXPECT_EQ(train[0]["samples"], 6);
  EXPECT_EQ(train[0]["points"], 3000);
  // A failed call is a warning with its error; a bad name is quoted safely.
  const std::vector<nlohmann::json> get = RpcLines("GetGallery");
  ASSERT_EQ(get.size(), 1u);
  EXPECT_EQ(get[0]["level"], "warning");
  EXPECT_EQ(get[0]["code"], "INVALID_ARGUMENT");
  EXPECT_EQ(get[0]["gallery"], "Not a name!");
  EXPECT_THAT(get[0]["error"].get<std::string>(), HasSubstr("does not match"));
  EXPECT_EQ(get[0]["request_id"], kRequestId);
  // No point data: the log holds no float of the clouds sent, and stays small.
  EXPECT_LT(server_->StderrText().size(), 8000u);
}

TEST_F(OperationsE2ETest, TheRequestIdIsEchoedAndMadeUpWhenAbsentOrInvalid) {
  auto channel = grpc::CreateChannel(server_->address(), grpc::InsecureChannelCredentials());
  auto stub = v1::ShapeId::NewStub(channel);
  const auto call = [&](const char* sent) {
    grpc::ClientContext context;
    if (sent != nullptr) context.AddMetadata("x-request-id", sent);
    v1::ListGalleriesResponse response;
    EXPECT_TRUE(stub->ListGalleries(&context, {}, &response).ok());
    const auto& metadata = context.GetServerInitialMetadata();
    const auto it = metadata.find("x-request-id");
    return it == metadata.end() ? std::string() : std::string(it->second.data(), it->second.size());
  };
  EXPECT_EQ(call("abc-123"), "abc-123");
  const std::string made_up = call(nullptr);
  EXPECT_THAT(made_up, testing::MatchesRegex("[0-9a-f]{16}"));
  const std::string replaced = call("has spaces");
  const std::string too_long = call(std::string(129, 'a').c_str());
  EXPECT_THAT(too_long, testing::MatchesRegex("[0-9a-f]{16}"));
  EXPECT_THAT(replaced, testing::MatchesRegex("[0-9a-f]{16}"));
  // And the log says the same ids.
  std::set<std::string> logged;
  for (const nlohmann::json& line : RpcLines("ListGalleries")) logged.insert(line["request_id"]);
  EXPECT_EQ(logged, (std::set<std::string>{"abc-123", made_up, replaced, too_long}));
  EXPECT_THAT(server_->StderrText(), Not(HasSubstr("has spaces")));
}

TEST_F(OperationsE2ETest, StatsSummariseAndTheLogLevelChangesLive) {
  TrainShelf(3);
  for (int q = 0; q < 4; ++q)
    ASSERT_TRUE(client_->Classify("shelf", ShapeCloud(q % 3, 70 + q, 300)).ok());
  const absl::StatusOr<v1::ServerStats> stats = client_->GetServerStats();
  ASSERT_TRUE(stats.ok()) << stats.status();
  EXPECT_EQ(stats->state(), "serving");
  EXPECT_EQ(stats->samples(), 9u);
  ASSERT_EQ(stats->galleries_size(), 1);
  EXPECT_EQ(stats->galleries(0).name(), "shelf");
  EXPECT_EQ(stats->galleries(0).samples(), 9u);
  EXPECT_EQ(stats->metrics_address(), metrics_);
  EXPECT_EQ(stats->log_level(), "info");
  EXPECT_GT(stats->resident_memory_bytes(), 1000000u);
  EXPECT_EQ(stats->points_received(), 9u * 500 + 4u * 300);
  bool saw_classify = false;
  for (const v1::MethodStats& method : stats->methods()) {
    if (method.method() != "ClassifyCloud") continue;
    saw_classify = true;
    EXPECT_EQ(method.calls(), 4u);
    EXPECT_EQ(method.errors(), 0u);
    EXPECT_TRUE(method.has_latency_p50());
    EXPECT_GE(method.latency_p99().seconds() * 1e9 + method.latency_p99().nanos(),
              method.latency_p50().seconds() * 1e9 + method.latency_p50().nanos());
  }
  EXPECT_TRUE(saw_classify);

  // Warning: successful calls stop being logged, failures still are; the change itself is
  // logged as a warning.
  const absl::StatusOr<v1::SetLogLevelResponse> set = client_->SetLogLevel("warning");
  ASSERT_TRUE(set.ok()) << set.status();
  EXPECT_EQ(set->previous_level(), "info");
  EXPECT_EQ(set->level(), "warning");
  const size_t classified = RpcLines("ClassifyCloud").size();
  ASSERT_TRUE(client_->Classify("shelf", ShapeCloud(1, 99, 300)).ok());
  EXPECT_FALSE(client_->Classify("absent", ShapeCloud(1, 99, 300)).ok());
  const std::vector<nlohmann::json> after = RpcLines("ClassifyCloud");
  ASSERT_EQ(after.size(), classified + 1);
  EXPECT_EQ(after.back()["code"], "NOT_FOUND");
  EXPECT_EQ(client_->SetLogLevel("loud").status().code(), absl::StatusCode::kInvalidArgument);
  bool change_logged = false;
  for (const nlohmann::json& line : LogLines()) {
    if (line.value("msg", "") == "log level changed") {
      change_logged =
          line["from"] == "info" && line["to"] == "warning" && line["request_id"] == kRequestId;
    }
  }
  EXPECT_TRUE(change_logged);
}

// deploy/grafana/shapeid-dashboard.json may only chart what a real server exports (the
// deploy check has the same list offline; this is the truth it follows). The three replication
// series exist only over PostgreSQL (server/ops/metrics_test.cc checks them).
TEST_F(OperationsE2ETest, TheDashboardChartsOnlyMetricsTheServerExports) {
  TrainShelf(1);
  ASSERT_TRUE(client_->Classify("shelf", ShapeCloud(0, 3, 300)).ok());
  EXPECT_FALSE(client_->GetGallery("absent").ok());
  std::set<std::string> exported = Names(ScrapeNow());
  for (const char* postgres_only :
       {"shapeid_store_reachable", "shapeid_replication_changes_applied_total",
        "shapeid_replication_sync_age_seconds"}) {
    exported.insert(postgres_only);
  }
  // Store failures appear once a write fails; the series name is fixed in server/ops/metrics.cc.
  exported.insert("shapeid_store_write_failures_total");
  std::ifstream file(SHAPEID_SOURCE_DIR "/deploy/grafana/shapeid-dashboard.json");
  ASSERT_TRUE(file) << "deploy/grafana/shapeid-dashboard.json";
  std::stringstream text;
  text << file.rdbuf();
  ASSERT_FALSE(nlohmann::json::parse(text.str(), nullptr, false).is_discarded());
  const std::regex metric(R"(\b((?:shapeid|process)_[a-z_]+))");
  std::set<std::string> charted;
  const std::string dashboard = text.str();
  for (auto it = std::sregex_iterator(dashboard.begin(), dashboard.end(), metric);
       it != std::sregex_iterator(); ++it) {
    charted.insert((*it)[1]);
  }
  ASSERT_GT(charted.size(), 10u);
  for (const std::string& name : charted) {
    EXPECT_TRUE(exported.count(name) > 0)
        << "the dashboard charts " << name << ", which the server does not export";
  }
}

}  // namespace
}  // namespace shapeid
