#ifndef SHAPEID_CORE_LEARNING_MLP_CLASSIFIER_H_
#define SHAPEID_CORE_LEARNING_MLP_CLASSIFIER_H_

// A small multilayer perceptron that learns classes from feature vectors (descriptors), fitted
// and answered in C++ with Eigen: the trained head of a gallery (core/gallery/gallery_head.h).
//
// Network: standardised input (each feature's training mean and spread), then `hidden` fully
// connected ReLU layers with dropout while fitting, then a linear layer to one logit a class;
// softmax gives probabilities. Fitting: softmax cross-entropy with label smoothing, AdamW,
// a cosine learning-rate schedule after one epoch of linear warm-up, shuffled mini-batches.
// Everything random (initial weights, shuffles, dropout) comes from SplitMix64 seeded by
// MlpOptions::seed, so one seed and one training set give the same classifier bit for bit on
// one machine.

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "Eigen/Core"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "absl/types/span.h"

namespace shapeid {

struct MlpOptions {
  std::vector<int> hidden = {256, 256};  // units of each hidden layer, in order
  int epochs = 30;
  int batch_size = 128;
  double learning_rate = 2e-3;  // AdamW's peak step
  double weight_decay = 1e-4;   // decoupled, on weights only
  double dropout = 0.25;        // of each hidden layer's units, while fitting
  double label_smoothing = 0.1;
  // Gaussian noise added to each standardised input while fitting (its standard deviation):
  // a regulariser against the signature of whatever simulated the training views.
  double input_noise = 0.0;
  uint64_t seed = 1;
};

// InvalidArgument naming the field for options no fit could use.
absl::Status ValidateMlpOptions(const MlpOptions& options);

// Rows of features, each with its class in [0, num_classes).
struct TrainingRows {
  int dimension = 0;
  int num_classes = 0;
  std::vector<float> features;  // rows * dimension, row after row
  std::vector<int> classes;     // one a row
  int64_t rows() const { return static_cast<int64_t>(classes.size()); }
};

// Called between mini-batches with the fraction of the fit done, in [0, 1]; a status that is
// not OK stops the fit, which returns it.
using FitProgress = std::function<absl::Status(double done)>;

class MlpClassifier {
 public:
  // An empty classifier: no classes; Probabilities refuses every query.
  MlpClassifier() = default;

  // Fits a classifier. InvalidArgument for bad options, no rows, a class out of range, a
  // features length that is not rows * dimension, or a non-finite feature. Cost: about
  // 6 * epochs * rows * (parameters) floating-point operations, on the calling thread.
  static absl::StatusOr<MlpClassifier> Fit(const TrainingRows& rows, const MlpOptions& options,
                                           const FitProgress& progress = nullptr);

  // Weights and biases of a network over `dimension` features with `hidden` layers and
  // `classes` outputs: what Fit makes and parameters() counts.
  static int64_t ParametersFor(int dimension, const std::vector<int>& hidden, int classes);

  int dimension() const { return dimension_; }
  int num_classes() const { return biases_.empty() ? 0 : static_cast<int>(biases_.back().size()); }
  // Weights and biases of every layer.
  int64_t parameters() const;
  int64_t memory_bytes() const { return parameters() * 4 + dimension_ * 8 + 256; }

  // Class probabilities for each of `features`' rows (dimension() floats each), averaged over
  // the rows: `features` holds one query's vectors (a descriptor and its pose variants).
  // InvalidArgument for a length that is not a positive multiple of dimension().
  absl::StatusOr<std::vector<float>> Probabilities(absl::Span<const float> features) const;

  // A versioned, checksummed little-endian encoding; Parse(Serialize()) answers bit for bit
  // as this classifier does.
  std::string Serialize() const;
  // DataLoss for bytes that are not a classifier this build can read (bad magic, version,
  // sizes, checksum, or non-finite values); never crashes or allocates beyond what the bytes
  // could describe.
  static absl::StatusOr<MlpClassifier> Parse(absl::string_view bytes);

 private:
  using Matrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

  // Logits of `input` (rows of standardised features): the network without dropout.
  Matrix Logits(const Matrix& input) const;

  int dimension_ = 0;
  Eigen::VectorXf offset_;       // subtracted from each feature ...
  Eigen::VectorXf scale_;        // ... then multiplied by this
  std::vector<Matrix> weights_;  // layer l: inputs x outputs
  std::vector<Eigen::RowVectorXf> biases_;
};

}  // namespace shapeid

#endif  // SHAPEID_CORE_LEARNING_MLP_CLASSIFIER_H_
