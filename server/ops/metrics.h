#ifndef SHAPEID_SERVER_OPS_METRICS_H_
#define SHAPEID_SERVER_OPS_METRICS_H_

// The server's Prometheus metrics (docs/operations.md lists them): events are counted as they
// happen (calls, points, descriptor and search times, store writes); state is read when
// Prometheus scrapes (galleries and their samples, calls in flight, serving, replication,
// process). gRPC-free: the service reports each call through RecordCall.
//
// Label cardinality is bounded, so that no client can grow the server's memory or a
// Prometheus' series count by naming galleries: the `gallery` label is
//   ""          for calls that name no gallery (ListGalleries, Describe by spec...);
//   the name    for a gallery the server holds when the call ends (or that the call just
//               deleted), for the first `max_gallery_labels` such names since start (kept
//               until the server stops, also if the gallery is deleted);
//   "_other"    for every gallery after those (shapeid_gallery_labels_folded counts them);
//   "_unknown"  for a name the server does not hold (a failed call: NOT_FOUND, a typo...).
// Gallery names start with a letter or digit, so these never collide with one. `method` and
// `code` come from fixed lists; `descriptor` is a registered kind.

#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "absl/base/thread_annotations.h"
#include "absl/container/flat_hash_map.h"
#include "absl/container/flat_hash_set.h"
#include "absl/status/status.h"
#include "absl/strings/string_view.h"
#include "absl/time/time.h"
#include "prometheus/collectable.h"
#include "prometheus/counter.h"
#include "prometheus/family.h"
#include "prometheus/gauge.h"
#include "prometheus/histogram.h"
#include "prometheus/registry.h"

namespace shapeid {

class GalleryRegistry;

struct MetricsOptions {
  // HOST:PORT of the plaintext /metrics endpoint (server/server.cc starts it); empty: none.
  // The metrics are kept either way, for GetServerStats.
  std::string listen;
  // Galleries that get a label of their own; later ones fold into "_other".
  int max_gallery_labels = 50;
};

// What a replica over a shared store reports (PostgreSQL; absent for a private store).
struct ReplicationState {
  bool reachable = true;
  int64_t changes_applied = 0;
  absl::Duration since_last_sync;
};

// One lane of the work scheduler (server/runtime/work_scheduler.h) at scrape time.
struct WorkLaneState {
  std::string lane;  // "cheap", "heavy", "store"
  int workers = 0;
  int running = 0;
  int64_t queued = 0;
  double queued_seconds = 0;  // the queued pieces' estimated CPU time
};

// The scheduler's callers' backlogs at scrape time (WorkScheduler::BacklogStats).
struct WorkBacklogState {
  double backlog_seconds = 0;  // summed over callers; equals the lanes' queued_seconds summed
  int64_t callers = 0;
};

// The memory budget (server/runtime/memory_budget.h) at scrape time.
struct MemoryBudgetState {
  uint64_t budget_bytes = 0;  // 0: unbounded
  uint64_t held_bytes = 0;
  uint64_t peak_bytes = 0;
};

// Read at scrape time; each may be empty. Called from the scraping thread.
// The background fitting of galleries' trained heads (core/gallery/gallery_learner.h).
struct LearnerState {
  int64_t fits = 0;
  int64_t failures = 0;
  bool fitting = false;
};

struct LiveSources {
  std::function<int64_t()> calls_in_flight;
  std::function<bool()> serving;
  std::function<std::optional<ReplicationState>()> replication;
  std::function<std::vector<WorkLaneState>()> work;
  std::function<WorkBacklogState()> backlog;
  std::function<MemoryBudgetState()> memory;
  std::function<std::optional<LearnerState>()> learner;  // nullopt: the server does not learn
};

// One call, as the service saw it when it answered.
struct CallMetrics {
  absl::string_view method;   // "ClassifyCloud"
  absl::string_view gallery;  // empty when the call names none
  absl::StatusCode code = absl::StatusCode::kOk;
  absl::Duration elapsed;  // arrival to answer
  int64_t points = 0;      // points received in its clouds
  int64_t samples_trained = 0;
  absl::Duration waited;  // its work's time in the scheduler's queues
};

// Calls of one method since start, for GetServerStats.
struct MethodSummary {
  std::string method;
  uint64_t calls = 0;
  uint64_t errors = 0;
  std::optional<absl::Duration> p50, p99;  // estimated from the histogram's buckets
  // Of the time its work waited for a worker (unset: no call of the method queued work).
  std::optional<absl::Duration> wait_p50, wait_p99;
};

// Thread-safe. Also a prometheus::Collectable: register it with an Exposer.
class ServerMetrics final : public prometheus::Collectable {
 public:
  explicit ServerMetrics(MetricsOptions options = {});

