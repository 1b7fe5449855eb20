#include "core/gallery/gallery_head.h"

#include <algorithm>
#include <map>
#include <utility>

#include "absl/strings/str_cat.h"
#include "core/binary_codec.h"
#include "core/fnv1a.h"
#include "core/gallery/gallery_snapshot.h"
#include "core/random.h"
#include "core/status_macros.h"

namespace shapeid {
namespace {

constexpr char kMagic[8] = {'S', 'H', 'P', 'D', 'H', 'E', 'A', 'D'};
constexpr uint32_t kFormatVersion = 1;
constexpr uint32_t kMaxLabels = 1 << 16;

// Whether sample `id` is held out: a hash of the id alone, so that a sample stays on its side
// of the split as the gallery grows and shrinks.
bool HeldOut(uint64_t id, int per_mille) {
  return per_mille > 0 &&
         SplitMix64(id ^ 0x5eedf00dull).Next() % 1000 < static_cast<uint64_t>(per_mille);
}

// The chance that a view (1 and up) of a sample is read, and the chance that a sample's own
// descriptor is, so that a fit reads about max_vectors vectors.
struct Sampling {
  double own = 1.0;
  double views = 1.0;
};

Sampling SamplingFor(int64_t samples, int64_t rows, int64_t max_vectors) {
  Sampling sampling;
  if (rows <= max_vectors) return sampling;
  if (samples >= max_vectors) {
    sampling.own = static_cast<double>(max_vectors) / static_cast<double>(samples);
    sampling.views = 0;
  } else {
    sampling.views =
        static_cast<double>(max_vectors - samples) / static_cast<double>(rows - samples);
  }
  return sampling;
}

// A uniform draw in [0, 1) fixed by (id, view).
double Draw(uint64_t id, int view) {
  return static_cast<double>(
             SplitMix64(id * 0x9e3779b97f4a7c15ull + static_cast<uint64_t>(view)).Next() >> 11) *
         0x1.0p-53;
}

}  // namespace

int64_t FitVectors(const GallerySnapshot& snapshot, const HeadOptions& options) {
  return std::min<int64_t>(snapshot.index().num_rows(), options.max_vectors);
}

absl::Status ValidateHeadOptions(const HeadOptions& options) {
  if (absl::Status valid = ValidateMlpOptions(options.mlp); !valid.ok()) return valid;
  if (options.holdout_per_mille < 0 || options.holdout_per_mille > 500) {
    return absl::InvalidArgumentError(
        absl::StrCat("held-out per mille must be in [0, 500], not ", options.holdout_per_mille));
  }
  if (options.min_samples < 2) return absl::InvalidArgumentError("min samples must be >= 2");
  if (options.max_vectors < options.min_samples) {
    return absl::InvalidArgumentError("max vectors must be >= min samples");
  }
  return absl::OkStatus();
}

int GalleryHead::ClassOf(absl::string_view label) const {
  const auto found = std::lower_bound(labels.begin(), labels.end(), label);
  return found != labels.end() && *found == label ? static_cast<int>(found - labels.begin()) : -1;
}

std::string GalleryHead::Serialize() const {
  ByteWriter out;
  out.Header(absl::string_view(kMagic, sizeof(kMagic)), kFormatVersion);
  out.U64(fitted_version);
  out.U64(samples_fingerprint);
  out.U64(static_cast<uint64_t>(fitted_samples));
  out.U64(static_cast<uint64_t>(fitted_rows));
  out.U64(static_cast<uint64_t>(holdout_samples));
  out.U64(static_cast<uint64_t>(holdout_rows));
  out.U64(static_cast<uint64_t>(holdout_right));
  out.U64(static_cast<uint64_t>(absl::ToInt64Microseconds(fit_time)));
  out.U32(static_cast<uint32_t>(labels.size()));
  for (const std::string& label : labels) out.String(label);
  out.String(classifier.Serialize());
  return std::move(out).Finish();
}

absl::StatusOr<GalleryHead> GalleryHead::Parse(absl::string_view bytes) {
  auto bad = [](absl::string_view why) {
    return absl::DataLossError(absl::StrCat("not a shapeid gallery head: ", why));
  };
  ByteReader reader;
  SHAPEID_RETURN_IF_ERROR(OpenVersionedFile(bytes, absl::string_view(kMagic, sizeof(kMagic)),
                                            kFormatVersion, "gallery head", reader));
  GalleryHead head;
  uint64_t counts[5] = {};
  uint64_t micros = 0;
  if (!reader.U64(head.fitted_version) || !reader.U64(head.samples_fingerprint)) {
    return bad("truncated");
  }
  for (uint64_t& count : counts) {
    if (!reader.U64(count) || count > (uint64_t{1} << 40)) return bad("a count out of range");
  }
  if (!reader.U64(micros) || micros > (uint64_t{1} << 50)) return bad("a time out of range");
  head.fitted_samples = static_cast<int64_t>(counts[0]);
  head.fitted_rows = static_cast<int64_t>(counts[1]);
  head.holdout_samples = static_cast<int64_t>(counts[2]);
  head.holdout_rows = static_cast<int64_t>(counts[3]);
  head.holdout_right = static_cast<int64_t>(counts[4]);
  if (head.holdout_right > head.holdout_rows) return bad("more right than held out");
  head.fit_time = absl::Microseconds(static_cast<int64_t>(micros));
  uint32_t num_labels = 0;
  if (!reader.U32(num_labels) || num_labels < 2 || num_labels > kMaxLabels ||
      num_labels > reader.left() / 4) {
    return bad("label count out of range");
  }
  head.labels.resize(num_labels);
  for (std::string& label : head.labels) {
    if (!reader.String(label, kMaxLabelBytes)) return bad("a label out of range");
  }
  if (!std::is_sorted(head.labels.begin(), head.labels.end()) ||
      std::adjacent_find(head.labels.begin(), head.labels.end()) != head.labels.end()) {
    return bad("labels not sorted and distinct");
  }
  uint32_t size = 0;
  absl::string_view net;
  if (!reader.U32(size) || !reader.Bytes(size, net) || reader.left() != 0) {
    return bad("the classifier's length does not match");
  }
  absl::StatusOr<MlpClassifier> classifier = MlpClassifier::Parse(net);
  if (!classifier.ok()) return classifier.status();
  if (classifier->num_classes() != static_cast<int>(num_labels)) {
    return bad("the classifier's classes are not the labels");
  }
  head.classifier = *std::move(classifier);
  return head;
}

uint64_t SamplesFingerprint(const GallerySnapshot& snapshot) {
  const KnnIndex& index = snapshot.index();
  Fnv1a hash;  // over (id, label) in order
  for (int64_t s = 0; s < index.size(); ++s) {
    const uint64_t id = index.IdAt(s);
    const std::string& label = index.LabelAt(s);
    const uint64_t size = label.size();
    hash.Add(&id, sizeof(id));
    hash.Add(&size, sizeof(size));
    hash.Add(label.data(), label.size());
  }
  return hash.value();
}

absl::StatusOr<GalleryHead> FitGalleryHead(const GallerySnapshot& snapshot,
                                           const HeadOptions& options,
                                           const FitProgress& progress) {
  if (absl::Status valid = ValidateHeadOptions(options); !valid.ok()) return valid;
  const KnnIndex& index = snapshot.index();
  const std::map<std::string, int64_t> counts = snapshot.LabelCounts();
  if (index.size() < options.min_samples || counts.size() < 2) {
    return absl::FailedPreconditionError(absl::StrCat(
        "gallery '", snapshot.name(), "' has ", index.size(), " samples of ", counts.size(),
        " labels; a head needs at least ", options.min_samples, " samples of 2 labels"));
  }
  const absl::Time start = absl::Now();
  GalleryHead head;
  head.fitted_version = snapshot.version();
  head.samples_fingerprint = SamplesFingerprint(snapshot);
  for (const auto& [label, count] : counts) head.labels.push_back(label);
  const int d = index.dimension();
  TrainingRows fit, held;
  fit.dimension = held.dimension = d;
  fit.num_classes = held.num_classes = static_cast<int>(head.labels.size());
  const Sampling sampling = SamplingFor(index.size(), index.num_rows(), options.max_vectors);
  std::vector<float> views;
  for (int64_t s = 0; s < index.size(); ++s) {
    const uint64_t id = index.IdAt(s);
    const int cls = head.ClassOf(index.LabelAt(s));
    const int n = index.ViewsAt(s);
    views.resize(static_cast<size_t>(n) * d);
    index.CopyFeatures(s, views.data());
    TrainingRows& rows = HeldOut(id, options.holdout_per_mille) ? held : fit;
    (&rows == &held ? head.holdout_samples : head.fitted_samples) += 1;
    for (int v = 0; v < n; ++v) {
      if (Draw(id, v) >= (v == 0 ? sampling.own : sampling.views)) continue;
      rows.features.insert(rows.features.end(), views.begin() + static_cast<size_t>(v) * d,
                           views.begin() + static_cast<size_t>(v + 1) * d);
      rows.classes.push_back(cls);
    }
  }
  if (fit.rows() == 0) {
    return absl::FailedPreconditionError(
        absl::StrCat("gallery '", snapshot.name(), "': no vector left to fit after sampling"));
  }
  head.fitted_rows = fit.rows();
  head.holdout_rows = held.rows();
  absl::StatusOr<MlpClassifier> classifier = MlpClassifier::Fit(fit, options.mlp, progress);
  if (!classifier.ok()) return classifier.status();
  head.classifier = *std::move(classifier);
  for (int64_t r = 0; r < held.rows(); ++r) {
    const std::vector<float> p =
        *head.classifier.Probabilities({&held.features[r * d], static_cast<size_t>(d)});
    head.holdout_right += std::max_element(p.begin(), p.end()) - p.begin() == held.classes[r];
  }
  head.fit_time = absl::Now() - start;
  return head;
}

}  // namespace shapeid
