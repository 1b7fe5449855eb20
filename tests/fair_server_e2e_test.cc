// A shared server that one client cannot freeze (issue 25), through a real shapeid-server
// process: one caller ("abuser") sends heavy Describe streams while another ("lab") classifies
// small clouds and a probe checks health on both ports. The lab's calls and the probes all
// succeed while the heavy lane is busy; the lab's own heavy work is served before the abuser's
// backlog; the abuser's work whose deadline passes in the queue is dropped unstarted; and a
// stream past a caller's share of the memory budget is refused, naming the flag. The full-size
// reproduction with latency figures is bench/fair_server_bench (docs/reliability.md).

#include <atomic>
#include <memory>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "client/client.h"
#include "core/point_cloud.h"
#include "core/testing/test_clouds.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "nlohmann/json.hpp"
#include "server/security/api_keys.h"
#include "tests/server_process.h"

namespace shapeid {
namespace {

using ::testing::AnyOf;
using ::testing::HasSubstr;

// Sanitizers slow describing several times over: smaller clouds keep the heavy lane as busy.
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
constexpr size_t kHugePoints = 500'000;
#else
constexpr size_t kHugePoints = 1'500'000;
#endif
constexpr char kAbuserKey[] = "abuser-key-0123456789abcdefghijklmnopqrstuv";
constexpr char kLabKey[] = "lab-key-0123456789abcdefghijklmnopqrstuvwxyz";

std::vector<std::string> ServerFlags(int memory_budget_mib) {
  return {absl::StrCat("--api_keys=abuser write ", Sha256Hex(kAbuserKey), ";lab write ",
                       Sha256Hex(kLabKey)),
          "--health_listen=127.0.0.1:0",
          "--log_format=json",
          "--log_level=info",
          "--workers=2",
          "--heavy_workers=1",
          absl::StrCat("--memory_budget_mib=", memory_budget_mib)};
}

std::unique_ptr<Client> Connect(const std::string& target, const std::string& key,
                                absl::Duration deadline, const std::string& request_id = "") {
  ClientOptions options;
  options.target = target;
  options.api_key = key;
  options.deadline = deadline;
  options.max_attempts = 1;
  options.request_id = request_id;
  absl::StatusOr<std::unique_ptr<Client>> client = Client::Connect(options);
  EXPECT_TRUE(client.ok()) << client.status();
  return client.ok() ? *std::move(client) : nullptr;
}

std::vector<nlohmann::json> LogLines(const ServerProcess& server) {
  std::vector<nlohmann::json> lines;
  std::istringstream text(server.StderrText());
  for (std::string line; std::getline(text, line);) {
    lines.push_back(nlohmann::json::parse(line));
  }
  return lines;
}

std::string HealthAddress(const ServerProcess& server) {
  for (const nlohmann::json& line : LogLines(server)) {
    const std::string message = line.value("msg", "");
    const std::string prefix = "health checks also on ";
    if (absl::StartsWith(message, prefix)) {
      const std::string rest = message.substr(prefix.size());
      return rest.substr(0, rest.find(' '));
    }
  }
  return "";
}

v1::WorkLaneStats Heavy(const v1::ServerStats& stats) {
  for (const v1::WorkLaneStats& lane : stats.work()) {
    if (lane.lane() == "heavy") return lane;
  }
  return {};
}

TEST(FairServerE2ETest, HeavyCallsOfOneCallerNeitherFreezeNorStarveTheOthers) {
  ServerProcess server(ServerFlags(1024));
  ASSERT_FALSE(server.address().empty()) << server.StderrText();
  const std::string health_address = HealthAddress(server);
  ASSERT_FALSE(health_address.empty()) << server.StderrText();

  std::unique_ptr<Client> lab = Connect(server.address(), kLabKey, absl::Seconds(30));
  std::unique_ptr<Client> main_probe = Connect(server.address(), "", absl::Seconds(3));
  std::unique_ptr<Client> health_probe = Connect(health_address, "", absl::Seconds(3));
  ASSERT_TRUE(lab && main_probe && health_probe);
  v1::CreateGalleryRequest create;
  create.set_name("lab");
  ASSERT_TRUE(lab->CreateGallery(create).ok());
  std::vector<PointCloud> clouds;
  std::vector<TrainSample> samples;
  for (uint32_t i = 0; i < 8; ++i) clouds.push_back(testing_clouds::ShapeCloud(i % 2, i, 1024));
  for (uint32_t i = 0; i < 8; ++i) samples.push_back({i % 2 ? "box" : "ball", 0, &clouds[i]});
  ASSERT_TRUE(lab->Train("lab", samples).ok());

  // Two heavy describes from one caller: one runs on the heavy lane's single worker, one waits.
  const PointCloud huge = testing_clouds::UniformCloud(kHugePoints, 1);
  std::atomic<int> abuser_done{0};
  std::vector<absl::Status> abuser_status(2);
  absl::Time second_finished;
  std::vector<std::thread> abusers;
  for (int i = 0; i < 2; ++i) {
    abusers.emplace_back([&, i] {
      std::unique_ptr<Client> abuser = Connect(server.address(), kAbuserKey, absl::Seconds(120));
      abuser_status[i] = abuser->Describe(huge).status();
      if (abuser_done.fetch_add(1) == 1) second_finished = absl::Now();
    });
  }
  // Until the heavy lane is busy with one and holds the other.
  const absl::Time give_up = absl::Now() + absl::Seconds(60);
  while (absl::Now() < give_up) {
    absl::StatusOr<v1::ServerStats> stats = lab->GetServerStats();
    ASSERT_TRUE(stats.ok()) << stats.status();
    if (Heavy(*stats).running() == 1 && Heavy(*stats).queued() == 1) break;
    absl::SleepFor(absl::Milliseconds(5));
  }
  ASSERT_EQ(abuser_done.load(), 0) << "the heavy work ended before the test could watch it";

  // Now: the lab's own heavy describe, which must not wait for the abuser's queued one, and
  // an abuser describe whose deadline passes while it waits.
  absl::Time lab_heavy_finished;
  absl::Status lab_heavy;
  std::thread lab_heavy_thread([&] {
    std::unique_ptr<Client> heavy = Connect(server.address(), kLabKey, absl::Seconds(120));
    lab_heavy = heavy->Describe(testing_clouds::UniformCloud(200'000, 2)).status();
    lab_heavy_finished = absl::Now();
  });
  absl::Status dropped;
  std::thread dropped_thread([&] {
    std::unique_ptr<Client> late =
        Connect(server.address(), kAbuserKey, absl::Milliseconds(300), "dropped-1");
    dropped = late->Describe(testing_clouds::UniformCloud(200'000, 3)).status();
  });

  // The lab classifies and the probes check health while the abuser's work runs.
  int classified = 0, probes = 0;
  std::vector<std::string> failures;
  const PointCloud query = testing_clouds::ShapeCloud(1, 99, 1024);
  while (abuser_done.load() < 2 && absl::Now() < give_up) {
    absl::StatusOr<v1::ClassifyResponse> answer = lab->Classify("lab", query);
    if (answer.ok()) {
      ++classified;
    } else {
      failures.push_back(absl::StrCat("classify: ", answer.status().ToString()));
    }
    for (Client* probe : {main_probe.get(), health_probe.get()}) {
      if (const absl::Status health = probe->CheckHealth(); health.ok()) {
        ++probes;
      } else {
        failures.push_back(absl::StrCat("health: ", health.ToString()));
      }
    }
  }
  for (std::thread& thread : abusers) thread.join();
  lab_heavy_thread.join();
  dropped_thread.join();

  EXPECT_THAT(failures, ::testing::IsEmpty());
  EXPECT_GE(classified, 5) << "the lab's calls did not get through while the heavy work ran";
  EXPECT_GE(probes, 10);
  EXPECT_TRUE(abuser_status[0].ok()) << abuser_status[0];
  EXPECT_TRUE(abuser_status[1].ok()) << abuser_status[1];
  EXPECT_TRUE(lab_heavy.ok()) << lab_heavy;
  EXPECT_LT(lab_heavy_finished, second_finished)
      << "the lab's heavy work waited behind the abuser's backlog";
  EXPECT_EQ(dropped.code(), absl::StatusCode::kDeadlineExceeded) << dropped;

  // The log: the dropped call never ran its work; the lab's classifies report their wait.
  bool saw_dropped = false, saw_wait = false;
  for (const nlohmann::json& line : LogLines(server)) {
    if (line.value("request_id", "") == "dropped-1") {
      saw_dropped = true;
      EXPECT_THAT(line.value("code", ""), AnyOf("DEADLINE_EXCEEDED", "CANCELLED")) << line;
      EXPECT_EQ(line.value("describe_us", -1), 0) << line;
    }
    if (line.value("method", "") == "ClassifyCloud" && line.contains("wait_us")) saw_wait = true;
  }
  EXPECT_TRUE(saw_dropped) << server.StderrText();
  EXPECT_TRUE(saw_wait);

  // The memory the streams held shows in the stats, and all of it came back.
  absl::StatusOr<v1::ServerStats> stats = lab->GetServerStats();
  ASSERT_TRUE(stats.ok());
  EXPECT_EQ(stats->memory_budget_bytes(), uint64_t{1024} << 20);
  EXPECT_GE(stats->memory_held_peak_bytes(), 2 * huge.size() * 12);
  EXPECT_EQ(Heavy(*stats).queued(), 0u);
  const absl::Time until = absl::Now() + absl::Seconds(10);
  while (stats->memory_held_bytes() > 0 && absl::Now() < until) {
    absl::SleepFor(absl::Milliseconds(10));
    stats = lab->GetServerStats();
    ASSERT_TRUE(stats.ok());
  }
  EXPECT_EQ(stats->memory_held_bytes(), 0u);
}

TEST(FairServerE2ETest, AStreamPastTheCallersShareOfMemoryIsRefusedNamingTheFlag) {
  ServerProcess server(ServerFlags(64));  // 32 MiB a caller
  ASSERT_FALSE(server.address().empty()) << server.StderrText();
  std::unique_ptr<Client> abuser = Connect(server.address(), kAbuserKey, absl::Seconds(60));
  ASSERT_TRUE(abuser);
  const absl::StatusOr<v1::DescribeResponse> big =
      abuser->Describe(testing_clouds::UniformCloud(3'000'000, 4));  // 36 MB in transit
  ASSERT_EQ(big.status().code(), absl::StatusCode::kResourceExhausted) << big.status();
  EXPECT_THAT(big.status().message(), HasSubstr("--memory_budget_mib"));
  // The memory came back: a cloud within the share is described.
  const absl::StatusOr<v1::DescribeResponse> small =
      abuser->Describe(testing_clouds::UniformCloud(100'000, 5));
  EXPECT_TRUE(small.ok()) << small.status();
  // The server is alive and well.
  EXPECT_TRUE(abuser->CheckHealth().ok());
}

}  // namespace
}  // namespace shapeid
