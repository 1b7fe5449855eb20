#include "core/descriptors/point_network.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "core/binary_codec.h"
#include "core/descriptors/point_network_kernels.h"
#include "core/simd.h"
#include "core/status_macros.h"

namespace shapeid {
namespace {

constexpr char kMagic[8] = {'S', 'H', 'P', 'D', 'P', 'N', 'E', 'T'};
constexpr uint32_t kFormatVersion = 1;
constexpr size_t kMaxNameBytes = 256;
constexpr size_t kMaxCardBytes = 64 * 1024;

using point_network_internal::DenseReluLayer;
using point_network_internal::kPointBlock;
using point_network_internal::LayerInput;

// The activation rows' stride for n points: the kernel's blocks, whole.
size_t PaddedPoints(size_t n) { return (n + kPointBlock - 1) / kPointBlock * kPointBlock; }

}  // namespace

absl::StatusOr<PointNetwork> PointNetwork::Create(std::string name, std::string card, Frame frame,
                                                  uint32_t max_points, std::vector<Layer> layers) {
  if (name.empty() || name.size() > kMaxNameBytes) {
    return absl::InvalidArgumentError("a point network needs a name of 1-256 bytes");
  }
  if (card.size() > kMaxCardBytes) return absl::InvalidArgumentError("model card over 64 KiB");
  if (frame != Frame::kBox && frame != Frame::kUpright) {
    return absl::InvalidArgumentError("unknown point network frame");
  }
  if (max_points < 1 || max_points > kMaxPoints) {
    return absl::InvalidArgumentError(absl::StrCat("max_points must be in [1, ", kMaxPoints, "]"));
  }
  if (layers.empty() || layers.size() > kMaxLayers) {
    return absl::InvalidArgumentError(
        absl::StrCat("a point network has 1-", kMaxLayers, " layers"));
  }
  Eigen::Index in = 3;
  int64_t parameters = 0;
  for (const Layer& layer : layers) {
    const Eigen::Index out = layer.weight.rows();
    if (layer.weight.cols() != in || layer.bias.size() != out || out < 1 || out > kMaxUnits) {
      return absl::InvalidArgumentError(
          absl::StrCat("layer shapes do not chain from 3 inputs (a layer of ", layer.weight.rows(),
                       " x ", layer.weight.cols(), " after ", in, " units)"));
    }
    if (!layer.weight.allFinite() || !layer.bias.allFinite()) {
      return absl::InvalidArgumentError("a point network's weights must be finite");
    }
    parameters += int64_t{out} * in + out;
    in = out;
  }
  if (parameters > kMaxParameters) {
    return absl::InvalidArgumentError("a point network over 4,000,000 parameters");
  }
  PointNetwork network;
  network.name_ = std::move(name);
  network.card_ = std::move(card);
  network.frame_ = frame;
  network.max_points_ = max_points;
  network.layers_ = std::move(layers);
  return network;
}

int64_t PointNetwork::MultiplyAddsPerPoint() const {
  int64_t total = 0;
  for (const Layer& layer : layers_) total += int64_t{layer.weight.rows()} * layer.weight.cols();
  return total;
}

size_t PointNetwork::WidestActivation() const {
  size_t widest = 3;
  for (const Layer& layer : layers_) widest = std::max<size_t>(widest, layer.bias.size());
  return widest;
}

size_t PointNetwork::WorkingBytes(size_t n) const {
  // Two activation buffers, the pooled vector.
  const size_t widest = WidestActivation();
  return (2 * widest * PaddedPoints(n) + widest) * sizeof(float);
}

void PointNetwork::Embed(const Eigen::Matrix3Xf& points, float* out) const {
  const size_t n = static_cast<size_t>(points.cols());
  const size_t stride = PaddedPoints(n);
  const size_t widest = WidestActivation();
  std::vector<float> buffers(2 * widest * stride);
  float* current = buffers.data();
  float* next = current + widest * stride;
  // Rows by coordinate; the padding repeats the first point, which changes no maximum.
  for (size_t a = 0; a < 3; ++a) {
    for (size_t p = 0; p < stride; ++p) {
      current[a * stride + p] =
          points(static_cast<Eigen::Index>(a), static_cast<Eigen::Index>(p < n ? p : 0));
    }
  }
  std::vector<float> pooled(static_cast<size_t>(dimension()));
  const SimdLevel level = ActiveSimdLevel();
  for (size_t l = 0; l < layers_.size(); ++l) {
    LayerInput input;
    input.weight = layers_[l].weight.data();
    input.bias = layers_[l].bias.data();
    input.inputs = static_cast<int>(layers_[l].weight.cols());
    input.units = static_cast<int>(layers_[l].weight.rows());
    input.activations = current;
    input.stride = stride;
    const bool last = l + 1 == layers_.size();
    DenseReluLayer(input, last ? nullptr : next, last ? pooled.data() : nullptr, level);
    std::swap(current, next);
  }
  double squares = 0;
  for (const float v : pooled) squares += double{v} * v;
  // All-zero pooled features (every unit dead for every point) have no direction: left 0.
  const double scale = squares > 0 ? 1.0 / std::sqrt(squares) : 0.0;
  for (size_t i = 0; i < pooled.size(); ++i) out[i] = static_cast<float>(pooled[i] * scale);
}

std::string PointNetwork::Serialize() const {
  ByteWriter out;
  out.Header(absl::string_view(kMagic, sizeof(kMagic)), kFormatVersion);
  out.String(name_);
  out.String(card_);
  out.U32(static_cast<uint32_t>(frame_));
  out.U32(max_points_);
  out.U32(static_cast<uint32_t>(layers_.size()));
  for (const Layer& layer : layers_) out.U32(static_cast<uint32_t>(layer.weight.rows()));
  for (const Layer& layer : layers_) {
    out.Floats(layer.weight.data(), layer.weight.size());
    out.Floats(layer.bias.data(), layer.bias.size());
  }
  return std::move(out).Finish();
}

absl::StatusOr<PointNetwork> PointNetwork::Parse(absl::string_view bytes) {
  auto bad = [](absl::string_view why) {
    return absl::DataLossError(absl::StrCat("not a shapeid point network: ", why));
  };
  ByteReader reader;
  SHAPEID_RETURN_IF_ERROR(OpenVersionedFile(bytes, absl::string_view(kMagic, sizeof(kMagic)),
                                            kFormatVersion, "point network", reader));
  std::string name, card;
  if (!reader.String(name, kMaxNameBytes) || !reader.String(card, kMaxCardBytes)) {
    return bad("name or card too long");
  }
  uint32_t frame = 0, max_points = 0, count = 0;
  if (!reader.U32(frame) || !reader.U32(max_points) || !reader.U32(count) || count < 1 ||
      count > kMaxLayers) {
    return bad("header out of range");
  }
  std::vector<uint32_t> units(count);
  int64_t parameters = 0;
  int64_t in = 3;
  for (uint32_t& out : units) {
    if (!reader.U32(out) || out < 1 || out > kMaxUnits) return bad("layer units out of range");
    parameters += in * out + out;
    in = out;
  }
  // Sizes first: nothing is allocated that the bytes left could not fill.
  if (parameters > kMaxParameters || static_cast<int64_t>(reader.left()) != 4 * parameters) {
    return bad("sizes do not match the length");
  }
  std::vector<Layer> layers;
  in = 3;
  for (const uint32_t out : units) {
    Layer layer;
    layer.weight.resize(out, in);
    layer.bias.resize(out);
    if (!reader.Floats(layer.weight.data(), layer.weight.size()) ||
        !reader.Floats(layer.bias.data(), out)) {
      return bad("a weight is not finite");
    }
    layers.push_back(std::move(layer));
    in = out;
  }
  absl::StatusOr<PointNetwork> network = Create(
      std::move(name), std::move(card), static_cast<Frame>(frame), max_points, std::move(layers));
  if (!network.ok()) return bad(network.status().message());
  return network;
}

}  // namespace shapeid
