// Scale-out (issue 11): shapeid-server replicas sharing their galleries in one PostgreSQL.
// Starts a private PostgreSQL (server/storage/testing/postgres_instance.h) and the largest
// --replicas count of real shapeid-server child processes over it, then measures
//  1. Classify throughput and latency from --clients closed-loop threads, each with its own
//     shapeid::Client balancing round_robin over the first N replicas, for each N (median of
//     --runs runs), with every process's CPU so that the machine's core ceiling shows;
//  2. replication delay: a Train acknowledged by replica 0 until replica 1 shows the sample;
//  3. Train throughput through the N balanced replicas, then whether every replica holds
//     exactly the acknowledged samples (PASS / FAIL).
// Prints markdown tables to paste into docs, with the command line and the machine.
//
//   scale_out_bench                                  defaults (~70 s)
//   scale_out_bench --replicas 1,3 --seconds 2 --runs 1 --delay_trials 10
//
// Load generator, replicas and PostgreSQL share the machine's cores, so on a 2-core machine
// more replicas cannot add CPU: the figures show what balancing costs and where it saturates.
// Classify calls are made once (max_attempts 1): an error the client library would have
// retried away still counts. Exit 0 when nothing failed, 1 otherwise.

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/sysinfo.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <memory>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "CLI/CLI.hpp"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "bench/host_info.h"
#include "bench/percentile.h"
#include "client/client.h"
#include "core/testing/test_clouds.h"
#include "server/storage/testing/postgres_instance.h"
#include "server/testing/child_server.h"

extern char** environ;

namespace shapeid {
namespace {

using bench::CpuModel;
using bench::Percentile;

using Clock = std::chrono::steady_clock;
using testing_clouds::ShapeCloud;
constexpr auto& kShapes = testing_clouds::kShapeNames;

double MsSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}
Clock::time_point After(Clock::time_point t, double seconds) {
  return t + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds));
}
std::string ReadAll(const std::string& path) {
  std::ifstream in(path);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}
double SelfCpuSeconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_utime.tv_sec + u.ru_utime.tv_usec / 1e6 + u.ru_stime.tv_sec +
         u.ru_stime.tv_usec / 1e6;
}

// A client of `addresses`: round_robin over them when `balanced`, else pick_first.
std::unique_ptr<Client> Connect(const std::vector<std::string>& addresses, bool balanced,
                                int max_attempts = 3) {
  ClientOptions options;
  options.target = absl::StrJoin(addresses, ",");
  options.load_balancing = balanced ? "round_robin" : "pick_first";
  options.deadline = absl::Seconds(10);
  options.max_attempts = max_attempts;
  auto client = Client::Connect(options);
  if (!client.ok()) {
    std::fprintf(stderr, "Connect(%s): %s\n", options.target.c_str(),
                 client.status().ToString().c_str());
    std::exit(1);
  }
  return *std::move(client);
}

// Polls until gallery `name` holds `count` samples on the client's server, without pause;
// the milliseconds waited, or -1 after `timeout_ms`.
double WaitForCount(Client& client, const std::string& name, uint64_t count, double timeout_ms) {
  const auto t0 = Clock::now();
  while (MsSince(t0) < timeout_ms) {
    auto gallery = client.GetGallery(name);
    if (gallery.ok() && gallery->sample_count() == count) return MsSince(t0);
  }
  return -1;
}

struct Query {
  int kind;
  PointCloud cloud;
};

struct ClassifyRun {
  double per_second = 0, p50_ms = 0, p99_ms = 0, bench_cores = 0;
  int64_t errors = 0, wrong = 0, health_failures = 0, health_checks = 0;
  std::vector<double> replica_cpu;  // seconds, per replica
};

