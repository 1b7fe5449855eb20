#ifndef SHAPEID_CORE_DESCRIPTORS_POINT_NETWORK_H_
#define SHAPEID_CORE_DESCRIPTORS_POINT_NETWORK_H_

// A trained point network (PointNet's shared per-point MLP and max pool) and its model file:
// the inference half of the `learned` descriptor. Networks are trained in Python apart from
// the product (learn/); this is how C++ answers with one, with no Python at run time.

#include <cstdint>
#include <string>
#include <vector>

#include "Eigen/Core"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"

namespace shapeid {

class PointNetwork {
 public:
  // The frame a network's points are laid in before it sees them (CanonicalPoints).
  enum class Frame : uint32_t {
    kBox = 0,      // DFSD's frame=box: rotation invariant, any pose
    kUpright = 1,  // DFSD's frame=upright with z up: yaw invariant, keeps the vertical
  };

  using Weights = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  struct Layer {
    Weights weight;        // out x in
    Eigen::VectorXf bias;  // out
  };

  // Bounds a model file may not exceed (the parser refuses larger ones before allocating).
  static constexpr uint32_t kMaxPoints = 4096;
  static constexpr uint32_t kMaxLayers = 8;
  static constexpr uint32_t kMaxUnits = 2048;
  static constexpr int64_t kMaxParameters = 4'000'000;

  // `layers` map 3 -> ... -> dimension, each followed by ReLU; the embedding is the max over
  // points of the last layer, scaled to unit length. InvalidArgument where the shapes do
  // not chain or a bound above is exceeded.
  static absl::StatusOr<PointNetwork> Create(std::string name, std::string card, Frame frame,
                                             uint32_t max_points, std::vector<Layer> layers);

  // A model file: a versioned, checksummed little-endian encoding (learn/point_network_file.py
  // writes the same bytes). DataLoss naming the defect for anything else; never allocates
  // more than the bytes could fill.
  static absl::StatusOr<PointNetwork> Parse(absl::string_view bytes);
  std::string Serialize() const;

  const std::string& name() const { return name_; }
  // The model card: what the network was trained on, how, and how well it did (Markdown).
  const std::string& card() const { return card_; }
  Frame frame() const { return frame_; }
  // The most points the network reads of a cloud (CanonicalPoints subsamples to it).
  uint32_t max_points() const { return max_points_; }
  int dimension() const { return static_cast<int>(layers_.back().bias.size()); }
  const std::vector<Layer>& layers() const { return layers_; }
  // Multiply-adds per point, for cost estimates.
  int64_t MultiplyAddsPerPoint() const;

  // The embedding of points already in the network's frame (3 x n, n >= 1) into `out`
  // (dimension() floats). The same bits on every SIMD level (point_network_kernels.h);
  // thread-safe; allocates WorkingBytes(n).
  void Embed(const Eigen::Matrix3Xf& points, float* out) const;
  // The heap Embed allocates for n points.
  size_t WorkingBytes(size_t n) const;

 private:
  PointNetwork() = default;
  // Units of the widest activation Embed holds per point (3, the input, at least).
  size_t WidestActivation() const;

  std::string name_;
  std::string card_;
  Frame frame_ = Frame::kBox;
  uint32_t max_points_ = 0;
  std::vector<Layer> layers_;
};

}  // namespace shapeid

#endif  // SHAPEID_CORE_DESCRIPTORS_POINT_NETWORK_H_
