#include "server/ops/server_stats.h"

#include <algorithm>
#include <memory>
#include <utility>
#include <vector>

#include "absl/time/clock.h"
#include "core/gallery/gallery.h"
#include "core/version.h"
#include "server/ops/process_stats.h"
#include "server/wire/proto_convert.h"

namespace shapeid {

void BuildServerStats(const ServerStatsSources& sources, v1::ServerStats* out) {
  out->set_version(kShapeidVersion);
  ToProto(absl::Now() - sources.description->started, out->mutable_uptime());
  out->set_state(CallTracker::StateName(sources.tracker->state()));
  out->set_calls_in_flight(std::max<int64_t>(0, sources.tracker->in_flight() - 1));
  if (const ServerMetrics* metrics = sources.metrics) {
    for (const MethodSummary& summary : metrics->MethodSummaries()) {
      v1::MethodStats* method = out->add_methods();
      method->set_method(summary.method);
      method->set_calls(summary.calls);
      method->set_errors(summary.errors);
      if (summary.p50) ToProto(*summary.p50, method->mutable_latency_p50());
      if (summary.p99) ToProto(*summary.p99, method->mutable_latency_p99());
      if (summary.wait_p50) ToProto(*summary.wait_p50, method->mutable_wait_p50());
      if (summary.wait_p99) ToProto(*summary.wait_p99, method->mutable_wait_p99());
    }
    out->set_points_received(metrics->points_received());
  }
  std::vector<v1::GalleryStats> galleries;
  uint64_t samples = 0;
  for (const std::shared_ptr<Gallery>& gallery : sources.registry->All()) {
    const std::shared_ptr<const GallerySnapshot> snapshot = gallery->Snapshot();
    v1::GalleryStats& stats = galleries.emplace_back();
    stats.set_name(gallery->name());
    stats.set_samples(static_cast<uint64_t>(snapshot->num_samples()));
    stats.set_version(snapshot->version());
    samples += stats.samples();
  }
  std::stable_sort(galleries.begin(), galleries.end(),
                   [](const v1::GalleryStats& a, const v1::GalleryStats& b) {
                     return a.samples() > b.samples();
                   });
  for (v1::GalleryStats& stats : galleries) *out->add_galleries() = std::move(stats);
  out->set_samples(samples);
  if (const absl::StatusOr<ProcessStats> process = ReadProcessStats(); process.ok()) {
    out->set_resident_memory_bytes(static_cast<uint64_t>(process->resident_bytes));
  }
  out->set_store(sources.description->store.empty() ? "memory" : sources.description->store);
  if (sources.logger != nullptr) {
    out->set_log_level(std::string(LogLevelName(sources.logger->level())));
  }
  out->set_metrics_address(sources.description->metrics_address);
  for (const WorkLane lane : {WorkLane::kCheap, WorkLane::kHeavy, WorkLane::kStore}) {
    const WorkScheduler::LaneStats stats = sources.scheduler->stats(lane);
    v1::WorkLaneStats* work = out->add_work();
    work->set_lane(WorkLaneName(lane));
    work->set_workers(static_cast<uint32_t>(stats.workers));
    work->set_running(static_cast<uint32_t>(stats.running));
    work->set_queued(static_cast<uint64_t>(stats.queued));
    ToProto(stats.queued_cost, work->mutable_queued_work());
    work->set_queued_callers(static_cast<uint32_t>(stats.queued_callers));
  }
  const WorkScheduler::BacklogStats backlog = sources.scheduler->backlog();
  ToProto(backlog.total, out->mutable_caller_backlog());
  out->set_callers_with_backlog(static_cast<uint32_t>(backlog.callers));
  out->set_memory_budget_bytes(sources.budget->total_bytes());
  out->set_memory_held_bytes(sources.budget->held_bytes());
  out->set_memory_held_peak_bytes(sources.budget->peak_bytes());
}

}  // namespace shapeid
