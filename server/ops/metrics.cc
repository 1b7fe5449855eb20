#include "server/ops/metrics.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <utility>

#include "absl/strings/str_cat.h"
#include "core/gallery/gallery.h"
#include "core/gallery/gallery_options.h"
#include "core/gallery/gallery_registry.h"
#include "core/version.h"
#include "server/ops/process_stats.h"

namespace shapeid {
namespace {

using prometheus::ClientMetric;
using prometheus::MetricFamily;
using prometheus::MetricType;

constexpr char kOtherGalleries[] = "_other";
constexpr char kUnknownGallery[] = "_unknown";

// Seconds. A call spans 100 us (a small unary classify) to minutes (an export); describing and
// searching a cloud 10 us to seconds; a store write a millisecond (SQLite, synchronous) to
// seconds (a large import, PostgreSQL across a network).
const prometheus::Histogram::BucketBoundaries& CallBuckets() {
  static const auto* buckets = new prometheus::Histogram::BucketBoundaries{
      0.0001, 0.00025, 0.0005, 0.00075, 0.001, 0.0025, 0.005, 0.0075, 0.01, 0.025, 0.05,
      0.1,    0.25,    0.5,    1,       2.5,   5,      10,    30,     60,   300};
  return *buckets;
}
const prometheus::Histogram::BucketBoundaries& WorkBuckets() {
  static const auto* buckets = new prometheus::Histogram::BucketBoundaries{
      0.00001, 0.000025, 0.00005, 0.0001, 0.00025, 0.0005, 0.001, 0.0025, 0.005,
      0.01,    0.025,    0.05,    0.1,    0.25,    0.5,    1,     2.5,    10};
  return *buckets;
}
// A wait for a worker: microseconds when idle, seconds behind heavy work, minutes at worst
// (a caller's backlog is bounded by --max_caller_backlog_seconds).
const prometheus::Histogram::BucketBoundaries& WaitBuckets() {
  static const auto* buckets = new prometheus::Histogram::BucketBoundaries{
      0.00001, 0.000025, 0.00005, 0.0001, 0.00025, 0.0005, 0.001, 0.0025, 0.005, 0.01, 0.025, 0.05,
      0.1,     0.25,     0.5,     1,      2.5,     5,      10,    30,     60,    120,  300};
  return *buckets;
}
const prometheus::Histogram::BucketBoundaries& StoreBuckets() {
  static const auto* buckets = new prometheus::Histogram::BucketBoundaries{
      0.0001, 0.00025, 0.0005, 0.001, 0.0025, 0.005, 0.01, 0.025, 0.05,
      0.1,    0.25,    0.5,    1,     2.5,    5,     10,   30};
  return *buckets;
}

MetricFamily Family(std::string name, std::string help, MetricType type) {
  MetricFamily family;
  family.name = std::move(name);
  family.help = std::move(help);
  family.type = type;
  return family;
}

ClientMetric Gauge(double value, std::vector<ClientMetric::Label> labels = {}) {
  ClientMetric metric;
  metric.label = std::move(labels);
  metric.gauge.value = value;
  return metric;
}

ClientMetric Counter(double value) {
  ClientMetric metric;
  metric.counter.value = value;
  return metric;
}

std::string LabelValue(const ClientMetric& metric, absl::string_view name) {
  for (const ClientMetric::Label& label : metric.label) {
    if (label.name == name) return label.value;
  }
  return "";
}

}  // namespace

std::optional<double> HistogramQuantile(double q, const std::vector<double>& bounds,
                                        const std::vector<uint64_t>& cumulative) {
  if (bounds.empty() || bounds.size() != cumulative.size() || cumulative.back() == 0) {
    return std::nullopt;
  }
  const double rank = q * static_cast<double>(cumulative.back());
  size_t bucket = 0;
  while (bucket + 1 < cumulative.size() && static_cast<double>(cumulative[bucket]) < rank) {
    ++bucket;
  }
  // In the +Inf bucket there is no upper bound to interpolate to: the highest finite bound.
  if (std::isinf(bounds[bucket])) return bucket == 0 ? 0.0 : bounds[bucket - 1];
  const double lower = bucket == 0 ? 0.0 : bounds[bucket - 1];
  const double below = bucket == 0 ? 0.0 : static_cast<double>(cumulative[bucket - 1]);
  const double in_bucket = static_cast<double>(cumulative[bucket]) - below;
  if (in_bucket <= 0) return lower;
  return lower + (bounds[bucket] - lower) * (rank - below) / in_bucket;
}

ServerMetrics::ServerMetrics(MetricsOptions options)
    : options_(std::move(options)),
      registry_(std::make_shared<prometheus::Registry>()),
      requests_(prometheus::BuildCounter()
                    .Name("shapeid_requests_total")
                    .Help("Calls answered, by method, gallery (bounded: see docs/operations.md) "
                          "and gRPC status code.")
                    .Register(*registry_)),
      request_duration_(prometheus::BuildHistogram()
                            .Name("shapeid_request_duration_seconds")
                            .Help("Server time from a call's arrival to its answer, by method.")
                            .Register(*registry_)),
      request_wait_(prometheus::BuildHistogram()
                        .Name("shapeid_request_wait_seconds")
                        .Help("Time a call's work waited for a worker (the scheduler's "
                              "queues), by method; calls with no work to queue are not counted.")
                        .Register(*registry_)),
      work_wait_(prometheus::BuildHistogram()
                     .Name("shapeid_work_wait_seconds")
                     .Help("Time one piece of work waited for a worker, by the scheduler's "
                           "lane (cheap, heavy, store).")
                     .Register(*registry_)),
      points_(prometheus::BuildCounter()
                  .Name("shapeid_points_received_total")
                  .Help("Points received in the clouds of calls, by method.")
                  .Register(*registry_)),
      samples_trained_(prometheus::BuildCounter()
                           .Name("shapeid_samples_trained_total")
                           .Help("Samples committed by Train, by gallery.")
                           .Register(*registry_)),
      describe_duration_(prometheus::BuildHistogram()
                             .Name("shapeid_describe_duration_seconds")
                             .Help("Time to compute one cloud's descriptor, by descriptor kind "
                                   "(with training-time views, a sample's clouds together).")
                             .Register(*registry_)),
      search_duration_(prometheus::BuildHistogram()
                           .Name("shapeid_search_duration_seconds")
                           .Help("Time of one Classify's kNN search, by index (exact or "
                                 "approximate).")
                           .Register(*registry_)),
      store_write_duration_(prometheus::BuildHistogram()
                                .Name("shapeid_store_write_duration_seconds")
                                .Help("Time of one durable write to the gallery store, by "
                                      "operation (save, append, remove, delete).")
                                .Register(*registry_)),
      store_write_failures_(prometheus::BuildCounter()
                                .Name("shapeid_store_write_failures_total")
                                .Help("Writes to the gallery store that failed, by operation.")
                                .Register(*registry_)) {}

void ServerMetrics::SetSources(std::weak_ptr<const GalleryRegistry> galleries, LiveSources live) {
  std::lock_guard<std::mutex> lock(mu_);
  galleries_ = std::move(galleries);
  live_ = std::move(live);
}

std::string ServerMetrics::GalleryLabel(absl::string_view name, bool held) const {
  if (name.empty()) return "";
  if (!held) return kUnknownGallery;
  std::lock_guard<std::mutex> lock(mu_);
  if (labeled_galleries_.contains(name)) return std::string(name);
  if (static_cast<int>(labeled_galleries_.size()) >= options_.max_gallery_labels) {
    return kOtherGalleries;
  }
  labeled_galleries_.insert(std::string(name));
  return std::string(name);
}

template <typename T, typename... Args>
T& ServerMetrics::Series(SeriesCache<T>& cache, prometheus::Family<T>& family,
                         const prometheus::Labels& labels, Args&&... args) {
  std::string key;
  for (const auto& [name, value] : labels) absl::StrAppend(&key, value, "\x1f");
  std::lock_guard<std::mutex> lock(mu_);
  T*& series = cache[key];
  if (series == nullptr) series = &family.Add(labels, std::forward<Args>(args)...);
  return *series;
}

void ServerMetrics::RecordCall(const CallMetrics& call) {
  // Only a real gallery's name becomes a label: one the server holds when the call ends, or
  // one the call just deleted. Any other name a client sends, however long or strange, is
  // "_unknown".
  bool held = false;
  if (!call.gallery.empty() && ValidateGalleryName(call.gallery).ok()) {
    if (call.code == absl::StatusCode::kOk && call.method == "DeleteGallery") {
      held = true;
    } else {
      std::shared_ptr<const GalleryRegistry> galleries;
      {
        std::lock_guard<std::mutex> lock(mu_);
        galleries = galleries_.lock();
      }
      held = galleries != nullptr && galleries->Get(call.gallery).ok();
    }
  }
  const std::string gallery = GalleryLabel(call.gallery, held);
  const std::string method(call.method);
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (std::find(methods_seen_.begin(), methods_seen_.end(), method) == methods_seen_.end()) {
      methods_seen_.push_back(method);
    }
  }
  // Series are cached: prometheus-cpp's Family::Add builds a new series object on every call
  // before it looks the labels up.
  Series(requests_cache_, requests_,
         {{"method", method}, {"gallery", gallery}, {"code", absl::StatusCodeToString(call.code)}})
      .Increment();
  Series(request_duration_cache_, request_duration_, {{"method", method}}, CallBuckets())
      .Observe(absl::ToDoubleSeconds(call.elapsed));
  if (call.waited > absl::ZeroDuration()) {
    Series(request_wait_cache_, request_wait_, {{"method", method}}, WaitBuckets())
        .Observe(absl::ToDoubleSeconds(call.waited));
  }
  if (call.points > 0) {
    Series(points_cache_, points_, {{"method", method}})
        .Increment(static_cast<double>(call.points));
  }
  if (call.samples_trained > 0) {
    Series(samples_trained_cache_, samples_trained_, {{"gallery", gallery}})
        .Increment(static_cast<double>(call.samples_trained));
  }
}

