// End-to-end scale-out (issue 11): three real shapeid-server replicas over one PostgreSQL
// (Debian's, started privately on loopback), driven by the client library balancing
// round_robin over all three. Train through one replica and classify through the others;
// kill a replica under load; restart it; restart PostgreSQL under load.

#include <atomic>
#include <chrono>
#include <functional>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/time/clock.h"
#include "client/client.h"
#include "core/point_cloud.h"
#include "core/testing/test_clouds.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "server/storage/testing/postgres_instance.h"
#include "tests/server_process.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;
using testing_clouds::ShapeCloud;
constexpr auto& kShapes = testing_clouds::kShapeNames;

// The bound the replicas are started with (--store_refresh_ms): how late a replica may see
// another's change, and how long it may go on answering without PostgreSQL.
constexpr int kRefreshMs = 200;

// Waits until `done()` holds: the replicas' bound, then up to 5 s more, since a loaded 2-core
// CI machine can delay any process by more than the bound. Returns how long it took.
absl::Duration WaitFor(const std::function<bool()>& done) {
  const absl::Time start = absl::Now();
  absl::SleepFor(absl::Milliseconds(kRefreshMs));
  while (!done() && absl::Now() - start < absl::Seconds(5) + absl::Milliseconds(kRefreshMs)) {
    absl::SleepFor(absl::Milliseconds(10));
  }
  return absl::Now() - start;
}

class ScaleOutE2ETest : public ::testing::Test {
 protected:
  void SetUp() override {
    absl::StatusOr<std::unique_ptr<PostgresInstance>> pg = PostgresInstance::Start();
    if (!pg.ok()) {
      if (PostgresInstance::Required()) FAIL() << pg.status();
      GTEST_SKIP() << "no PostgreSQL to test against: " << pg.status();
    }
    pg_ = *std::move(pg);
    for (int i = 0; i < 3; ++i) replicas_.push_back(StartReplica());
  }

  std::unique_ptr<ServerProcess> StartReplica() {
    auto replica = std::make_unique<ServerProcess>(std::vector<std::string>{
        "--store=" + pg_->conninfo(), absl::StrCat("--store_refresh_ms=", kRefreshMs)});
    EXPECT_FALSE(replica->address().empty()) << "replica did not start; stderr:\n"
                                             << replica->StderrText();
    return replica;
  }

  // A client of one replica, or (balanced) of every replica: round_robin over the list.
  std::unique_ptr<Client> ConnectTo(const std::vector<const ServerProcess*>& replicas) {
    std::vector<std::string> addresses;
    for (const ServerProcess* r : replicas) addresses.push_back(r->address());
    ClientOptions options;
    options.target = absl::StrJoin(addresses, ",");
    options.deadline = absl::Seconds(20);
    options.max_attempts = 4;
    options.initial_backoff = absl::Milliseconds(50);
    // One replica: pick_first, so that calls reach it even when it is out of service (and its
    // own refusal can be read); round_robin would leave it out.
    if (replicas.size() == 1) options.load_balancing = "pick_first";
    auto client = Client::Connect(options);
    EXPECT_TRUE(client.ok()) << client.status();
    return client.ok() ? *std::move(client) : nullptr;
  }
  std::unique_ptr<Client> ConnectTo(const ServerProcess& replica) { return ConnectTo({&replica}); }
  std::unique_ptr<Client> ConnectToAll() {
    std::vector<const ServerProcess*> all;
    for (const auto& r : replicas_) all.push_back(r.get());
    return ConnectTo(all);
  }

  // Waits (WaitFor) until every running replica holds `samples` samples in `gallery`.
  void AwaitEveryReplicaHolds(const std::string& gallery, uint64_t samples) {
    for (const auto& r : replicas_) {
      auto client = ConnectTo(*r);
      WaitFor([&] {
        auto g = client->GetGallery(gallery);
        return g.ok() && g->sample_count() == samples;
      });
      auto g = client->GetGallery(gallery);
      ASSERT_TRUE(g.ok()) << g.status();
      ASSERT_EQ(g->sample_count(), samples);
    }
  }

  std::unique_ptr<PostgresInstance> pg_;
  std::vector<std::unique_ptr<ServerProcess>> replicas_;
};

// A Train the client retried after its first attempt went unanswered (a replica killed) may
// have committed all the same; the client then says so in an ALREADY_EXISTS.
bool CommittedAfterRetry(const absl::Status& status) {
  return absl::IsAlreadyExists(status) && absl::StrContains(status.message(), "may have committed");
}

// Trains `count` clouds of shape `kind` with client-chosen ids from `first_id` (so that a
// retried stream cannot add a sample twice).
absl::Status Train(Client& client, const std::string& gallery, int kind, uint32_t seed, int count,
                   uint64_t first_id) {
  std::vector<PointCloud> clouds;
  for (int i = 0; i < count; ++i) clouds.push_back(ShapeCloud(kind, seed + i, 300));
  std::vector<TrainSample> samples;
  for (int i = 0; i < count; ++i) {
    samples.push_back({kShapes[kind], first_id + static_cast<uint64_t>(i), &clouds[i]});
  }
  return client.Train(gallery, samples).status();
}

