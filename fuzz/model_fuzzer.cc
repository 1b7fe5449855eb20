// libFuzzer target: a point network's model file as the `learned` descriptor reads it
// (core/descriptors/point_network.h). Oracles beyond "no crash": errors are DataLoss; a network
// that parses serializes to the same bytes and embeds any points into finite values of unit
// length (or all zero).

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/string_view.h"
#include "core/descriptors/point_network.h"
#include "fuzz/fuzz_oracle.h"

namespace shapeid {
namespace {

using fuzz::Fail;

void CheckEmbedding(const PointNetwork& network) {
  Eigen::Matrix3Xf points(3, 5);
  points << -1, -0.5f, 0, 0.5f, 1, 0.3f, -0.2f, 0.9f, -1, 0, 1, 1, -1, 0.25f, -0.75f;
  std::vector<float> out(static_cast<size_t>(network.dimension()));
  network.Embed(points, out.data());
  double norm = 0;
  for (const float v : out) {
    if (!std::isfinite(v)) Fail("an embedding value that is not finite");
    norm += double{v} * v;
  }
  if (norm != 0 && std::abs(norm - 1) > 1e-3) Fail("an embedding neither unit length nor zero");
}

}  // namespace
}  // namespace shapeid

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace shapeid;
  // Replay reads the shipped models (~170 KB); generated inputs stay small to stay fast.
  if (size > (1 << 20)) return 0;
  const absl::string_view bytes(reinterpret_cast<const char*>(data), size);
  absl::StatusOr<PointNetwork> network = PointNetwork::Parse(bytes);
  if (network.ok()) {
    if (network->Serialize() != bytes) Fail("Serialize(Parse(bytes)) differs from the bytes");
    CheckEmbedding(*network);
  } else if (network.status().code() != absl::StatusCode::kDataLoss) {
    Fail("a bad model file is not DataLoss", network.status());
  }
  return 0;
}