void ServerMetrics::ObserveDescribe(absl::string_view descriptor, absl::Duration elapsed) {
  Series(describe_cache_, describe_duration_, {{"descriptor", std::string(descriptor)}},
         WorkBuckets())
      .Observe(absl::ToDoubleSeconds(elapsed));
}

void ServerMetrics::ObserveSearch(bool approximate, absl::Duration elapsed) {
  Series(search_cache_, search_duration_, {{"index", approximate ? "approximate" : "exact"}},
         WorkBuckets())
      .Observe(absl::ToDoubleSeconds(elapsed));
}

void ServerMetrics::ObserveWait(absl::string_view lane, absl::Duration waited) {
  Series(work_wait_cache_, work_wait_, {{"lane", std::string(lane)}}, WaitBuckets())
      .Observe(absl::ToDoubleSeconds(waited));
}

void ServerMetrics::ObserveStoreWrite(absl::string_view operation, absl::Duration elapsed,
                                      bool ok) {
  const prometheus::Labels labels = {{"operation", std::string(operation)}};
  Series(store_write_cache_, store_write_duration_, labels, StoreBuckets())
      .Observe(absl::ToDoubleSeconds(elapsed));
  if (!ok) Series(store_failures_cache_, store_write_failures_, labels).Increment();
}

