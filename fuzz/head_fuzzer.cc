// libFuzzer target: a gallery's trained head as a store or a replica reads it back
// (core/gallery/gallery_head.h), and the MLP classifier inside it (core/learning). Oracles
// beyond "no crash": errors are DataLoss; a head that parses serializes to the same bytes
// and answers any query of its dimension with probabilities that are finite and sum to 1.

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/string_view.h"
#include "core/gallery/gallery_head.h"
#include "fuzz/fuzz_oracle.h"

namespace shapeid {
namespace {

using fuzz::Fail;

void CheckClassifier(const MlpClassifier& classifier) {
  std::vector<float> query(static_cast<size_t>(classifier.dimension()), 0.5f);
  absl::StatusOr<std::vector<float>> p = classifier.Probabilities(query);
  if (!p.ok()) Fail("a parsed classifier refuses a query of its dimension", p.status());
  if (static_cast<int>(p->size()) != classifier.num_classes()) Fail("not one value a class");
  double sum = 0;
  for (const float v : *p) {
    if (!std::isfinite(v) || v < 0) Fail("a probability that is not finite and >= 0");
    sum += v;
  }
  if (std::abs(sum - 1) > 1e-3) Fail("probabilities that do not sum to 1");
}

}  // namespace
}  // namespace shapeid

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace shapeid;
  if (size > (1 << 16)) return 0;
  const absl::string_view bytes(reinterpret_cast<const char*>(data), size);
  absl::StatusOr<GalleryHead> head = GalleryHead::Parse(bytes);
  if (head.ok()) {
    if (head->Serialize() != bytes) Fail("Serialize(Parse(bytes)) differs from the bytes");
    CheckClassifier(head->classifier);
  } else if (head.status().code() != absl::StatusCode::kDataLoss) {
    Fail("a bad head is not DataLoss", head.status());
  }
  absl::StatusOr<MlpClassifier> classifier = MlpClassifier::Parse(bytes);
  if (classifier.ok()) {
    if (classifier->Serialize() != bytes) Fail("Serialize(Parse(bytes)) differs from the bytes");
    CheckClassifier(*classifier);
  } else if (classifier.status().code() != absl::StatusCode::kDataLoss) {
    Fail("a bad classifier is not DataLoss", classifier.status());
  }
  return 0;
}
