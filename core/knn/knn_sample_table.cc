#include "core/knn/knn_sample_table.h"

#include "core/heap_chunk.h"

namespace shapeid {
namespace knn_internal {

std::vector<std::pair<std::string, int64_t>> SampleTable::LabelCounts() const {
  std::vector<std::pair<std::string, int64_t>> counts;
  counts.reserve(static_cast<std::size_t>(labels_.size()));
  for (int64_t l = 0; l < labels_.size(); ++l) counts.emplace_back(labels_[l], label_counts_[l]);
  return counts;
}

std::vector<uint64_t> SampleTable::IdsWithLabel(absl::string_view label) const {
  std::vector<uint64_t> ids;
  const auto* entry = label_index_.Find(std::string(label));
  if (entry == nullptr) return ids;
  const int32_t l = entry->second;
  ids.reserve(static_cast<std::size_t>(label_counts_[l]));
  for (int64_t s = 0; s < size(); ++s) {
    if (label_of_sample_[s] == l) ids.push_back(ids_[s]);
  }
  return ids;
}

int64_t SampleTable::memory_bytes() const {
  return ids_.memory_bytes() + label_of_sample_.memory_bytes() + id_set_.memory_bytes() +
         first_row_.memory_bytes() + sample_of_row_.memory_bytes() + labels_.memory_bytes() +
         label_counts_.memory_bytes() + label_index_.memory_bytes() + label_text_bytes_;
}

void SampleTable::Append(uint64_t id, absl::string_view label, int64_t rows) {
  const int64_t sample = size();
  if (rows > 1 && first_row_.empty()) {
    // The first sample with several rows: rows and samples part ways from here on.
    for (int64_t s = 0; s <= sample; ++s) first_row_.PushBack(s);
    for (int64_t row = 0; row < num_rows_; ++row) sample_of_row_.PushBack(row);
  }
  if (!first_row_.empty()) {
    for (int64_t r = 0; r < rows; ++r) sample_of_row_.PushBack(sample);
    first_row_.PushBack(num_rows_ + rows);
  }
  num_rows_ += rows;

  int32_t l;
  if (const auto* entry = label_index_.Find(std::string(label)); entry != nullptr) {
    l = entry->second;
    label_counts_.Set(l, label_counts_[l] + 1);
  } else {
    l = static_cast<int32_t>(labels_.size());
    labels_.PushBack(std::string(label));
    label_counts_.PushBack(1);
    label_index_.Insert({std::string(label), l});
    label_text_bytes_ += 2 * static_cast<int64_t>(StringHeapBytes(labels_[l]));
  }
  ids_.PushBack(id);
  label_of_sample_.PushBack(l);
  id_set_.Insert(id);
}

}  // namespace knn_internal
}  // namespace shapeid
