#include "core/descriptors/learned.h"

#include <algorithm>
#include <memory>
#include <utility>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "core/descriptors/dfsd.h"
#include "core/descriptors/dfsd_frame.h"
#include "core/status_macros.h"

namespace shapeid {

// The model files under core/descriptors/models/, embedded by CMake (cmake/embed_files.cmake).
namespace shipped_point_networks {
struct File {
  const char* name;
  const unsigned char* bytes;
  size_t size;
};
extern const File kFiles[];
extern const size_t kNumFiles;
}  // namespace shipped_point_networks

namespace {

using dfsd_internal::CloudFrame;

struct Shipped {
  std::string name;
  PointNetwork network;
};

// Parsed once, on first use; a shipped file that does not parse is a build defect, caught by
// learned_test, and is left out rather than taking the process down.
const std::vector<Shipped>& AllShipped() {
  static const auto* const all = [] {
    auto* networks = new std::vector<Shipped>;
    for (size_t i = 0; i < shipped_point_networks::kNumFiles; ++i) {
      const auto& file = shipped_point_networks::kFiles[i];
      absl::StatusOr<PointNetwork> network = PointNetwork::Parse(
          absl::string_view(reinterpret_cast<const char*>(file.bytes), file.size));
      if (network.ok()) networks->push_back({file.name, std::move(*network)});
    }
    return networks;
  }();
  return *all;
}

DfsdOptions FrameOptions(PointNetwork::Frame frame) {
  DfsdOptions options;
  options.frame =
      frame == PointNetwork::Frame::kBox ? DfsdOptions::Frame::kBox : DfsdOptions::Frame::kUpright;
  return options;
}

CanonicalPoints PointsInFrame(const PointCloud& cloud, const CloudStats& stats,
                              PointNetwork::Frame frame, uint32_t max_points) {
  const CloudFrame found = CloudFrame::Find(cloud, stats, FrameOptions(frame));
  CanonicalPoints canonical;
  const size_t n = cloud.size();
  const size_t m = std::min<size_t>(n, max_points);
  const double scale = 1.0 / found.half_extent().maxCoeff();  // > 0: ValidateCloud
  canonical.points.resize(3, static_cast<Eigen::Index>(m));
  for (size_t i = 0; i < m; ++i) {
    // i < m <= PointNetwork::kMaxPoints, so i * n cannot overflow for any cloud in memory.
    const size_t p = m == n ? i : static_cast<size_t>(uint64_t{i} * n / m);
    double x = 0, y = 0, z = 0;
    double* const coord[3] = {&x, &y, &z};
    found.Coordinates(cloud, p, 1, coord);
    canonical.points.col(static_cast<Eigen::Index>(i)) =
        Eigen::Vector3d(x, y, z).cast<float>() * static_cast<float>(scale);
  }
  canonical.extent = 2.0 * found.half_extent();
  const Eigen::Vector3d& extent = canonical.extent;
  const bool upright = frame == PointNetwork::Frame::kUpright;
  for (int a = 0; a < (upright ? 2 : 3); ++a) {
    if (found.skewness()[a] < dfsd_internal::kSkewnessTolerance) canonical.ambiguous |= 1u << a;
  }
  const double tolerance = 1 + dfsd_internal::kAxisOrderTolerance;
  if (extent[1] * tolerance >= extent[0]) canonical.ambiguous |= kAmbiguousSwap01;
  if (!upright && extent[2] * tolerance >= extent[1]) canonical.ambiguous |= kAmbiguousSwap12;
  return canonical;
}

class LearnedDescriptor final : public Descriptor {
 public:
  LearnedDescriptor(DescriptorSpec spec, const PointNetwork* network, double size_weight)
      : Descriptor(std::move(spec), static_cast<size_t>(network->dimension()) +
                                        (size_weight > 0 ? dfsd_internal::kSizeFeatures : 0)),
        network_(network),
        size_weight_(size_weight) {}

