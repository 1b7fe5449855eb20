#include "core/learning/mlp_classifier.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <utility>

#include "absl/strings/str_cat.h"
#include "core/binary_codec.h"
#include "core/random.h"
#include "core/status_macros.h"

namespace shapeid {
namespace {

constexpr char kMagic[8] = {'S', 'H', 'P', 'D', 'M', 'L', 'P', '\0'};
constexpr uint32_t kFormatVersion = 1;
constexpr int kMaxDimension = 1 << 16;
constexpr int kMaxUnits = 1 << 14;
constexpr int kMaxLayers = 16;
constexpr int64_t kMaxParameters = int64_t{1} << 26;  // 256 MiB of floats

// A, M, V for AdamW over one parameter block.
struct AdamState {
  Eigen::ArrayXf m, v;
  explicit AdamState(Eigen::Index n) : m(Eigen::ArrayXf::Zero(n)), v(Eigen::ArrayXf::Zero(n)) {}
};

// Turns a row of logits into probabilities, in place (shifted by its largest for range).
template <typename Row>
void Softmax(Row&& row) {
  const float top = row.maxCoeff();
  row = (row.array() - top).exp().matrix();
  row /= row.sum();
}

}  // namespace

absl::Status ValidateMlpOptions(const MlpOptions& options) {
  if (options.hidden.size() > kMaxLayers - 1) {
    return absl::InvalidArgumentError(absl::StrCat("at most ", kMaxLayers - 1, " hidden layers"));
  }
  for (const int units : options.hidden) {
    if (units < 1 || units > kMaxUnits) {
      return absl::InvalidArgumentError(
          absl::StrCat("hidden layer units must be in [1, ", kMaxUnits, "], not ", units));
    }
  }
  if (options.epochs < 1 || options.epochs > 10000) {
    return absl::InvalidArgumentError(
        absl::StrCat("epochs must be in [1, 10000], not ", options.epochs));
  }
  if (options.batch_size < 1 || options.batch_size > 65536) {
    return absl::InvalidArgumentError(
        absl::StrCat("batch size must be in [1, 65536], not ", options.batch_size));
  }
  if (!(options.learning_rate > 0 && options.learning_rate <= 1)) {
    return absl::InvalidArgumentError("learning rate must be in (0, 1]");
  }
  if (!(options.weight_decay >= 0 && options.weight_decay < 1)) {
    return absl::InvalidArgumentError("weight decay must be in [0, 1)");
  }
  if (!(options.dropout >= 0 && options.dropout < 1)) {
    return absl::InvalidArgumentError("dropout must be in [0, 1)");
  }
  if (!(options.input_noise >= 0 && options.input_noise <= 10)) {
    return absl::InvalidArgumentError("input noise must be in [0, 10]");
  }
  if (!(options.label_smoothing >= 0 && options.label_smoothing < 1)) {
    return absl::InvalidArgumentError("label smoothing must be in [0, 1)");
  }
  return absl::OkStatus();
}

int64_t MlpClassifier::ParametersFor(int dimension, const std::vector<int>& hidden, int classes) {
  int64_t parameters = 0;
  int64_t inputs = dimension;
  for (const int units : hidden) {
    parameters += (inputs + 1) * units;
    inputs = units;
  }
  return parameters + (inputs + 1) * classes;
}

int64_t MlpClassifier::parameters() const {
  int64_t n = 0;
  for (size_t l = 0; l < weights_.size(); ++l) n += weights_[l].size() + biases_[l].size();
  return n;
}

MlpClassifier::Matrix MlpClassifier::Logits(const Matrix& input) const {
  Matrix h = input;
  for (size_t l = 0; l < weights_.size(); ++l) {
    Matrix z = h * weights_[l];
    z.rowwise() += biases_[l];
    if (l + 1 < weights_.size()) z = z.cwiseMax(0.0f);
    h = std::move(z);
  }
  return h;
}

absl::StatusOr<MlpClassifier> MlpClassifier::Fit(const TrainingRows& rows,
                                                 const MlpOptions& options,
                                                 const FitProgress& progress) {
  if (absl::Status valid = ValidateMlpOptions(options); !valid.ok()) return valid;
  const int64_t n = rows.rows();
  const int d = rows.dimension;
  const int classes = rows.num_classes;
  if (n == 0) return absl::InvalidArgumentError("no rows to fit");
  if (d < 1 || d > kMaxDimension) {
    return absl::InvalidArgumentError(
        absl::StrCat("dimension must be in [1, ", kMaxDimension, "], not ", d));
  }
  if (classes < 1 || classes > kMaxUnits) {
    return absl::InvalidArgumentError(
        absl::StrCat("classes must be in [1, ", kMaxUnits, "], not ", classes));
  }
  if (static_cast<int64_t>(rows.features.size()) != n * d) {
    return absl::InvalidArgumentError(absl::StrCat("features hold ", rows.features.size(),
                                                   " floats, not rows * dimension = ", n * d));
  }
  for (int64_t r = 0; r < n; ++r) {
    if (rows.classes[r] < 0 || rows.classes[r] >= classes) {
      return absl::InvalidArgumentError(
          absl::StrCat("row ", r, ": class ", rows.classes[r], " not in [0, ", classes, ")"));
    }
  }
  for (size_t i = 0; i < rows.features.size(); ++i) {
    if (!std::isfinite(rows.features[i])) {
      return absl::InvalidArgumentError(
          absl::StrCat("row ", i / d, ": feature ", i % d, " is not finite"));
    }
  }

  MlpClassifier net;
  net.dimension_ = d;
  const Eigen::Map<const Matrix> x(rows.features.data(), n, d);
  // Standardisation, in double so that a long column sums exactly enough.
  const Eigen::VectorXd mean = x.cast<double>().colwise().mean().transpose();
  const Eigen::VectorXd var =
      (x.cast<double>().rowwise() - mean.transpose()).array().square().colwise().mean();
  net.offset_ = mean.cast<float>();
  net.scale_.resize(d);
  for (int j = 0; j < d; ++j) {
    // A constant feature carries nothing: scaled to 0 rather than blown up.
    net.scale_[j] = var[j] > 1e-12 ? static_cast<float>(1.0 / std::sqrt(var[j])) : 0.0f;
  }

  SplitMix64 random(options.seed);
  std::vector<int> units = {d};
  units.insert(units.end(), options.hidden.begin(), options.hidden.end());
  units.push_back(classes);
  const int64_t parameters = ParametersFor(d, options.hidden, classes);
  if (parameters > kMaxParameters) {
    return absl::InvalidArgumentError(
        absl::StrCat(parameters, " parameters: at most ", kMaxParameters));
  }
  for (size_t l = 0; l + 1 < units.size(); ++l) {
    // He initialization (uniform), for ReLU layers.
    const float bound = static_cast<float>(std::sqrt(6.0 / units[l]));
    Matrix w(units[l], units[l + 1]);
    for (Eigen::Index i = 0; i < w.size(); ++i) {
      w.data()[i] = static_cast<float>((2 * random.Uniform() - 1) * bound);
    }
    net.weights_.push_back(std::move(w));
    net.biases_.push_back(Eigen::RowVectorXf::Zero(units[l + 1]));
  }
  const size_t layers = net.weights_.size();
  std::vector<AdamState> adam_w, adam_b;
  for (size_t l = 0; l < layers; ++l) {
    adam_w.emplace_back(net.weights_[l].size());
    adam_b.emplace_back(net.biases_[l].size());
  }

  const int batch = static_cast<int>(std::min<int64_t>(options.batch_size, n));
  const int64_t steps_per_epoch = (n + batch - 1) / batch;
  const int64_t total_steps = steps_per_epoch * options.epochs;
  const int64_t warmup = steps_per_epoch;
  const float keep = static_cast<float>(1.0 - options.dropout);
  const float smooth = static_cast<float>(options.label_smoothing);
  constexpr float kBeta1 = 0.9f, kBeta2 = 0.999f, kEpsilon = 1e-8f;

  std::vector<int64_t> order(n);
  std::iota(order.begin(), order.end(), 0);
  // Per layer: its input (activations after dropout) and the dropout masks.
  std::vector<Matrix> inputs(layers);
  std::vector<Matrix> masks(layers);
  Matrix grad_w, delta, back;
  Eigen::RowVectorXf grad_b;
  int64_t step = 0;
  for (int epoch = 0; epoch < options.epochs; ++epoch) {
    for (int64_t i = n - 1; i > 0; --i) {  // Fisher-Yates, with the project's generator
      std::swap(order[i], order[random.Next() % static_cast<uint64_t>(i + 1)]);
    }
    for (int64_t start = 0; start < n; start += batch) {
      if (progress) {
        if (absl::Status going = progress(static_cast<double>(step) / total_steps); !going.ok()) {
          return going;
        }
      }
      const int b = static_cast<int>(std::min<int64_t>(batch, n - start));
      Matrix& in = inputs[0];
      in.resize(b, d);
      for (int r = 0; r < b; ++r) {
        in.row(r) = (x.row(order[start + r]) - net.offset_.transpose())
                        .cwiseProduct(net.scale_.transpose());
      }
      if (options.input_noise > 0) {
        const float sigma = static_cast<float>(options.input_noise);
        for (Eigen::Index k = 0; k < in.size(); k += 2) {  // Box-Muller, two values a draw
          const double radius = std::sqrt(-2 * std::log(1 - random.Uniform()));
          const double angle = 2 * M_PI * random.Uniform();
          in.data()[k] += sigma * static_cast<float>(radius * std::cos(angle));
          if (k + 1 < in.size())
            in.data()[k + 1] += sigma * static_cast<float>(radius * std::sin(angle));
        }
      }
      // Forward.
      Matrix z;
      for (size_t l = 0; l < layers; ++l) {
        z.noalias() = inputs[l] * net.weights_[l];
        z.rowwise() += net.biases_[l];
        if (l + 1 == layers) break;
        Matrix& mask = masks[l + 1];
        mask.resize(b, z.cols());
        for (Eigen::Index k = 0; k < mask.size(); ++k) {
          const bool kept = options.dropout == 0 || random.Uniform() < keep;
          mask.data()[k] = z.data()[k] > 0 && kept ? 1.0f / keep : 0.0f;
        }
        inputs[l + 1] = z.cwiseProduct(mask);
      }
      // Softmax cross-entropy with smoothed targets: delta = p - target, averaged on the batch.
      delta = z;
      for (int r = 0; r < b; ++r) {
        Softmax(delta.row(r));
        delta.row(r).array() -= smooth / classes;
        delta(r, rows.classes[order[start + r]]) -= 1.0f - smooth;
      }
      delta /= static_cast<float>(b);
      // Learning rate: linear warm-up over the first epoch, then cosine down to zero.
      double rate = options.learning_rate;
      if (step < warmup) {
        rate *= static_cast<double>(step + 1) / warmup;
      } else {
        const double t =
            static_cast<double>(step - warmup) / std::max<int64_t>(1, total_steps - warmup);
        rate *= 0.5 * (1 + std::cos(M_PI * t));
      }
      ++step;
      const float correction1 = 1.0f - std::pow(kBeta1, static_cast<float>(step));
      const float correction2 = 1.0f - std::pow(kBeta2, static_cast<float>(step));
      const float lr = static_cast<float>(rate);
      const float decay = static_cast<float>(1.0 - rate * options.weight_decay);
      // Backward, layer by layer from the top; each layer's update after its input's delta.
      for (size_t l = layers; l-- > 0;) {
        grad_w.noalias() = inputs[l].transpose() * delta;
        grad_b = delta.colwise().sum();
        if (l > 0) {
          back.noalias() = delta * net.weights_[l].transpose();
          delta = back.cwiseProduct(masks[l]);  // ReLU and dropout in one mask
        }
        auto adam = [&](float* param, const float* grad, AdamState& state, bool decayed) {
          Eigen::Map<Eigen::ArrayXf> p(param, state.m.size());
          const Eigen::Map<const Eigen::ArrayXf> g(grad, state.m.size());
          state.m = kBeta1 * state.m + (1 - kBeta1) * g;
          state.v = kBeta2 * state.v + (1 - kBeta2) * g.square();
          if (decayed) p *= decay;
          p -= lr * (state.m / correction1) / ((state.v / correction2).sqrt() + kEpsilon);
        };
        adam(net.weights_[l].data(), grad_w.data(), adam_w[l], true);
        adam(net.biases_[l].data(), grad_b.data(), adam_b[l], false);
      }
    }
  }
  if (progress) {
    if (absl::Status going = progress(1.0); !going.ok()) return going;
  }
  return net;
}

absl::StatusOr<std::vector<float>> MlpClassifier::Probabilities(
    absl::Span<const float> features) const {
  if (dimension_ == 0) return absl::FailedPreconditionError("an empty classifier answers nothing");
  if (features.empty() || features.size() % dimension_ != 0) {
    return absl::InvalidArgumentError(absl::StrCat(
        "a query of ", features.size(), " features: not a positive multiple of ", dimension_));
  }
  const Eigen::Index n = static_cast<Eigen::Index>(features.size() / dimension_);
  const Eigen::Map<const Matrix> x(features.data(), n, dimension_);
  Matrix input = (x.rowwise() - offset_.transpose()).array().rowwise() * scale_.transpose().array();
  Matrix logits = Logits(input);  // softmaxed row by row below
  std::vector<float> mean(num_classes(), 0.0f);
  for (Eigen::Index r = 0; r < n; ++r) {
    Softmax(logits.row(r));
    for (int c = 0; c < num_classes(); ++c) mean[c] += logits(r, c) / static_cast<float>(n);
  }
  return mean;
}

std::string MlpClassifier::Serialize() const {
  ByteWriter out;
  out.Header(absl::string_view(kMagic, sizeof(kMagic)), kFormatVersion);
  out.U32(static_cast<uint32_t>(dimension_));
  out.U32(static_cast<uint32_t>(weights_.size()));
  for (const Matrix& w : weights_) out.U32(static_cast<uint32_t>(w.cols()));
  out.Floats(offset_.data(), offset_.size());
  out.Floats(scale_.data(), scale_.size());
  for (size_t l = 0; l < weights_.size(); ++l) {
    out.Floats(weights_[l].data(), weights_[l].size());
    out.Floats(biases_[l].data(), biases_[l].size());
  }
  return std::move(out).Finish();
}

absl::StatusOr<MlpClassifier> MlpClassifier::Parse(absl::string_view bytes) {
  auto bad = [](absl::string_view why) {
    return absl::DataLossError(absl::StrCat("not a shapeid MLP classifier: ", why));
  };
  ByteReader reader;
  SHAPEID_RETURN_IF_ERROR(OpenVersionedFile(bytes, absl::string_view(kMagic, sizeof(kMagic)),
                                            kFormatVersion, "MLP classifier", reader));
  uint32_t dimension = 0, layers = 0;
  if (!reader.U32(dimension) || dimension < 1 || dimension > kMaxDimension) {
    return bad("dimension out of range");
  }
  if (!reader.U32(layers) || layers < 1 || layers > kMaxLayers) return bad("layers out of range");
  std::vector<int> units = {static_cast<int>(dimension)};
  int64_t parameters = 2 * int64_t{dimension};
  for (uint32_t l = 0; l < layers; ++l) {
    uint32_t out = 0;
    if (!reader.U32(out) || out < 1 || out > kMaxUnits) return bad("layer units out of range");
    parameters += int64_t{units.back()} * out + out;
    units.push_back(static_cast<int>(out));
  }
  // Sizes first: nothing is allocated that the bytes left could not fill.
  if (parameters > kMaxParameters || static_cast<int64_t>(reader.left()) != 4 * parameters) {
    return bad("sizes do not match the length");
  }
  MlpClassifier net;
  net.dimension_ = static_cast<int>(dimension);
  net.offset_.resize(dimension);
  net.scale_.resize(dimension);
  if (!reader.Floats(net.offset_.data(), dimension) ||
      !reader.Floats(net.scale_.data(), dimension)) {
    return bad("a non-finite value");
  }
  for (uint32_t l = 0; l < layers; ++l) {
    Matrix w(units[l], units[l + 1]);
    Eigen::RowVectorXf b(units[l + 1]);
    if (!reader.Floats(w.data(), w.size()) || !reader.Floats(b.data(), b.size())) {
      return bad("a non-finite value");
    }
    net.weights_.push_back(std::move(w));
    net.biases_.push_back(std::move(b));
  }
  return net;
}

}  // namespace shapeid
