#ifndef SHAPEID_CORE_KNN_KNN_SAMPLE_TABLE_H_
#define SHAPEID_CORE_KNN_KNN_SAMPLE_TABLE_H_

// Internal to core/knn: the id map of a gallery (Faiss's IndexIDMap): each sample's id,
// label and rows, and the distinct labels with their counts.

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "absl/container/flat_hash_map.h"
#include "absl/container/flat_hash_set.h"
#include "absl/strings/string_view.h"
#include "core/knn/knn_shared_chunks.h"

namespace shapeid {
namespace knn_internal {

// Samples 0 .. size() - 1 in insertion order, each with an id (unique), a label and one or
// more consecutive rows of the feature storage. Every part is held in shared chunks or shards
// (knn_shared_chunks.h), so a copy costs O(size() / 4096 + 2,048) pointer copies and Append
// copies O(chunk) entries, never O(size()).
class SampleTable {
 public:
  int64_t size() const { return ids_.size(); }
  int64_t num_rows() const { return num_rows_; }
  bool Contains(uint64_t id) const { return id_set_.contains(id); }
  uint64_t IdAt(int64_t sample) const { return ids_[sample]; }
  int32_t LabelIndexAt(int64_t sample) const { return label_of_sample_[sample]; }
  const std::string& LabelAt(int64_t sample) const { return labels_[label_of_sample_[sample]]; }

  // Sample s holds rows [FirstRow(s), FirstRow(s + 1)); s in [0, size()].
  int64_t FirstRow(int64_t sample) const {
    return first_row_.empty() ? sample : first_row_[sample];
  }
  int64_t SampleOfRow(int64_t row) const {
    return sample_of_row_.empty() ? row : sample_of_row_[row];
  }
  // The sample of every row, for TopK's groups; nullptr while every sample has one row (row
  // and sample numbers coincide, which saves 16 bytes per sample).
  const SharedChunks<int64_t>* sample_of_row() const {
    return first_row_.empty() ? nullptr : &sample_of_row_;
  }

  int num_labels() const { return static_cast<int>(labels_.size()); }
  // The heap of every part (ids, labels, rows, both hash tables, the labels' text). O(1).
  int64_t memory_bytes() const;
  // Samples per distinct label, labels in order of first appearance. O(num_labels()).
  std::vector<std::pair<std::string, int64_t>> LabelCounts() const;
  // The ids of the samples labeled `label`, in insertion order. O(size()).
  std::vector<uint64_t> IdsWithLabel(absl::string_view label) const;

  // Appends a sample of `rows` rows (>= 1) after the existing ones. The caller has checked
  // that the id is absent and the label non-empty.
  void Append(uint64_t id, absl::string_view label, int64_t rows);

 private:
  SharedChunks<uint64_t> ids_;
  SharedChunks<int32_t> label_of_sample_;  // index into labels_
  SharedHashTable<absl::flat_hash_set<uint64_t>> id_set_;
  int64_t num_rows_ = 0;
  // size() + 1 entries and one per row, or both empty while every sample has one row.
  SharedChunks<int64_t> first_row_;
  SharedChunks<int64_t> sample_of_row_;
  SharedChunks<std::string> labels_;  // distinct, in order of first appearance
  SharedChunks<int64_t> label_counts_;
  SharedHashTable<absl::flat_hash_map<std::string, int32_t>> label_index_;
  int64_t label_text_bytes_ = 0;  // the heap of the distinct labels' strings, in both places
};

}  // namespace knn_internal
}  // namespace shapeid

#endif  // SHAPEID_CORE_KNN_KNN_SAMPLE_TABLE_H_