std::vector<MetricFamily> ServerMetrics::Collect() const {
  std::vector<MetricFamily> families = registry_->Collect();
  CollectLive(&families);
  return families;
}

void ServerMetrics::CollectLive(std::vector<MetricFamily>* out) const {
  std::shared_ptr<const GalleryRegistry> galleries;
  LiveSources live;
  {
    std::lock_guard<std::mutex> lock(mu_);
    galleries = galleries_.lock();
    live = live_;
  }
  MetricFamily build =
      Family("shapeid_build_info", "Always 1; the version in a label.", MetricType::Gauge);
  build.metric.push_back(Gauge(1, {{"version", kShapeidVersion}}));
  out->push_back(std::move(build));

  if (live.calls_in_flight) {
    MetricFamily family = Family("shapeid_requests_in_flight",
                                 "Calls admitted and not yet answered.", MetricType::Gauge);
    family.metric.push_back(Gauge(static_cast<double>(live.calls_in_flight())));
    out->push_back(std::move(family));
  }
  if (live.serving) {
    MetricFamily family = Family("shapeid_serving",
                                 "1 while calls are served; 0 while loading, draining or (a "
                                 "replica) cut off from its shared store.",
                                 MetricType::Gauge);
    family.metric.push_back(Gauge(live.serving() ? 1 : 0));
    out->push_back(std::move(family));
  }
  if (live.work) {
    MetricFamily workers =
        Family("shapeid_workers", "Threads of the work scheduler, by lane (cheap, heavy, store).",
               MetricType::Gauge);
    MetricFamily running =
        Family("shapeid_work_running", "Pieces of work running now, by lane.", MetricType::Gauge);
    MetricFamily queued = Family(
        "shapeid_work_queued", "Pieces of work waiting for a worker, by lane.", MetricType::Gauge);
    MetricFamily queued_seconds =
        Family("shapeid_work_queued_seconds",
               "Estimated CPU time of the work waiting for a worker, by lane.", MetricType::Gauge);
    for (const WorkLaneState& lane : live.work()) {
      workers.metric.push_back(Gauge(lane.workers, {{"lane", lane.lane}}));
      running.metric.push_back(Gauge(lane.running, {{"lane", lane.lane}}));
      queued.metric.push_back(Gauge(static_cast<double>(lane.queued), {{"lane", lane.lane}}));
      queued_seconds.metric.push_back(Gauge(lane.queued_seconds, {{"lane", lane.lane}}));
    }
    out->push_back(std::move(workers));
    out->push_back(std::move(running));
    out->push_back(std::move(queued));
    out->push_back(std::move(queued_seconds));
  }
  if (live.backlog) {
    const WorkBacklogState state = live.backlog();
    MetricFamily backlog = Family(
        "shapeid_caller_backlog_seconds",
        "Estimated work admitted and not yet started, summed over callers (each bounded by "
        "--max_caller_backlog_seconds); always sum(shapeid_work_queued_seconds), 0 when idle.",
        MetricType::Gauge);
    backlog.metric.push_back(Gauge(state.backlog_seconds));
    out->push_back(std::move(backlog));
    MetricFamily callers = Family("shapeid_callers_with_backlog",
                                  "Callers with work waiting in the scheduler.", MetricType::Gauge);
    callers.metric.push_back(Gauge(static_cast<double>(state.callers)));
    out->push_back(std::move(callers));
  }
  if (live.learner) {
    if (const std::optional<LearnerState> learner = live.learner(); learner.has_value()) {
      MetricFamily fits = Family("shapeid_head_fits_total",
                                 "Trained heads fitted and published since start (--learn=mlp).",
                                 MetricType::Counter);
      fits.metric.push_back(Counter(static_cast<double>(learner->fits)));
      out->push_back(std::move(fits));
      MetricFamily failures = Family(
          "shapeid_head_fit_failures_total",
          "Fits that failed (their memory could not be held, say) since start; retried later.",
          MetricType::Counter);
      failures.metric.push_back(Counter(static_cast<double>(learner->failures)));
      out->push_back(std::move(failures));
      MetricFamily fitting =
          Family("shapeid_head_fitting", "1 while a gallery's head is being fitted, else 0.",
                 MetricType::Gauge);
      fitting.metric.push_back(Gauge(learner->fitting ? 1 : 0));
      out->push_back(std::move(fitting));
    }
  }
  if (live.memory) {
    const MemoryBudgetState memory = live.memory();
    MetricFamily budget = Family("shapeid_memory_budget_bytes",
                                 "The memory calls may hold beyond the galleries (clouds in "
                                 "transit, describing): --memory_budget_mib; 0 unbounded.",
                                 MetricType::Gauge);
    budget.metric.push_back(Gauge(static_cast<double>(memory.budget_bytes)));
    out->push_back(std::move(budget));
    MetricFamily held = Family("shapeid_memory_held_bytes",
                               "Memory of the budget that calls hold now.", MetricType::Gauge);
    held.metric.push_back(Gauge(static_cast<double>(memory.held_bytes)));
    out->push_back(std::move(held));
    MetricFamily peak =
        Family("shapeid_memory_held_peak_bytes",
               "The most of the budget calls held at once since start.", MetricType::Gauge);
    peak.metric.push_back(Gauge(static_cast<double>(memory.peak_bytes)));
    out->push_back(std::move(peak));
  }
  if (galleries != nullptr) {
    // Galleries past the label limit are summed under "_other".
    std::vector<std::pair<std::string, double>> held;
    for (const std::shared_ptr<Gallery>& gallery : galleries->All()) {
      held.emplace_back(gallery->name(), static_cast<double>(gallery->Snapshot()->num_samples()));
    }
    const int64_t count = static_cast<int64_t>(held.size());
    int64_t folded = 0;
    std::map<std::string, double> samples;
    for (const auto& [name, n] : held) {
      // A gallery first seen here takes a free label, as a call would have given it.
      const std::string label = GalleryLabel(name, true);
      if (label == kOtherGalleries) ++folded;
      samples[label] += n;
    }
    MetricFamily galleries_family =
        Family("shapeid_galleries", "Galleries held.", MetricType::Gauge);
    galleries_family.metric.push_back(Gauge(static_cast<double>(count)));
    out->push_back(std::move(galleries_family));
    MetricFamily samples_family = Family(
        "shapeid_gallery_samples",
        "Samples held, by gallery (galleries past --metrics_max_galleries summed as _other).",
        MetricType::Gauge);
    for (const auto& [name, n] : samples) {
      samples_family.metric.push_back(Gauge(n, {{"gallery", name}}));
    }
    out->push_back(std::move(samples_family));
    MetricFamily folded_family = Family(
        "shapeid_gallery_labels_folded",
        "Galleries held without a label of their own (past --metrics_max_galleries): counted "
        "under gallery=\"_other\".",
        MetricType::Gauge);
    folded_family.metric.push_back(Gauge(static_cast<double>(folded)));
    out->push_back(std::move(folded_family));
  }
  if (live.replication) {
    if (const std::optional<ReplicationState> replication = live.replication()) {
      MetricFamily reachable = Family(
          "shapeid_store_reachable",
          "1 while this replica reaches its shared store (PostgreSQL) within the refresh bound.",
          MetricType::Gauge);
      reachable.metric.push_back(Gauge(replication->reachable ? 1 : 0));
      out->push_back(std::move(reachable));
      MetricFamily applied =
          Family("shapeid_replication_changes_applied_total",
                 "Changes made through other replicas and applied here.", MetricType::Counter);
      applied.metric.push_back(Counter(static_cast<double>(replication->changes_applied)));
      out->push_back(std::move(applied));
      MetricFamily age = Family(
          "shapeid_replication_sync_age_seconds",
          "Time since this replica last read the shared store's change log: how stale it may "
          "be. Stays below --store_refresh_ms while healthy.",
          MetricType::Gauge);
      age.metric.push_back(Gauge(absl::ToDoubleSeconds(replication->since_last_sync)));
      out->push_back(std::move(age));
    }
  }
  if (const absl::StatusOr<ProcessStats> process = ReadProcessStats(); process.ok()) {
    const auto add = [&](const char* name, const char* help, MetricType type, double value) {
      MetricFamily family = Family(name, help, type);
      family.metric.push_back(type == MetricType::Counter ? Counter(value) : Gauge(value));
      out->push_back(std::move(family));
    };
    add("process_cpu_seconds_total", "User and system CPU time spent, in seconds.",
        MetricType::Counter, process->cpu_seconds);
    add("process_resident_memory_bytes", "Resident memory size, in bytes.", MetricType::Gauge,
        static_cast<double>(process->resident_bytes));
    add("process_virtual_memory_bytes", "Virtual memory size, in bytes.", MetricType::Gauge,
        static_cast<double>(process->virtual_bytes));
    add("process_open_fds", "Open file descriptors.", MetricType::Gauge,
        static_cast<double>(process->open_fds));
    add("process_max_fds", "The limit of open file descriptors.", MetricType::Gauge,
        static_cast<double>(process->max_fds));
    add("process_threads", "Threads of the process.", MetricType::Gauge,
        static_cast<double>(process->threads));
    add("process_start_time_seconds", "Start time of the process since the Unix epoch.",
        MetricType::Gauge, process->start_time_seconds);
  }
}