ClassifyRun RunClassify(const std::vector<ChildServer*>& replicas,
                        const std::vector<Query>& queries, int clients, double warmup_s,
                        double seconds) {
  std::vector<std::string> addresses;
  for (const ChildServer* r : replicas) addresses.push_back(r->address());
  std::vector<std::unique_ptr<Client>> own;
  for (int c = 0; c < clients; ++c) own.push_back(Connect(addresses, true, 1));
  const auto start = Clock::now();
  const auto measure = After(start, warmup_s);
  const auto end = After(measure, seconds);
  std::vector<std::vector<double>> ms(clients);
  std::atomic<int64_t> errors{0}, wrong{0};
  std::vector<std::thread> threads;
  for (int c = 0; c < clients; ++c) {
    threads.emplace_back([&, c] {
      for (size_t i = static_cast<size_t>(c) * 7; Clock::now() < end; ++i) {
        const Query& q = queries[i % queries.size()];
        const auto t0 = Clock::now();
        auto answer = own[c]->Classify("bench", q.cloud);
        if (t0 < measure) continue;
        if (!answer.ok()) {
          if (errors++ < 3)
            std::fprintf(stderr, "classify: %s\n", answer.status().ToString().c_str());
          continue;
        }
        if (answer->label() != kShapes[q.kind]) ++wrong;
        ms[c].push_back(MsSince(t0));
      }
    });
  }
  // Each replica's health every 200 ms, through its own pick_first client: a flapping
  // replica would drop out of round_robin.
  ClassifyRun r;
  std::atomic<bool> stop{false};
  std::thread health([&] {
    std::vector<std::unique_ptr<Client>> each;
    for (const std::string& a : addresses) each.push_back(Connect({a}, false, 1));
    while (!stop) {
      for (auto& c : each) {
        ++r.health_checks;
        if (!c->CheckHealth().ok()) ++r.health_failures;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(200));
    }
  });
  std::this_thread::sleep_until(measure);
  std::vector<double> cpu0;
  for (const ChildServer* rep : replicas) cpu0.push_back(absl::ToDoubleSeconds(rep->CpuTime()));
  const double self0 = SelfCpuSeconds();
  for (auto& t : threads) t.join();
  const double elapsed = std::chrono::duration<double>(Clock::now() - measure).count();
  const double self = SelfCpuSeconds() - self0;
  for (size_t i = 0; i < replicas.size(); ++i)
    r.replica_cpu.push_back(absl::ToDoubleSeconds(replicas[i]->CpuTime()) - cpu0[i]);
  stop = true;
  health.join();
  std::vector<double> all;
  for (auto& v : ms) all.insert(all.end(), v.begin(), v.end());
  r.per_second = all.size() / elapsed;
  r.p50_ms = Percentile(all, 0.5);
  r.p99_ms = Percentile(all, 0.99);
  r.bench_cores = self / elapsed;  // the health thread's few calls included
  r.errors = errors;
  r.wrong = wrong;
  return r;
}

struct TrainResult {
  double per_second = 0, batch_p50_ms = 0, converge_ms = 0;
  int64_t acked = 0, errors = 0;
  std::vector<int64_t> counts;  // per replica, after converging (or the timeout)
  std::string first_error;
  bool pass = false;
};

