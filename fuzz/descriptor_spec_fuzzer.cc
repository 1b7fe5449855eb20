// libFuzzer target: descriptor specs as users type them ("rphsd:refs=cubic27,bins=100"),
// through the syntax parser (core/descriptor_spec.h) and the registry's schema check
// (core/descriptor_registry.h), then the descriptor itself on a small cloud. Oracles beyond
// "no crash": errors are InvalidArgument; Parse(ToString()) round-trips; the canonical spec
// of a descriptor builds a descriptor with the same canonical spec; a built descriptor
// describes a valid cloud into dimension() finite values.

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/string_view.h"
#include "core/descriptor_registry.h"
#include "core/descriptor_spec.h"
#include "core/point_cloud.h"
#include "fuzz/fuzz_oracle.h"

namespace shapeid {
namespace {

using fuzz::Fail;

void CheckError(const absl::Status& status) {
  if (status.code() != absl::StatusCode::kInvalidArgument) {
    Fail("a bad spec is not InvalidArgument", status);
  }
}

// 256 points on a squashed, slightly twisted helix: not symmetric, so every frame is defined.
const PointCloud& ProbeCloud() {
  static const PointCloud* cloud = [] {
    auto* c = new PointCloud;
    for (int i = 0; i < 256; ++i) {
      const float t = 0.05f * static_cast<float>(i);
      c->Add(std::cos(t) * (1.0f + 0.01f * t), 0.5f * std::sin(1.3f * t), 0.02f * t * t);
    }
    return c;
  }();
  return *cloud;
}

}  // namespace
}  // namespace shapeid

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace shapeid;
  // Specs are short lines; longer inputs only slow the search down.
  if (size > 512) return 0;
  const absl::string_view text(reinterpret_cast<const char*>(data), size);

  absl::StatusOr<DescriptorSpec> spec = DescriptorSpec::Parse(text);
  if (!spec.ok()) {
    CheckError(spec.status());
    return 0;
  }
  absl::StatusOr<DescriptorSpec> again = DescriptorSpec::Parse(spec->ToString());
  if (!again.ok()) Fail("Parse(ToString()) fails", again.status());
  if (!(*again == *spec)) Fail("Parse(ToString()) differs from the spec");

  absl::StatusOr<std::unique_ptr<Descriptor>> descriptor = CreateDescriptor(*spec);
  if (!descriptor.ok()) {
    CheckError(descriptor.status());
    return 0;
  }
  const DescriptorSpec& canonical = (*descriptor)->spec();
  absl::StatusOr<std::unique_ptr<Descriptor>> rebuilt = CreateDescriptor(canonical.ToString());
  if (!rebuilt.ok()) Fail("the canonical spec does not build", rebuilt.status());
  if (!((*rebuilt)->spec() == canonical)) Fail("canonicalising is not idempotent");

  std::vector<float> values;
  const absl::Status computed = (*descriptor)->Compute(ProbeCloud(), &values);
  if (!computed.ok()) Fail("a valid cloud is refused", computed);
  if (values.size() != (*descriptor)->dimension()) Fail("output size is not dimension()");
  for (float v : values) {
    if (!std::isfinite(v)) Fail("non-finite descriptor value");
  }
  return 0;
}
