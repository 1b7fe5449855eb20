// What observing a call costs (issue 12): the metrics recorded per call, the log line's
// formatting and writing, and a Prometheus scrape, each alone, so the per-RPC overhead that
// service_bench --log_level=info shows can be split into its parts.
//
//   operations_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
//
// The figures are per call of the server's code, against the ~700 us a ModelNet10 Classify
// takes (docs/performance.md).

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/time/time.h"
#include "benchmark/benchmark.h"
#include "core/gallery/gallery_registry.h"
#include "prometheus/text_serializer.h"
#include "server/ops/logger.h"
#include "server/ops/metrics.h"

namespace shapeid {
namespace {

constexpr absl::string_view kMethods[] = {
    "Describe",      "DescribeCloud", "Train",           "Classify",       "ClassifyCloud",
    "CreateGallery", "GetGallery",    "ListGalleries",   "DeleteGallery",  "RemoveSamples",
    "ExportGallery", "ImportGallery", "ListDescriptors", "GetServerStats", "SetLogLevel"};

// A successful ClassifyCloud of a 1,024-point cloud: what most calls look like.
CallMetrics ClassifyCall(absl::string_view gallery) {
  CallMetrics call;
  call.method = "ClassifyCloud";
  call.gallery = gallery;
  call.elapsed = absl::Microseconds(740);
  call.points = 1024;
  return call;
}

// ----------------------------------------------------------------------------- metrics

// Metrics over a registry holding `galleries` (empty) galleries named g0, g1...: a call's
// gallery gets a label of its own only if the server holds it.
struct Served {
  explicit Served(int galleries, MetricsOptions options = {}) : metrics(options) {
    GalleryLimits limits;
    limits.max_galleries = static_cast<size_t>(galleries) + 1;
    registry = std::make_shared<GalleryRegistry>(limits);
    for (int g = 0; g < galleries; ++g) {
      names.push_back(absl::StrCat("g", g));
      (void)registry->Create(names.back(), GalleryOptions());
    }
    metrics.SetSources(registry, LiveSources());
  }
  std::shared_ptr<GalleryRegistry> registry;
  std::vector<std::string> names;
  ServerMetrics metrics;
};

// The common case: the call's series exist already.
void BM_RecordCall(benchmark::State& state) {
  Served served(1);
  ServerMetrics& metrics = served.metrics;
  const CallMetrics call = ClassifyCall(served.names[0]);
  metrics.RecordCall(call);
  for (auto _ : state) metrics.RecordCall(call);
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_RecordCall);

// A gallery seen for the first time: a label taken and new series built. Fixed iterations,
// since every one adds series that stay (and needs a gallery held).
void BM_RecordCallFreshGallery(benchmark::State& state) {
  MetricsOptions options;
  options.max_gallery_labels = static_cast<int>(state.max_iterations) + 1;
  Served served(static_cast<int>(state.max_iterations), options);
  size_t i = 0;
  for (auto _ : state) served.metrics.RecordCall(ClassifyCall(served.names[i++]));
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_RecordCallFreshGallery)->Iterations(2000);

// A failed call naming a gallery the server does not hold ("_unknown").
void BM_RecordCallNotFound(benchmark::State& state) {
  Served served(1);
  ServerMetrics& metrics = served.metrics;
  CallMetrics call = ClassifyCall("missing");
  call.code = absl::StatusCode::kNotFound;
  metrics.RecordCall(call);
  for (auto _ : state) metrics.RecordCall(call);
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_RecordCallNotFound);

// Every server thread records into one ServerMetrics: its one mutex (taken five times per call)
// and prometheus-cpp's per-series atomics are shared. items_per_second is the total.
void BM_RecordCallThreads(benchmark::State& state) {
  static Served* const served = new Served(1);
  const CallMetrics call = ClassifyCall(served->names[0]);
  for (auto _ : state) served->metrics.RecordCall(call);
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_RecordCallThreads)->Threads(1)->Threads(2)->Threads(4)->UseRealTime();

void BM_ObserveDescribe(benchmark::State& state) {
  ServerMetrics metrics;
  for (auto _ : state) metrics.ObserveDescribe("dfsd", absl::Microseconds(140));
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_ObserveDescribe);

// ----------------------------------------------------------------------------- log

// The fields CallObserver::Finish writes for a successful call.
struct RpcLine {
  std::string code = "OK";
  std::string peer = "ipv4:127.0.0.1:53410";
  std::string caller = "robot-7";
  std::string request_id = "3f9a0c1b7d2e4a68";
  std::vector<LogField> fields{{"method", "ClassifyCloud"},
                               {"gallery", "modelnet10"},
                               {"code", code},
                               {"us", int64_t{742}},
                               {"points", int64_t{1024}},
                               {"samples", int64_t{0}},
                               {"describe_us", int64_t{139}},
                               {"search_us", int64_t{561}},
                               {"peer", peer},
                               {"caller", caller},
                               {"request_id", request_id}};
};

LogFormat FormatArg(const benchmark::State& state) {
  return state.range(0) == 0 ? LogFormat::kText : LogFormat::kJson;
}

void BM_LogFormat(benchmark::State& state) {
  const RpcLine line;
  const Logger logger({FormatArg(state), LogLevel::kInfo}, [](absl::string_view) {});
  size_t bytes = 0;
  for (auto _ : state) {
    const std::string text = logger.Format(LogLevel::kInfo, "rpc", line.fields);
    bytes = text.size();
    benchmark::DoNotOptimize(text.data());
  }
  state.counters["line_bytes"] = static_cast<double>(bytes);
  state.SetLabel(FormatArg(state) == LogFormat::kText ? "text" : "json");
}
BENCHMARK(BM_LogFormat)->Arg(0)->Arg(1)->ArgName("json");

// --log_level=warning or error: an info line is dropped before it is formatted.
void BM_LogDropped(benchmark::State& state) {
  const RpcLine line;
  const Logger logger({LogFormat::kJson, LogLevel::kError}, [](absl::string_view) {});
  for (auto _ : state) logger.Log(LogLevel::kInfo, "rpc", line.fields);
}
BENCHMARK(BM_LogDropped);

// Formatted and written with one write(2), as the default sink does to stderr, to an fd on
// /dev/null: the system call without a disk or a terminal behind it.
void BM_LogDevNull(benchmark::State& state) {
  const int fd = open("/dev/null", O_WRONLY | O_CLOEXEC);
  if (fd < 0) {
    state.SkipWithError("cannot open /dev/null");
    return;
  }
  const RpcLine line;
  const Logger logger({FormatArg(state), LogLevel::kInfo}, [fd](absl::string_view text) {
    while (!text.empty()) {
      const ssize_t n = write(fd, text.data(), text.size());
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) return;
      text.remove_prefix(static_cast<size_t>(n));
    }
  });
  for (auto _ : state) logger.Log(LogLevel::kInfo, "rpc", line.fields);
  close(fd);
  state.SetLabel(FormatArg(state) == LogFormat::kText ? "text" : "json");
}
BENCHMARK(BM_LogDevNull)->Arg(0)->Arg(1)->ArgName("json");

// ----------------------------------------------------------------------------- scrape

// A busy server: 50 galleries, each classified, trained and read, every one of the 15
// methods called, some calls failed, the describe/search/store histograms filled.
struct BusyServer {
  std::shared_ptr<GalleryRegistry> registry = std::make_shared<GalleryRegistry>();
  ServerMetrics metrics;