TrainResult RunTrain(const std::vector<ChildServer*>& replicas, const std::string& gallery,
                     int threads_n, double seconds, double bound_ms,
                     const std::vector<Query>& clouds) {
  std::vector<std::string> addresses;
  for (const ChildServer* r : replicas) addresses.push_back(r->address());
  TrainResult r;
  std::atomic<int64_t> acked{0}, errors{0};
  std::vector<std::vector<double>> ms(threads_n);
  const auto start = Clock::now();
  const auto end = After(start, seconds);
  std::vector<std::thread> threads;
  for (int t = 0; t < threads_n; ++t) {
    threads.emplace_back([&, t] {
      auto client = Connect(addresses, true);  // retries: every sample has its own id
      for (uint64_t batch = 0; Clock::now() < end; ++batch) {
        std::vector<TrainSample> samples;
        for (uint64_t j = 0; j < 4; ++j) {
          const Query& q = clouds[(batch * 4 + j + t) % clouds.size()];
          samples.push_back(
              {kShapes[q.kind], (t + 1) * 1000000000ull + batch * 4 + j + 1, &q.cloud});
        }
        const auto t0 = Clock::now();
        auto done = client->Train(gallery, samples);
        if (done.ok()) {
          acked += 4;
          ms[t].push_back(MsSince(t0));
        } else if (errors++ == 0) {
          r.first_error = done.status().ToString();  // read after the join
        }
      }
    });
  }
  for (auto& t : threads) t.join();
  const double elapsed = std::chrono::duration<double>(Clock::now() - start).count();
  r.acked = acked;
  r.errors = errors;
  r.per_second = r.acked / elapsed;
  std::vector<double> all;
  for (auto& v : ms) all.insert(all.end(), v.begin(), v.end());
  r.batch_p50_ms = Percentile(all, 0.5);
  // PASS: every replica holds exactly the acknowledged samples (a failed batch added none).
  r.pass = true;
  const auto t0 = Clock::now();
  for (const std::string& a : addresses) {
    auto client = Connect({a}, false);
    const double waited =
        WaitForCount(*client, gallery, r.acked, std::max(0.0, bound_ms + 2000 - MsSince(t0)));
    auto g = client->GetGallery(gallery);
    r.counts.push_back(g.ok() ? static_cast<int64_t>(g->sample_count()) : -1);
    if (waited < 0) r.pass = false;
  }
  r.converge_ms = MsSince(t0);
  return r;
}

// The figures of several runs: the median of each.
ClassifyRun Median(const std::vector<ClassifyRun>& runs) {
  auto med = [&](auto field) {
    std::vector<double> v;
    for (const ClassifyRun& r : runs) v.push_back(static_cast<double>(field(r)));
    return Percentile(v, 0.5);
  };
  ClassifyRun m;
  m.per_second = med([](const ClassifyRun& r) { return r.per_second; });
  m.p50_ms = med([](const ClassifyRun& r) { return r.p50_ms; });
  m.p99_ms = med([](const ClassifyRun& r) { return r.p99_ms; });
  m.bench_cores = med([](const ClassifyRun& r) { return r.bench_cores; });
  for (size_t i = 0; i < runs[0].replica_cpu.size(); ++i) {
    m.replica_cpu.push_back(med([i](const ClassifyRun& r) { return r.replica_cpu[i]; }));
  }
  for (const ClassifyRun& r : runs) {  // totals, not medians: any of them is a finding
    m.errors += r.errors, m.wrong += r.wrong;
    m.health_failures += r.health_failures, m.health_checks += r.health_checks;
  }
  return m;
}