std::vector<MethodSummary> ServerMetrics::MethodSummaries() const {
  std::vector<std::string> methods;
  {
    std::lock_guard<std::mutex> lock(mu_);
    methods = methods_seen_;
  }
  std::vector<MethodSummary> summaries;
  for (const std::string& method : methods) {
    MethodSummary summary;
    summary.method = method;
    summaries.push_back(std::move(summary));
  }
  const auto find = [&](const std::string& method) -> MethodSummary* {
    for (MethodSummary& summary : summaries) {
      if (summary.method == method) return &summary;
    }
    return nullptr;
  };
  for (const MetricFamily& family : requests_.Collect()) {
    for (const ClientMetric& metric : family.metric) {
      MethodSummary* summary = find(LabelValue(metric, "method"));
      if (summary == nullptr) continue;
      const auto calls = static_cast<uint64_t>(metric.counter.value);
      summary->calls += calls;
      if (LabelValue(metric, "code") != "OK") summary->errors += calls;
    }
  }
  // p50 and p99 of each method's series of `histograms` into `p50` / `p99` of its summary.
  const auto quantiles = [&](prometheus::Family<prometheus::Histogram>& histograms,
                             std::optional<absl::Duration> MethodSummary::*p50,
                             std::optional<absl::Duration> MethodSummary::*p99) {
    for (const MetricFamily& family : histograms.Collect()) {
      for (const ClientMetric& metric : family.metric) {
        MethodSummary* summary = find(LabelValue(metric, "method"));
        if (summary == nullptr) continue;
        std::vector<double> bounds;
        std::vector<uint64_t> cumulative;
        for (const ClientMetric::Bucket& bucket : metric.histogram.bucket) {
          bounds.push_back(bucket.upper_bound);
          cumulative.push_back(bucket.cumulative_count);
        }
        if (const auto q = HistogramQuantile(0.5, bounds, cumulative)) {
          summary->*p50 = absl::Seconds(*q);
        }
        if (const auto q = HistogramQuantile(0.99, bounds, cumulative)) {
          summary->*p99 = absl::Seconds(*q);
        }
      }
    }
  };
  quantiles(request_duration_, &MethodSummary::p50, &MethodSummary::p99);
  quantiles(request_wait_, &MethodSummary::wait_p50, &MethodSummary::wait_p99);
  return summaries;
}

uint64_t ServerMetrics::points_received() const {
  double total = 0;
  for (const MetricFamily& family : points_.Collect()) {
    for (const ClientMetric& metric : family.metric) total += metric.counter.value;
  }
  return static_cast<uint64_t>(total);
}

}  // namespace shapeid
