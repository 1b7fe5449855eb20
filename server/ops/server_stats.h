#ifndef SHAPEID_SERVER_OPS_SERVER_STATS_H_
#define SHAPEID_SERVER_OPS_SERVER_STATS_H_

// GetServerStats' answer, gathered from the parts of the server that know each figure.

#include <string>

#include "absl/time/time.h"
#include "core/gallery/gallery_registry.h"
#include "server/ops/logger.h"
#include "server/ops/metrics.h"
#include "server/runtime/call_gate.h"
#include "server/runtime/memory_budget.h"
#include "server/runtime/work_scheduler.h"
#include "shapeid/v1/shapeid.pb.h"

namespace shapeid {

// What GetServerStats reports about the server around the service; set once, before serving.
struct ServerDescription {
  std::string store;            // "shapeid-data", "PostgreSQL db:5432/shapeid (shared)"
  std::string metrics_address;  // empty: no endpoint
  absl::Time started = absl::Now();
};

struct ServerStatsSources {
  const ServerDescription* description = nullptr;
  const CallTracker* tracker = nullptr;
  const GalleryRegistry* registry = nullptr;
  const WorkScheduler* scheduler = nullptr;
  const MemoryBudget* budget = nullptr;
  const ServerMetrics* metrics = nullptr;  // may be null
  const Logger* logger = nullptr;          // may be null
};

// Fills `out`. The call asking is in flight itself and is not counted.
void BuildServerStats(const ServerStatsSources& sources, v1::ServerStats* out);

}  // namespace shapeid

#endif  // SHAPEID_SERVER_OPS_SERVER_STATS_H_