void CreateTrainedGallery(Client& client, const std::string& name) {
  v1::CreateGalleryRequest create;
  create.set_name(name);
  create.mutable_knn()->set_k(3);
  ASSERT_TRUE(client.CreateGallery(create).ok());
  for (int kind = 0; kind < 3; ++kind) {
    ASSERT_TRUE(Train(client, name, kind, 100 + 10 * kind, 4, 1 + 100 * kind).ok());
  }
}

// Labels and neighbor ids of a fixed set of queries.
std::vector<std::string> Answers(Client& client, const std::string& gallery) {
  std::vector<std::string> answers;
  for (uint32_t q = 0; q < 6; ++q) {
    auto answer = client.Classify(gallery, ShapeCloud(static_cast<int>(q % 3), 900 + q, 400));
    if (!answer.ok()) {
      answers.push_back(answer.status().ToString());
      continue;
    }
    std::string line = answer->label();
    for (const auto& n : answer->neighbors()) absl::StrAppend(&line, " ", n.sample_id());
    answers.push_back(line);
  }
  return answers;
}

TEST_F(ScaleOutE2ETest, TrainThroughOneClassifyThroughTheOthersAfterTheBound) {
  auto first = ConnectTo(*replicas_[0]);
  CreateTrainedGallery(*first, "lab");
  const std::vector<std::string> expected = Answers(*first, "lab");
  const uint64_t version = first->GetGallery("lab")->version();
  // The stated bound, then every replica answers as the one trained through.
  for (int r = 1; r < 3; ++r) {
    SCOPED_TRACE(absl::StrCat("replica ", r, "; stderr:\n", replicas_[r]->StderrText()));
    auto other = ConnectTo(*replicas_[r]);
    const absl::Duration took = WaitFor([&] {
      auto g = other->GetGallery("lab");
      return g.ok() && g->version() == version;
    });
    // Not asserted: a loaded CI machine may stall any process past the bound. Printed, and
    // bench/scale_out_bench measures the delay (docs/scaling.md).
    std::printf("replica %d held the change %s after the write (bound %d ms)\n", r,
                absl::FormatDuration(took).c_str(), kRefreshMs);
    auto gallery = other->GetGallery("lab");
    ASSERT_TRUE(gallery.ok()) << gallery.status();
    EXPECT_EQ(gallery->sample_count(), 12u);
    EXPECT_EQ(gallery->version(), version);
    EXPECT_EQ(Answers(*other, "lab"), expected);
  }
  // Writes through any replica: a removal through replica 2, seen by replica 1.
  auto third = ConnectTo(*replicas_[2]);
  ASSERT_TRUE(third->RemoveSamples("lab", {1, 2}, {}).ok());
  auto second = ConnectTo(*replicas_[1]);
  WaitFor([&] {
    auto g = second->GetGallery("lab");
    return g.ok() && g->sample_count() == 10u;
  });
  EXPECT_EQ(second->GetGallery("lab")->sample_count(), 10u);
  // A name taken through one replica is taken for all.
  v1::CreateGalleryRequest again;
  again.set_name("lab");
  EXPECT_EQ(third->CreateGallery(again).status().code(), absl::StatusCode::kAlreadyExists);
}