int Run(int argc, char** argv) {
  CLI::App app{
      "Classify, replication delay and Train through shapeid-server replicas over PostgreSQL"};
  std::vector<int> replica_counts = {1, 2, 3};
  int clients = 16, runs = 3, delay_trials = 50, refresh_ms = 1000, train_threads = 4;
  double seconds = 5, warmup = 1, train_seconds = 3;
  size_t points = 1024;
  std::string server = SHAPEID_SERVER_PATH;
  std::string store;
  bool logs = false;
  bool pin = false;
  app.add_option("--replicas", replica_counts, "replica counts to measure")
      ->delimiter(',')
      ->capture_default_str();
  app.add_option("--clients", clients, "closed-loop Classify threads")->capture_default_str();
  app.add_option("--seconds", seconds, "measured seconds per Classify run")->capture_default_str();
  app.add_option("--warmup", warmup, "warm-up seconds before each Classify run")
      ->capture_default_str();
  app.add_option("--runs", runs, "Classify runs per replica count (median reported)")
      ->capture_default_str();
  app.add_option("--delay_trials", delay_trials, "replication delay trials (0: skip)")
      ->capture_default_str();
  app.add_option("--store_refresh_ms", refresh_ms, "the replicas' polling bound")
      ->capture_default_str();
  app.add_option("--train_seconds", train_seconds, "Train run per replica count (0: skip)")
      ->capture_default_str();
  app.add_option("--train_threads", train_threads, "Train threads (batches of 4)")
      ->capture_default_str();
  app.add_option("--points", points, "points per cloud")->capture_default_str();
  app.add_option("--server", server, "shapeid-server binary")->capture_default_str();
  app.add_option("--store", store,
                 "an existing PostgreSQL to use (conninfo; its galleries bench* must not exist); "
                 "default: a private one");
  app.add_flag("--pin", pin,
               "run replica i on core i mod nproc only (taskset), so each replica is one core");
  app.add_flag("--logs", logs, "print each replica's stderr at the end (always on failure)");
  CLI11_PARSE(app, argc, argv);
  if (replica_counts.empty() || clients < 1 || runs < 1 || train_threads < 1 || points < 16 ||
      *std::min_element(replica_counts.begin(), replica_counts.end()) < 1) {
    std::fprintf(stderr,
                 "--replicas, --clients, --runs, --train_threads must be >= 1, --points >= 16\n");
    return 2;
  }
  const int max_n = *std::max_element(replica_counts.begin(), replica_counts.end());
  std::vector<std::string> args(argv, argv + argc);
  const std::string load_start = ReadAll("/proc/loadavg");

  std::unique_ptr<PostgresInstance> pg;
  if (store.empty()) {
    auto started = PostgresInstance::Start();
    if (!started.ok()) {
      std::fprintf(stderr, "%s\n", started.status().ToString().c_str());
      return 1;
    }
    pg = *std::move(started);
    store = pg->conninfo();
  }
  std::vector<std::unique_ptr<ChildServer>> replicas;
  std::vector<std::string> stderr_paths;
  for (int i = 0; i < max_n; ++i) {
    stderr_paths.push_back(
        absl::StrCat("/tmp/scale_out_bench_", getpid(), "_replica", i, ".stderr"));
    replicas.push_back(std::make_unique<ChildServer>());
    std::vector<std::string> command = {server, "--listen=127.0.0.1:0", "--store=" + store,
                                        absl::StrCat("--store_refresh_ms=", refresh_ms)};
    // One core per replica (taskset execs the server: the pid stays the replica's), so that
    // on a small machine the figures show what a replica adds, not how the kernel shares.
    if (pin) {
      command.insert(command.begin(),
                     {"/usr/bin/taskset", "-c", std::to_string(i % std::max(1, get_nprocs()))});
    }
    const std::string binary = command.front();
    command.erase(command.begin());
    const absl::Status s = replicas.back()->Start(binary, command, stderr_paths.back());
    if (!s.ok()) {
      std::fprintf(stderr, "replica %d: %s\n", i, s.ToString().c_str());
      return 1;
    }
  }
  auto first = Connect({replicas[0]->address()}, false);
  v1::CreateGalleryRequest create;
  create.set_name("bench");
  auto created = first->CreateGallery(create);
  std::vector<Query> train_clouds, queries;
  for (uint32_t i = 0; i < 90; ++i)
    train_clouds.push_back({static_cast<int>(i % 3), ShapeCloud(i % 3, 100 + i, points)});
  for (uint32_t i = 0; i < 48; ++i)
    queries.push_back({static_cast<int>(i % 3), ShapeCloud(i % 3, 5000 + i, points)});
  std::vector<TrainSample> samples;
  for (size_t i = 0; i < train_clouds.size(); ++i)
    samples.push_back({kShapes[train_clouds[i].kind], i + 1, &train_clouds[i].cloud});
  const absl::Status trained =
      created.ok() ? first->Train("bench", samples).status() : created.status();
  if (!trained.ok()) {
    std::fprintf(stderr, "create / train: %s\n", trained.ToString().c_str());
    return 1;
  }
  for (int i = 0; i < max_n; ++i) {
    if (WaitForCount(*Connect({replicas[i]->address()}, false), "bench", 90, refresh_ms + 5000.0) <
        0) {
      std::fprintf(stderr, "replica %d never showed the 90 samples; stderr:\n%s\n", i,
                   replicas[i]->StderrText().c_str());
      return 1;
    }
  }
  bool failed = false;

  // 1. Classify throughput.
  std::vector<std::pair<int, ClassifyRun>> classify;
  for (int n : replica_counts) {
    std::vector<ChildServer*> use;
    for (int i = 0; i < n; ++i) use.push_back(replicas[i].get());
    std::vector<ClassifyRun> each;
    for (int run = 0; run < runs; ++run) {
      each.push_back(RunClassify(use, queries, clients, warmup, seconds));
      const ClassifyRun& r = each.back();
      std::fprintf(stderr,
                   "replicas %d run %d: %.0f /s, p50 %.2f ms, p99 %.2f ms, errors %lld, cpu %s\n",
                   n, run + 1, r.per_second, r.p50_ms, r.p99_ms, static_cast<long long>(r.errors),
                   absl::StrJoin(r.replica_cpu, " ", [](std::string* o, double v) {
                     absl::StrAppendFormat(o, "%.2f", v);
                   }).c_str());
    }
    classify.push_back({n, Median(each)});
    failed |= classify.back().second.errors > 0 || classify.back().second.wrong > 0;
  }

  // 2. Replication delay: acknowledged by replica 0 until replica 1 shows it.
  std::vector<double> delays, acks;
  int timeouts = 0;
  if (max_n >= 2 && delay_trials > 0) {
    v1::CreateGalleryRequest c;
    c.set_name("bench_delay");
    auto other = Connect({replicas[1]->address()}, false);
    failed |= !first->CreateGallery(c).ok() ||
              WaitForCount(*other, "bench_delay", 0, refresh_ms + 5000.0) < 0;
    std::mt19937 rng(7);
    for (int t = 0; t < delay_trials && !failed; ++t) {
      // A random pause so that the trials do not keep one phase against the polling timer.
      std::this_thread::sleep_for(std::chrono::milliseconds(rng() % 100));
      const TrainSample one{"box", static_cast<uint64_t>(t + 1), &train_clouds[0].cloud};
      const auto t0 = Clock::now();
      if (!first->Train("bench_delay", {&one, 1}).ok()) {
        failed = true;
        break;
      }
      acks.push_back(MsSince(t0));
      const double d = WaitForCount(*other, "bench_delay", t + 1, refresh_ms + 5000.0);
      if (d < 0)
        ++timeouts;
      else
        delays.push_back(d);
    }
    failed |= timeouts > 0;
  }

  // 3. Train throughput and the acknowledged count on every replica.
  std::vector<std::pair<int, TrainResult>> training;
  for (int n : replica_counts) {
    if (train_seconds <= 0) break;
    const std::string name = absl::StrCat("bench_train_", n);
    v1::CreateGalleryRequest c;
    c.set_name(name);
    failed |= !first->CreateGallery(c).ok();
    std::vector<ChildServer*> use;
    for (int i = 0; i < n; ++i) {
      use.push_back(replicas[i].get());
      failed |=
          WaitForCount(*Connect({replicas[i]->address()}, false), name, 0, refresh_ms + 5000.0) < 0;
    }
    training.push_back(
        {n, RunTrain(use, name, train_threads, train_seconds, refresh_ms, train_clouds)});
    failed |= !training.back().second.pass || training.back().second.errors > 0;
  }
  const std::string load_end = ReadAll("/proc/loadavg");
  std::vector<int> exits;
  for (auto& r : replicas) exits.push_back(r->Terminate(absl::Seconds(10)));

  // ------------------------------------------------------------------ report
  std::printf("## Scale-out bench\n\n");
  std::printf("- command: `%s`\n", absl::StrJoin(args, " ").c_str());
  std::printf("- machine: %ld cores (nproc), %s; load average at start %.14s, at end %.14s\n",
              sysconf(_SC_NPROCESSORS_ONLN), CpuModel().c_str(), load_start.c_str(),
              load_end.c_str());
  std::printf(
      "- %d shapeid-server replicas over one %s PostgreSQL on loopback, "
      "--store_refresh_ms=%d; gallery `bench`: %s, 90 samples (3 shapes x 30, %zu points), "
      "trained through replica 0\n",
      max_n, pg != nullptr ? "private" : "given (--store)", refresh_ms,
      created->descriptor_spec().c_str(), points);
  std::printf(
      "\n### Classify: %d closed-loop clients, each its own Client round_robin over the first N "
      "replicas; %g s after %g s warm-up; median of %d runs\n\n",
      clients, seconds, warmup, runs);
  std::printf(
      "| replicas | requests/s | p50 ms | p99 ms | errors | wrong labels | replica CPU s (each) | "
      "replica cores busy | bench cores busy | health checks failed |\n"
      "|---:|---:|---:|---:|---:|---:|---|---:|---:|---:|\n");
  for (const auto& [n, m] : classify) {
    double sum = 0;
    for (double v : m.replica_cpu) sum += v;
    std::printf("| %d | %.0f | %.2f | %.2f | %lld | %lld | %s | %.2f | %.2f | %lld / %lld |\n", n,
                m.per_second, m.p50_ms, m.p99_ms, static_cast<long long>(m.errors),
                static_cast<long long>(m.wrong),
                absl::StrJoin(m.replica_cpu, " / ",
                              [](std::string* o, double v) { absl::StrAppendFormat(o, "%.2f", v); })
                    .c_str(),
                sum / seconds, m.bench_cores, static_cast<long long>(m.health_failures),
                static_cast<long long>(m.health_checks));
  }
  std::printf(
      "\n(errors, wrong labels and failed health checks: totals over the runs; cores busy: CPU "
      "seconds per measured second)\n");
  if (!delays.empty() || timeouts > 0) {
    std::printf(
        "\n### Replication delay: Train of one sample acknowledged by replica 0 (pick_first) "
        "until GetGallery on replica 1 shows it (polled without pause)\n\n");
    std::printf(
        "| trials | min ms | median ms | p99 ms | max ms | over the bound | timeouts | "
        "polling bound ms | Train ack p50 ms |\n|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    const auto over =
        std::count_if(delays.begin(), delays.end(), [&](double d) { return d > refresh_ms; });
    std::printf("| %zu | %.2f | %.2f | %.2f | %.2f | %ld | %d | %d | %.2f |\n",
                delays.size() + timeouts, Percentile(delays, 0), Percentile(delays, 0.5),
                Percentile(delays, 0.99), Percentile(delays, 1), static_cast<long>(over), timeouts,
                refresh_ms, Percentile(acks, 0.5));
  }
  if (!training.empty()) {
    std::printf(
        "\n### Train: %d threads, batches of 4 samples with client ids, round_robin over the "
        "first N replicas, %g s; then every replica must hold exactly the acknowledged "
        "samples\n\n",
        train_threads, train_seconds);
    std::printf(
        "| replicas | samples/s | batch p50 ms | errors | acknowledged | count on each replica | "
        "all agreed after ms | check |\n|---:|---:|---:|---:|---:|---|---:|---|\n");
    for (const auto& [n, t] : training) {
      std::printf("| %d | %.0f | %.2f | %lld | %lld | %s | %.1f | %s |\n", n, t.per_second,
                  t.batch_p50_ms, static_cast<long long>(t.errors), static_cast<long long>(t.acked),
                  absl::StrJoin(t.counts, " / ").c_str(), t.converge_ms, t.pass ? "PASS" : "FAIL");
    }
    for (const auto& [n, t] : training) {
      if (t.errors > 0)
        std::printf("\n%d replicas, first Train error: %s\n", n, t.first_error.c_str());
    }
  }
  std::printf("\nreplica exit statuses after SIGTERM: %s\n", absl::StrJoin(exits, " ").c_str());
  for (int e : exits) failed |= e != 0;
  if (failed || logs) {
    for (int i = 0; i < max_n; ++i)
      std::printf("replica %d stderr:\n%s\n", i, replicas[i]->StderrText().c_str());
  }
  for (const std::string& p : stderr_paths) unlink(p.c_str());
  std::printf("result: %s\n", failed ? "FAIL" : "OK");
  return failed ? 1 : 0;
}

}  // namespace
}  // namespace shapeid

int main(int argc, char** argv) { return shapeid::Run(argc, argv); }
