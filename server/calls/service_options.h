#ifndef SHAPEID_SERVER_CALLS_SERVICE_OPTIONS_H_
#define SHAPEID_SERVER_CALLS_SERVICE_OPTIONS_H_

#include <cstddef>
#include <string>

#include "absl/time/time.h"
#include "core/descriptor_registry.h"
#include "server/runtime/work_scheduler.h"

namespace shapeid {

// What the ShapeId service accepts. Defaults suit a shared lab server; main.cc maps flags
// (and SHAPEID_* environment variables) onto these.
// The largest cloud any RPC accepts is the registry's GalleryLimits::max_points_per_cloud.
struct ServiceOptions {
  // Samples one Train stream may carry. A stream holds its described samples until it ends
  // (10,000 x 240 floats is 9.6 MB, times 1 + views with augmentation), and commits them in
  // one transaction; larger batches belong in several streams. 0: no limit.
  int64_t max_samples_per_train = 10'000;
  // Streams (Describe, Train, Classify, ExportGallery, ImportGallery) one client may have open
  // at once; a client is the peer's IP address (every process of one host counts together).
  // Each open stream may hold a cloud being assembled, so this bounds what one host can pin.
  // 64 is far above what the CLI opens (--jobs, default 4). 0: no limit.
  int max_streams_per_client = 64;
  // Longest a stream may run: one whose client asked for a later deadline, or none, is ended
  // DEADLINE_EXCEEDED when this has passed, so an idle or endless stream cannot hold its slot
  // and memory for ever. Unary calls are bounded by the message size instead. Zero: no
  // ceiling. Ten minutes fits an export or import of a 10^6-sample gallery over a slow link.
  absl::Duration max_call = absl::Minutes(10);
  // Spec used by Describe when neither a spec nor a gallery is given.
  std::string default_descriptor_spec = kDefaultDescriptorSpec;
  // The memory calls may hold beyond the galleries: clouds in transit and describing's
  // working memory (server/runtime/memory_budget.h). 0: DefaultMemoryBudgetBytes(), half of what
  // the process may use. A call that would pass it is refused RESOURCE_EXHAUSTED, or its work waits
  // for memory that other calls will give back.
  size_t memory_budget_bytes = 0;
  // The part of the budget one caller (an API key, else a client host) may hold.
  double memory_caller_share = 0.5;
  // The largest answer the service sends (a ListSamples page, a Classify with many
  // neighbors, a scene with its indices): pages are cut to fit it, and a call whose answer
  // would pass it fails RESOURCE_EXHAUSTED saying what to ask for instead. The project's
  // clients accept answers up to kClientMaxReceiveBytes, so they can always read one.
  size_t max_answer_bytes = 32 << 20;
  // The workers describing, searching and store writes run on (server/runtime/work_scheduler.h).
  WorkSchedulerOptions work;
};

}  // namespace shapeid

#endif  // SHAPEID_SERVER_CALLS_SERVICE_OPTIONS_H_