TEST_F(ScaleOutE2ETest, KillingAReplicaUnderLoadFailsNoRequestAndARestartCatchesUp) {
  auto setup = ConnectTo(*replicas_[0]);
  CreateTrainedGallery(*setup, "lab");
  AwaitEveryReplicaHolds("lab", 12);

  std::atomic<bool> stop{false};
  std::atomic<int> classified{0}, failed{0}, trained_batches{0};
  std::vector<std::string> failures;
  std::mutex failures_mu;
  const auto record = [&](const absl::Status& status) {
    ++failed;
    std::lock_guard<std::mutex> lock(failures_mu);
    failures.push_back(status.ToString());
  };
  std::vector<std::thread> load;
  for (int t = 0; t < 3; ++t) {
    load.emplace_back([&, t] {
      auto client = ConnectToAll();
      for (uint32_t i = 0; !stop; ++i) {
        auto answer = client->Classify("lab", ShapeCloud(static_cast<int>(i % 3), 500 + t, 300));
        answer.ok() ? ++classified : (record(answer.status()), 0);
      }
    });
  }
  // Training under load too: client ids, so the client may retry a stream on another replica.
  load.emplace_back([&] {
    auto client = ConnectToAll();
    for (int batch = 0; !stop; ++batch) {
      const absl::Status s = Train(*client, "lab", batch % 3, 700 + batch, 2, 10'000 + 2 * batch);
      (s.ok() || CommittedAfterRetry(s)) ? ++trained_batches : (record(s), 0);
    }
  });
  absl::SleepFor(absl::Seconds(1));
  replicas_[1]->Kill();  // SIGKILL: whatever it had in flight is cut
  const int before_kill = classified.load();
  absl::SleepFor(absl::Seconds(2));
  stop = true;
  for (auto& t : load) t.join();

  EXPECT_EQ(failed.load(), 0) << absl::StrJoin(failures, "\n");
  EXPECT_GT(classified.load(), before_kill) << "no load after the kill";
  EXPECT_GT(trained_batches.load(), 0);

  // Restarted, it loads everything, including what was trained while it was down.
  replicas_[1] = StartReplica();
  auto restarted = ConnectTo(*replicas_[1]);
  auto survivor = ConnectTo(*replicas_[0]);
  auto expected_or = survivor->GetGallery("lab");
  ASSERT_TRUE(expected_or.ok()) << expected_or.status();
  const v1::Gallery expected = *expected_or;
  EXPECT_EQ(expected.sample_count(), 12u + 2u * static_cast<uint64_t>(trained_batches.load()));
  WaitFor([&] {
    auto g = restarted->GetGallery("lab");
    return g.ok() && g->version() == expected.version();
  });
  auto caught_up_or = restarted->GetGallery("lab");
  ASSERT_TRUE(caught_up_or.ok()) << caught_up_or.status();
  const v1::Gallery caught_up = *caught_up_or;
  EXPECT_EQ(caught_up.sample_count(), expected.sample_count());
  EXPECT_EQ(caught_up.version(), expected.version());
  EXPECT_EQ(Answers(*restarted, "lab"), Answers(*survivor, "lab"));
}

TEST_F(ScaleOutE2ETest, PostgresRestartUnderLoadTakesReplicasOutOfServiceThenBack) {
  auto setup = ConnectTo(*replicas_[0]);
  CreateTrainedGallery(*setup, "lab");
  AwaitEveryReplicaHolds("lab", 12);

  std::atomic<bool> stop{false};
  std::atomic<int> answered{0};
  std::thread load([&] {
    auto client = ConnectToAll();
    for (uint32_t i = 0; !stop; ++i) {
      if (client->Classify("lab", ShapeCloud(static_cast<int>(i % 3), 40 + i, 300)).ok()) {
        ++answered;
      }
    }
  });
  std::vector<std::unique_ptr<Client>> direct;
  for (const auto& r : replicas_) {
    direct.push_back(ConnectTo(*r));
    ASSERT_TRUE(direct.back()->CheckHealth().ok());
  }
  absl::SleepFor(absl::Milliseconds(500));

  ASSERT_TRUE(pg_->Stop().ok());
  const absl::Time stopped = absl::Now();
  // Every replica stops serving: health NOT_SERVING and calls UNAVAILABLE, rather than going
  // on answering from a copy nobody can keep current. Stated bound: kRefreshMs after the last
  // contact, plus one poll slice; 5 s leaves a loaded machine room.
  absl::Duration all_out = absl::InfiniteDuration();
  while (absl::Now() - stopped < absl::Seconds(5)) {
    bool any_serving = false;
    for (auto& c : direct) any_serving |= c->CheckHealth().ok();
    if (!any_serving) {
      all_out = absl::Now() - stopped;
      break;
    }
    absl::SleepFor(absl::Milliseconds(10));
  }
  ASSERT_LT(all_out, absl::Seconds(5)) << "a replica kept serving without PostgreSQL";
  std::printf("all 3 replicas NOT_SERVING %s after PostgreSQL stopped (bound %d ms)\n",
              absl::FormatDuration(all_out).c_str(), kRefreshMs);
  for (auto& c : direct) {
    const absl::Status refused = c->Classify("lab", ShapeCloud(0, 1, 300)).status();
    EXPECT_EQ(refused.code(), absl::StatusCode::kUnavailable);
    EXPECT_THAT(refused.message(), HasSubstr("lost its gallery store"));
  }

  ASSERT_TRUE(pg_->StartServer().ok());
  const absl::Time started = absl::Now();
  bool all_back = false;
  while (!all_back && absl::Now() - started < absl::Seconds(20)) {
    all_back = true;
    for (auto& c : direct) all_back &= c->CheckHealth().ok();
    absl::SleepFor(absl::Milliseconds(20));
  }
  ASSERT_TRUE(all_back) << "replicas did not come back after PostgreSQL restarted";
  stop = true;
  load.join();
  EXPECT_GT(answered.load(), 0);

  // Writes work again and reach every replica.
  ASSERT_TRUE(Train(*direct[0], "lab", 1, 4000, 2, 50'000).ok());
  for (auto& c : direct) {
    WaitFor([&] {
      auto g = c->GetGallery("lab");
      return g.ok() && g->sample_count() == 14u;
    });
    auto g = c->GetGallery("lab");
    ASSERT_TRUE(g.ok()) << g.status();
    EXPECT_EQ(g->sample_count(), 14u);
  }
}

}  // namespace
}  // namespace shapeid