  BusyServer() {
    LiveSources live;
    live.calls_in_flight = [] { return int64_t{3}; };
    live.serving = [] { return true; };
    metrics.SetSources(registry, std::move(live));  // first: calls label held galleries only
    for (int g = 0; g < 50; ++g) {
      const std::string name = absl::StrCat("gallery", g);
      (void)registry->Create(name, GalleryOptions());
      for (const absl::string_view method : {"Classify", "ClassifyCloud", "GetGallery"}) {
        CallMetrics call = ClassifyCall(name);
        call.method = method;
        metrics.RecordCall(call);
      }
      CallMetrics train = ClassifyCall(name);
      train.method = "Train";
      train.samples_trained = 10;
      metrics.RecordCall(train);
    }
    for (const absl::string_view method : kMethods) {
      CallMetrics call;
      call.method = method;
      call.elapsed = absl::Microseconds(300);
      metrics.RecordCall(call);
      call.code = absl::StatusCode::kInvalidArgument;
      metrics.RecordCall(call);
    }
    CallMetrics missing = ClassifyCall("nope");
    missing.code = absl::StatusCode::kNotFound;
    metrics.RecordCall(missing);
    for (const absl::string_view kind : {"dfsd", "rphsd", "esf"}) {
      metrics.ObserveDescribe(kind, absl::Microseconds(140));
    }
    metrics.ObserveSearch(false, absl::Microseconds(500));
    metrics.ObserveSearch(true, absl::Microseconds(80));
    for (const absl::string_view op : {"save", "append", "remove", "delete"}) {
      metrics.ObserveStoreWrite(op, absl::Milliseconds(2), true);
    }
  }
};

void BM_ScrapeCollect(benchmark::State& state) {
  BusyServer server;
  for (auto _ : state) {
    std::vector<prometheus::MetricFamily> families = server.metrics.Collect();
    benchmark::DoNotOptimize(families.data());
  }
}
BENCHMARK(BM_ScrapeCollect)->Unit(benchmark::kMicrosecond);

// What /metrics does per scrape: Collect, then the text exposition format.
void BM_Scrape(benchmark::State& state) {
  BusyServer server;
  const prometheus::TextSerializer serializer;
  size_t bytes = 0;
  size_t series = 0;
  for (auto _ : state) {
    const std::vector<prometheus::MetricFamily> families = server.metrics.Collect();
    const std::string text = serializer.Serialize(families);
    bytes = text.size();
    series = 0;
    for (const auto& family : families) series += family.metric.size();
    benchmark::DoNotOptimize(text.data());
  }
  state.counters["bytes"] = static_cast<double>(bytes);
  state.counters["series"] = static_cast<double>(series);
}
BENCHMARK(BM_Scrape)->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace shapeid

BENCHMARK_MAIN();
