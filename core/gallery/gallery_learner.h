#ifndef SHAPEID_CORE_GALLERY_GALLERY_LEARNER_H_
#define SHAPEID_CORE_GALLERY_GALLERY_LEARNER_H_

// Fits every gallery of a registry its trained head (gallery_head.h) in the background, one
// gallery at a time, off the request path: Train stays instant (kNN over the stored samples),
// and once a gallery has been quiet for `settle` its head is fitted over its samples and
// views and published with Gallery::SetHead, so Classify answers with the head and the kNN
// vote together from then on. A change of the samples makes the head stale; it keeps
// answering while its labels are the gallery's, and is refitted once the gallery settles
// again. Each head is also handed to the store (GalleryStore::SaveHead), which gives it back
// at the next start for the same samples, so a restart need not fit it again.
//
// The fitting thread runs at the lowest CPU priority (nice 19): on a busy machine requests
// come first, and a fit only uses what they leave. A fit stops, publishing nothing, when the
// learner stops, when the gallery is deleted, or when its memory cannot be reserved (it is
// tried again later). Heads are derived state, deterministic for one gallery's samples: a
// store that keeps none (PostgreSQL today) makes a restarted server or a replica fit the same
// head again.

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "absl/status/statusor.h"
#include "absl/time/time.h"
#include "core/gallery/gallery_head.h"

namespace shapeid {

class GalleryRegistry;

struct GalleryLearnerOptions {
  HeadOptions head;
  // A gallery is fitted once its last change is this old (a training stream of many batches
  // is fitted once, after it).
  absl::Duration settle = absl::Seconds(2);
  // How often the registry is looked over for galleries to fit.
  absl::Duration poll = absl::Milliseconds(500);
  // Lower the fitting thread's CPU priority to nice 19 (off in tests that time a fit).
  bool low_priority = true;
  // Holds `bytes` of memory for a fit's working copy of the vectors while the fit runs, or
  // says why not (the fit is then tried later); null: nothing is counted. The returned
  // object releases the memory when destroyed.
  std::function<absl::StatusOr<std::shared_ptr<void>>(int64_t bytes)> reserve;
  // Called on the fitting thread after each head is published (a log line, say); may be null.
  std::function<void(const std::string& gallery, const GalleryHead& head)> on_fitted;
};

class GalleryLearner {
 public:
  // Starts the fitting thread. `registry` must outlive the learner.
  GalleryLearner(GalleryLearnerOptions options, GalleryRegistry* registry);
  // Stop(), then gone.
  ~GalleryLearner();

  // Stops the thread: a fit in progress is abandoned within one mini-batch. Idempotent; the
  // counters stay readable.
  void Stop();

  GalleryLearner(const GalleryLearner&) = delete;
  GalleryLearner& operator=(const GalleryLearner&) = delete;

  // Wakes the thread to look over the galleries now (after a commit, say), rather than at
  // its next poll.
  void Nudge();

  // The gallery being fitted now, or empty.
  std::string fitting() const;
  // Fits finished (published) and failed (not counted: abandoned ones) since start.
  int64_t fits() const { return fits_; }
  int64_t failures() const { return failures_; }

 private:
  void Run();
  void Fit(const std::shared_ptr<class Gallery>& gallery);

  const GalleryLearnerOptions options_;
  GalleryRegistry* const registry_;
  std::atomic<bool> stop_{false};
  std::atomic<int64_t> fits_{0};
  std::atomic<int64_t> failures_{0};
  mutable std::mutex mu_;
  std::condition_variable wake_;
  bool nudged_ = false;
  std::string fitting_;
  std::thread thread_;
};

}  // namespace shapeid

#endif  // SHAPEID_CORE_GALLERY_GALLERY_LEARNER_H_