  // Where scrape-time state comes from. Call before the endpoint starts. The registry is held
  // weakly: its store may hold these metrics (server/ops/observed_gallery_store.h).
  void SetSources(std::weak_ptr<const GalleryRegistry> galleries, LiveSources live);

  void RecordCall(const CallMetrics& call);
  // One cloud described by a descriptor of kind `descriptor` ("rphsd").
  void ObserveDescribe(absl::string_view descriptor, absl::Duration elapsed);
  void ObserveSearch(bool approximate, absl::Duration elapsed);
  // One piece of work waited `waited` in the scheduler's `lane` ("cheap", "heavy", "store").
  void ObserveWait(absl::string_view lane, absl::Duration waited);
  // One write to the gallery store: `operation` is save, append, remove or delete.
  void ObserveStoreWrite(absl::string_view operation, absl::Duration elapsed, bool ok);

  std::vector<prometheus::MetricFamily> Collect() const override;

  // Methods called so far, in the order of first call; and every point received.
  std::vector<MethodSummary> MethodSummaries() const;
  uint64_t points_received() const;
  const MetricsOptions& options() const { return options_; }

  // The `gallery` label a call naming `name` gets (see the header comment); `held`: the
  // server holds it, or the call created or deleted it.
  std::string GalleryLabel(absl::string_view name, bool held) const;

 private:
  void CollectLive(std::vector<prometheus::MetricFamily>* out) const;

  // Series by their label values, so that a call finds its series with one hash lookup.
  template <typename T>
  using SeriesCache = absl::flat_hash_map<std::string, T*>;
  template <typename T, typename... Args>
  T& Series(SeriesCache<T>& cache, prometheus::Family<T>& family, const prometheus::Labels& labels,
            Args&&... args);

  const MetricsOptions options_;
  const std::shared_ptr<prometheus::Registry> registry_;
  prometheus::Family<prometheus::Counter>& requests_;
  prometheus::Family<prometheus::Histogram>& request_duration_;
  prometheus::Family<prometheus::Histogram>& request_wait_;
  prometheus::Family<prometheus::Histogram>& work_wait_;
  prometheus::Family<prometheus::Counter>& points_;
  prometheus::Family<prometheus::Counter>& samples_trained_;
  prometheus::Family<prometheus::Histogram>& describe_duration_;
  prometheus::Family<prometheus::Histogram>& search_duration_;
  prometheus::Family<prometheus::Histogram>& store_write_duration_;
  prometheus::Family<prometheus::Counter>& store_write_failures_;

  // std::mutex, not absl::Mutex: Debian's Abseil is not built for TSan, which then sees
  // absl::Mutex's critical sections as races (core/gallery/gallery.h says the same).
  mutable std::mutex mu_;
  // Names given a label of their own (at most options_.max_gallery_labels); assigned on
  // first sight, by a call or a scrape, and kept until the server stops.
  mutable absl::flat_hash_set<std::string> labeled_galleries_ ABSL_GUARDED_BY(mu_);
  SeriesCache<prometheus::Counter> requests_cache_ ABSL_GUARDED_BY(mu_);
  SeriesCache<prometheus::Histogram> request_duration_cache_ ABSL_GUARDED_BY(mu_);
  SeriesCache<prometheus::Histogram> request_wait_cache_ ABSL_GUARDED_BY(mu_);
  SeriesCache<prometheus::Histogram> work_wait_cache_ ABSL_GUARDED_BY(mu_);
  SeriesCache<prometheus::Counter> points_cache_ ABSL_GUARDED_BY(mu_);
  SeriesCache<prometheus::Counter> samples_trained_cache_ ABSL_GUARDED_BY(mu_);
  SeriesCache<prometheus::Histogram> describe_cache_ ABSL_GUARDED_BY(mu_);
  SeriesCache<prometheus::Histogram> search_cache_ ABSL_GUARDED_BY(mu_);
  SeriesCache<prometheus::Histogram> store_write_cache_ ABSL_GUARDED_BY(mu_);
  SeriesCache<prometheus::Counter> store_failures_cache_ ABSL_GUARDED_BY(mu_);
  std::vector<std::string> methods_seen_ ABSL_GUARDED_BY(mu_);
  std::weak_ptr<const GalleryRegistry> galleries_ ABSL_GUARDED_BY(mu_);
  LiveSources live_ ABSL_GUARDED_BY(mu_);
};

// The value below which a fraction `q` of the observations of a cumulative histogram fall,
// interpolated linearly within the bucket as Prometheus' histogram_quantile does. `bounds`
// are the buckets' upper bounds, the last +Inf; `cumulative` the counts. nullopt when empty.
std::optional<double> HistogramQuantile(double q, const std::vector<double>& bounds,
                                        const std::vector<uint64_t>& cumulative);

}  // namespace shapeid

#endif  // SHAPEID_SERVER_OPS_METRICS_H_
