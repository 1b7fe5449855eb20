#include "core/knn/knn_ivf.h"

#include <algorithm>
#include <cmath>
#include <thread>
#include <utility>

#include "core/heap_chunk.h"
#include "core/knn/knn_kd_tree.h"
#include "core/parallel_ranges.h"

namespace shapeid {
namespace knn_internal {

namespace {

// Row-major vectors into blocked storage (zero-padded to whole blocks).
AlignedFloats ToBlocked(const std::vector<float>& rows, int64_t count, int dim) {
  AlignedFloats blocked(
      static_cast<std::size_t>((count + kBlockLanes - 1) / kBlockLanes) * BlockFloats(dim), 0.0f);
  for (int64_t r = 0; r < count; ++r) {
    for (int j = 0; j < dim; ++j) {
      blocked[FeatureOffset(r, dim, j)] = rows[static_cast<std::size_t>(r * dim + j)];
    }
  }
  return blocked;
}

}  // namespace

std::shared_ptr<InvertedLists> InvertedLists::WithSameCells() const {
  std::shared_ptr<InvertedLists> ivf(new InvertedLists());
  ivf->dim_ = dim_;
  ivf->num_centroids_ = num_centroids_;
  ivf->centroids_ = centroids_;
  return ivf;
}

BlockedView InvertedLists::List(int list) const {
  const std::size_t l = static_cast<std::size_t>(list);
  return BlockedView{
      data_.data() + static_cast<std::size_t>(list_start_[l] / kBlockLanes) * BlockFloats(dim_),
      list_size_[l], dim_, 0, row_ids_.data() + list_start_[l]};
}

void InvertedLists::Assign(SimdLevel level, const float* vectors, int64_t count, const float* scale,
                           int threads, int32_t* cell) const {
  const BlockedView centroids = Centroids();
  ParallelRanges(count, threads, /*min_per_part=*/1024, [&](int, int64_t begin, int64_t end) {
    for (int64_t i = begin; i < end; ++i) {
      TopK nearest(1);
      ScanBlocks(level, centroids, vectors + i * dim_, 1, scale, /*abandon=*/true, &nearest);
      cell[i] = static_cast<int32_t>(nearest.TakeSorted().front().row);
    }
  });
}

void InvertedLists::Fill(const FeatureStorage& gallery, int64_t rows,
                         absl::Span<const int32_t> cell_of_row) {
  const std::size_t lists = static_cast<std::size_t>(num_centroids_);
  indexed_rows_ = rows;
  cell_of_row_.assign(cell_of_row.begin(), cell_of_row.end());
  list_size_.assign(lists, 0);
  for (int32_t c : cell_of_row_) ++list_size_[static_cast<std::size_t>(c)];
  // Each list starts on a block boundary, so it scans as a gallery of its own.
  list_start_.assign(lists, 0);
  int64_t stored = 0;
  for (std::size_t l = 0; l < lists; ++l) {
    list_start_[l] = stored;
    stored += (list_size_[l] + kBlockLanes - 1) / kBlockLanes * kBlockLanes;
  }
  data_.assign(static_cast<std::size_t>(stored / kBlockLanes) * BlockFloats(dim_), 0.0f);
  row_ids_.assign(static_cast<std::size_t>(stored), -1);
  std::vector<int64_t> next = list_start_;
  for (int64_t row = 0; row < rows; ++row) {
    const int64_t dst =
        next[static_cast<std::size_t>(cell_of_row_[static_cast<std::size_t>(row)])]++;
    row_ids_[static_cast<std::size_t>(dst)] = row;
    for (int j = 0; j < dim_; ++j) {
      data_[FeatureOffset(dst, dim_, j)] = gallery.At(row, j);
    }
  }
}

int64_t InvertedLists::memory_bytes() const {
  return static_cast<int64_t>(
      SharedHeapBytes<InvertedLists>() +
      (centroids_.capacity() + data_.capacity()) * sizeof(float) +
      (row_ids_.capacity() + list_start_.capacity() + list_size_.capacity()) * sizeof(int64_t) +
      cell_of_row_.capacity() * sizeof(int32_t));
}

std::shared_ptr<const InvertedLists> InvertedLists::Build(SimdLevel level,
                                                          const FeatureStorage& gallery,
                                                          int64_t rows, const float* scale,
                                                          int lists, int threads,
                                                          const std::atomic<bool>* cancel) {
  auto cancelled = [cancel] {
    return cancel != nullptr && cancel->load(std::memory_order_relaxed);
  };
  std::shared_ptr<InvertedLists> ivf(new InvertedLists());
  const int d = gallery.dim();
  const std::size_t dim = static_cast<std::size_t>(d);
  const int64_t k = std::clamp<int64_t>(std::min<int64_t>(lists, rows / kMinRowsPerList), 1, rows);
  ivf->dim_ = d;
  ivf->num_centroids_ = k;

  // Training rows spread evenly over the gallery: galleries are often trained class by
  // class, so a prefix would miss whole classes. Deterministic, unlike a random sample.
  const int64_t m = std::min(rows, k * kTrainRowsPerList);
  std::vector<float> train(static_cast<std::size_t>(m) * dim);
  for (int64_t i = 0; i < m; ++i)
    gallery.CopyRow(i * rows / m, &train[static_cast<std::size_t>(i) * dim]);

  // Lloyd's k-means from k training rows spread evenly; cells that empty are re-seeded by
  // splitting the largest one (as Faiss does), so every list keeps a centroid.
  std::vector<float> centroids(static_cast<std::size_t>(k) * dim);
  for (int64_t c = 0; c < k; ++c) {
    std::copy_n(&train[static_cast<std::size_t>(c * m / k) * dim], dim,
                &centroids[static_cast<std::size_t>(c) * dim]);
  }
  std::vector<int32_t> cell(static_cast<std::size_t>(m));
  std::vector<double> sums(centroids.size());
  std::vector<int64_t> counts(static_cast<std::size_t>(k));
  for (int iteration = 0; iteration < kIterations; ++iteration) {
    if (cancelled()) return nullptr;
    ivf->centroids_ = ToBlocked(centroids, k, d);
    ivf->Assign(level, train.data(), m, scale, threads, cell.data());
    std::fill(sums.begin(), sums.end(), 0.0);
    std::fill(counts.begin(), counts.end(), 0);
    for (int64_t i = 0; i < m; ++i) {
      const std::size_t c = static_cast<std::size_t>(cell[static_cast<std::size_t>(i)]);
      ++counts[c];
      for (std::size_t j = 0; j < dim; ++j)
        sums[c * dim + j] += train[static_cast<std::size_t>(i) * dim + j];
    }
    for (std::size_t c = 0; c < counts.size(); ++c) {
      if (counts[c] == 0) continue;
      for (std::size_t j = 0; j < dim; ++j) {
        centroids[c * dim + j] =
            static_cast<float>(sums[c * dim + j] / static_cast<double>(counts[c]));
      }
    }
    for (std::size_t c = 0; c < counts.size(); ++c) {
      if (counts[c] != 0) continue;
      const std::size_t big =
          static_cast<std::size_t>(std::max_element(counts.begin(), counts.end()) - counts.begin());
      if (counts[big] < 2) break;
      constexpr float kEpsilon = 1.0f / 1024.0f;
      for (std::size_t j = 0; j < dim; ++j) {
        const float x = centroids[big * dim + j];
        const float sign = j % 2 == 0 ? 1.0f : -1.0f;
        centroids[c * dim + j] = x * (1.0f + sign * kEpsilon);
        centroids[big * dim + j] = x * (1.0f - sign * kEpsilon);
      }
      counts[c] = counts[big] / 2;
      counts[big] -= counts[c];
    }
  }
  ivf->centroids_ = ToBlocked(centroids, k, d);

  // Every row to its cell, a chunk at a time: the gallery is blocked, Assign wants rows.
  std::vector<int32_t> cell_of_row(static_cast<std::size_t>(rows));
  constexpr int64_t kChunk = 16384;
  std::vector<float> chunk(static_cast<std::size_t>(std::min(rows, kChunk)) * dim);
  for (int64_t begin = 0; begin < rows; begin += kChunk) {
    if (cancelled()) return nullptr;
    const int64_t count = std::min(kChunk, rows - begin);
    for (int64_t i = 0; i < count; ++i)
      gallery.CopyRow(begin + i, &chunk[static_cast<std::size_t>(i) * dim]);
    ivf->Assign(level, chunk.data(), count, scale, threads,
                &cell_of_row[static_cast<std::size_t>(begin)]);
  }
  ivf->Fill(gallery, rows, cell_of_row);
  return ivf;
}

std::shared_ptr<const InvertedLists> InvertedLists::Extend(SimdLevel level,
                                                           const FeatureStorage& gallery,
                                                           int64_t rows, const float* scale,
                                                           int threads) const {
  std::shared_ptr<InvertedLists> ivf = WithSameCells();
  std::vector<int32_t> cell_of_row = cell_of_row_;
  cell_of_row.resize(static_cast<std::size_t>(rows));
  const int64_t added = rows - indexed_rows_;
  std::vector<float> vectors(static_cast<std::size_t>(added) * static_cast<std::size_t>(dim_));
  for (int64_t i = 0; i < added; ++i) {
    gallery.CopyRow(indexed_rows_ + i, &vectors[static_cast<std::size_t>(i * dim_)]);
  }
  ivf->Assign(level, vectors.data(), added, scale, threads,
              &cell_of_row[static_cast<std::size_t>(indexed_rows_)]);
  ivf->Fill(gallery, rows, cell_of_row);
  return ivf;
}

std::shared_ptr<const InvertedLists> InvertedLists::Renumber(
    const FeatureStorage& gallery, absl::Span<const int64_t> new_row_of_old) const {
  int64_t kept = 0;
  for (int64_t row = 0; row < indexed_rows_; ++row)
    kept += new_row_of_old[static_cast<std::size_t>(row)] >= 0;
  const int64_t rows = kept / kBlockLanes * kBlockLanes;
  if (rows == 0) return nullptr;
  std::shared_ptr<InvertedLists> ivf = WithSameCells();
  // The kept indexed rows keep their order, so they are exactly new rows [0, kept).
  std::vector<int32_t> cell_of_row(static_cast<std::size_t>(rows));
  for (int64_t row = 0; row < indexed_rows_; ++row) {
    const int64_t now = new_row_of_old[static_cast<std::size_t>(row)];
    if (now >= 0 && now < rows) {
      cell_of_row[static_cast<std::size_t>(now)] = cell_of_row_[static_cast<std::size_t>(row)];
    }
  }
  ivf->Fill(gallery, rows, cell_of_row);
  return ivf;
}

void InvertedLists::Search(SimdLevel level, const float* queries, int num_queries,
                           const float* scale, int probes, bool abandon, TopK* top) const {
  const int lists = num_lists();
  probes = std::clamp(probes, 1, lists);
  const std::size_t dim = static_cast<std::size_t>(dim_);
  // (list, query) pairs: the lists each query vector probes.
  std::vector<std::pair<int32_t, int>> picks;
  picks.reserve(static_cast<std::size_t>(num_queries) * static_cast<std::size_t>(probes));
  for (int q = 0; q < num_queries; ++q) {
    TopK nearest(probes);
    ScanBlocks(level, Centroids(), queries + static_cast<std::size_t>(q) * dim, 1, scale,
               /*abandon=*/true, &nearest);
    for (const Candidate& c : nearest.TakeSorted())
      picks.emplace_back(static_cast<int32_t>(c.row), q);
  }
  std::sort(picks.begin(), picks.end());
  // Each list once, with the query vectors that chose it side by side.
  std::vector<float> group;
  std::vector<int> group_ids;
  for (std::size_t i = 0; i < picks.size();) {
    const int32_t list = picks[i].first;
    group.clear();
    group_ids.clear();
    for (; i < picks.size() && picks[i].first == list; ++i) {
      const float* q = queries + static_cast<std::size_t>(picks[i].second) * dim;
      group.insert(group.end(), q, q + dim);
      group_ids.push_back(picks[i].second);
    }
    ScanBlocks(level, List(list), group.data(), static_cast<int>(group_ids.size()), scale, abandon,
               top, group_ids.data());
  }
}

ApproximateIndex::Step ApproximateIndex::Plan(const ApproximateOptions& options,
                                              FeatureScaling scaling,
                                              const FeatureStorage& gallery) const {
  // Lists hold whole blocks, so the exact tail starts on a block boundary.
  const int64_t whole_blocks = gallery.rows() / kBlockLanes * kBlockLanes;
  if (options.min_vectors == 0 || gallery.rows() < options.min_vectors ||
      gallery.dim() <= kKdTreeMaxDimension || whole_blocks == 0) {
    return lists_ != nullptr ? Step::kDrop : Step::kNothing;
  }
  if (lists_ == nullptr || options.lists != options_.lists || scaling != scaling_ ||
      whole_blocks >= 4 * trained_rows_) {
    return Step::kBuild;
  }
  if (whole_blocks - lists_->indexed_rows() > lists_->indexed_rows() / 16) return Step::kExtend;
  return Step::kNothing;
}

bool ApproximateIndex::InStep(const ApproximateOptions& options, FeatureScaling scaling,
                              const FeatureStorage& gallery) const {
  // Probes only change how the lists are read.
  return Plan(options, scaling, gallery) == Step::kNothing &&
         (lists_ == nullptr || options.probes == options_.probes);
}

absl::Status ApproximateIndex::Update(const ApproximateOptions& options, FeatureScaling scaling,
                                      const FeatureStorage& gallery, const float* scale,
                                      const std::atomic<bool>* cancel) {
  const int64_t whole_blocks = gallery.rows() / kBlockLanes * kBlockLanes;
  const int threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  switch (Plan(options, scaling, gallery)) {
    case Step::kNothing:
      break;
    case Step::kDrop:
      lists_.reset();
      break;
    case Step::kBuild: {
      const int lists = options.lists > 0
                            ? options.lists
                            : static_cast<int>(std::clamp<double>(
                                  std::round(ApproximateOptions::kDefaultListsPerSqrt *
                                             std::sqrt(static_cast<double>(gallery.rows()))),
                                  1.0, ApproximateOptions::kMaxLists));
      auto built = InvertedLists::Build(ActiveSimdLevel(), gallery, whole_blocks, scale, lists,
                                        threads, cancel);
      if (built == nullptr) return absl::CancelledError("approximate index build cancelled");
      lists_ = std::move(built);
      trained_rows_ = whole_blocks;
      scaling_ = scaling;
      break;
    }
    case Step::kExtend:
      lists_ = lists_->Extend(ActiveSimdLevel(), gallery, whole_blocks, scale, threads);
      break;
  }
  options_ = options;
  return absl::OkStatus();
}

void ApproximateIndex::Renumber(const FeatureStorage& gallery,
                                absl::Span<const int64_t> new_row_of_old) {
  if (lists_ != nullptr) lists_ = lists_->Renumber(gallery, new_row_of_old);
}

}  // namespace knn_internal
}  // namespace shapeid
