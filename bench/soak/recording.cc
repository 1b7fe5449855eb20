#include "bench/soak/recording.h"

#include <utility>

#include "absl/strings/str_format.h"

namespace shapeid::soak {

const char* const kKindNames[kNumKinds] = {
    "train",          "classify_cloud", "classify_stream", "describe_cloud", "describe_stream",
    "create_gallery", "get_gallery",    "list_galleries",  "remove_samples", "delete_gallery",
    "export_gallery", "import_gallery", "recognize_scene"};

void Recorder::Record(int client, Kind kind, int64_t ns, bool ok) {
  Slot& slot = slots_[static_cast<size_t>(client)];
  std::lock_guard<std::mutex> lock(slot.mu);
  if (ok) {
    slot.tally.ns[kind].push_back(ns);
  } else {
    ++slot.tally.errors;
  }
}

Tally Recorder::Take() {
  Tally all;
  for (Slot& slot : slots_) {
    Tally taken;
    {
      std::lock_guard<std::mutex> lock(slot.mu);
      std::swap(taken, slot.tally);
    }
    for (int k = 0; k < kNumKinds; ++k) {
      all.ns[k].insert(all.ns[k].end(), taken.ns[k].begin(), taken.ns[k].end());
    }
    all.errors += taken.errors;
  }
  return all;
}

void ErrorLog::Add(double at_s, int client, Kind kind, const absl::Status& status) {
  std::lock_guard<std::mutex> lock(mu_);
  ++count_;
  if (first_.size() < 10) {
    first_.push_back(absl::StrFormat("%8.2f s  client %2d  %-15s %s", at_s, client,
                                     kKindNames[kind], status.ToString()));
  }
}

int64_t ErrorLog::count() const {
  std::lock_guard<std::mutex> lock(mu_);
  return count_;
}

std::vector<std::string> ErrorLog::first() const {
  std::lock_guard<std::mutex> lock(mu_);
  return first_;
}

}  // namespace shapeid::soak