  DescribeCost EstimateCost(size_t num_points) const override {
    // The frame as DFSD's estimate prices it (box: the most passes), then the network's
    // multiply-adds at the layer kernel's single-core rate. Constants: docs/performance.md,
    // "Describe cost".
    constexpr double kNsBase = 10000, kNsPerMultiplyAdd = 0.06;
    const bool box = network_->frame() == PointNetwork::Frame::kBox;
    const double ns_per_framed_point = box ? 220 : 75;
    const size_t m = std::min<size_t>(num_points, network_->max_points());
    DescribeCost cost;
    cost.cpu = absl::Nanoseconds(kNsBase + ns_per_framed_point * static_cast<double>(num_points) +
                                 kNsPerMultiplyAdd * static_cast<double>(m) *
                                     static_cast<double>(network_->MultiplyAddsPerPoint()));
    // The frame's passes, the canonical points, the network's buffers, the output.
    const size_t frame_bytes =
        dfsd_internal::FrameBytes(num_points, FrameOptions(network_->frame()).frame);
    cost.working_bytes = frame_bytes + 3 * m * sizeof(float) + network_->WorkingBytes(m) +
                         dimension() * sizeof(float) + 4096;
    return cost;
  }

 protected:
  absl::Status ComputeValidated(const PointCloud& cloud, const CloudStats& stats,
                                const CloudLimits& limits, absl::Span<float> out) const override {
    (void)limits;
    const CanonicalPoints canonical =
        PointsInFrame(cloud, stats, network_->frame(), network_->max_points());
    network_->Embed(canonical.points, out.data());
    if (size_weight_ > 0) {
      dfsd_internal::WriteSizeBlock(canonical.extent, size_weight_,
                                    out.data() + network_->dimension());
    }
    return absl::OkStatus();
  }

 private:
  const PointNetwork* network_;  // shipped: lives as long as the process
  double size_weight_;
};

absl::StatusOr<std::unique_ptr<Descriptor>> CreateFromSpec(const DescriptorSpec& filled) {
  const SpecParams params(filled);
  SHAPEID_ASSIGN_OR_RETURN(const std::string name, params.Text("model"));
  absl::StatusOr<const PointNetwork*> network = ShippedPointNetwork(name);
  if (!network.ok()) return absl::InvalidArgumentError(network.status().message());
  SHAPEID_ASSIGN_OR_RETURN(const double size_weight, params.Double("size", 0.0, 1000.0));
  return std::unique_ptr<Descriptor>(new LearnedDescriptor(filled, *network, size_weight));
}

}  // namespace

absl::StatusOr<const PointNetwork*> ShippedPointNetwork(absl::string_view name) {
  for (const Shipped& shipped : AllShipped()) {
    if (shipped.name == name) return &shipped.network;
  }
  return absl::NotFoundError(
      absl::StrCat("no point network named \"", name,
                   "\" is built in; built in: ", absl::StrJoin(ShippedPointNetworkNames(), ", ")));
}

std::vector<std::string> ShippedPointNetworkNames() {
  std::vector<std::string> names;
  for (const Shipped& shipped : AllShipped()) names.push_back(shipped.name);
  return names;
}

absl::StatusOr<CanonicalPoints> MakeCanonicalPoints(const PointCloud& cloud,
                                                    PointNetwork::Frame frame,
                                                    uint32_t max_points) {
  if (max_points < 1) return absl::InvalidArgumentError("max_points must be at least 1");
  SHAPEID_ASSIGN_OR_RETURN(const CloudStats stats, ValidateCloud(cloud));
  return PointsInFrame(cloud, stats, frame, max_points);
}

DescriptorKind LearnedKind() {
  return {"learned",
          "a trained point network's embedding (learn/; built in, no Python at run time); "
          "any pose or gravity known, as the model's frame is",
          {{"model", kDefaultPointNetwork,
            "the built-in network: pointnet-box-v1 (any pose) | pointnet-upright-v1 (z up, any "
            "yaw); both ModelNet10-trained, 256 values"},
           {"size", "0",
            "weight of the absolute size block (ln of the 3 box extents, as dfsd's); 0 = off; "
            "use ~0.15 when every cloud of a gallery is in metres"}},
          &CreateFromSpec};
}

}  // namespace shapeid
