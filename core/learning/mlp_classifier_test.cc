#include "core/learning/mlp_classifier.h"

#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include "core/binary_codec.h"
#include "core/random.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;

// Points on three concentric rings in the plane (radius 1, 2, 3, class = ring), with noise:
// no linear classifier separates them; 2 noise features ride along.
TrainingRows Rings(int per_class, uint64_t seed) {
  SplitMix64 random(seed);
  TrainingRows rows;
  rows.dimension = 4;
  rows.num_classes = 3;
  for (int i = 0; i < per_class * 3; ++i) {
    const int ring = i % 3;
    const double angle = 2 * M_PI * random.Uniform();
    const double radius = ring + 1 + 0.3 * (random.Uniform() - 0.5);
    rows.features.push_back(static_cast<float>(radius * std::cos(angle)));
    rows.features.push_back(static_cast<float>(radius * std::sin(angle)));
    rows.features.push_back(static_cast<float>(random.Uniform()));
    rows.features.push_back(static_cast<float>(1000 + 50 * random.Uniform()));  // unscaled
    rows.classes.push_back(ring);
  }
  return rows;
}

MlpOptions Small() {
  MlpOptions options;
  options.hidden = {32, 32};
  options.epochs = 100;
  options.batch_size = 32;
  options.dropout = 0.1;
  return options;
}

int Predict(const MlpClassifier& net, const float* row) {
  const std::vector<float> p = *net.Probabilities({row, static_cast<size_t>(net.dimension())});
  return static_cast<int>(std::max_element(p.begin(), p.end()) - p.begin());
}

double Accuracy(const MlpClassifier& net, const TrainingRows& rows) {
  int right = 0;
  for (int64_t r = 0; r < rows.rows(); ++r) {
    right += Predict(net, &rows.features[r * rows.dimension]) == rows.classes[r];
  }
  return static_cast<double>(right) / rows.rows();
}

TEST(MlpClassifierTest, LearnsClassesNoLinearRuleSeparatesAndAnswersUnseenRows) {
  const absl::StatusOr<MlpClassifier> net = MlpClassifier::Fit(Rings(200, 1), Small());
  ASSERT_TRUE(net.ok()) << net.status();
  EXPECT_EQ(net->dimension(), 4);
  EXPECT_EQ(net->num_classes(), 3);
  EXPECT_EQ(net->parameters(), (4 * 32 + 32) + (32 * 32 + 32) + (32 * 3 + 3));
  EXPECT_EQ(MlpClassifier::ParametersFor(4, {32, 32}, 3), net->parameters());
  EXPECT_GT(Accuracy(*net, Rings(200, 1)), 0.95) << "training rows";
  EXPECT_GT(Accuracy(*net, Rings(100, 2)), 0.95);
}

TEST(MlpClassifierTest, ProbabilitiesAreADistributionAveragedOverTheQueryRows) {
  const MlpClassifier net = *MlpClassifier::Fit(Rings(100, 1), Small());
  const TrainingRows query = Rings(1, 3);  // one row of each ring
  const std::vector<float> all = *net.Probabilities(query.features);
  ASSERT_EQ(all.size(), 3u);
  float sum = 0;
  std::vector<float> mean(3, 0.0f);
  for (int r = 0; r < 3; ++r) {
    const std::vector<float> one =
        *net.Probabilities({&query.features[4 * r], static_cast<size_t>(4)});
    for (int c = 0; c < 3; ++c) mean[c] += one[c] / 3;
  }
  for (int c = 0; c < 3; ++c) {
    EXPECT_GE(all[c], 0.0f);
    EXPECT_NEAR(all[c], mean[c], 1e-6);
    sum += all[c];
  }
  EXPECT_NEAR(sum, 1.0f, 1e-5);
  EXPECT_EQ(net.Probabilities({}).status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(net.Probabilities({query.features.data(), 5}).status().code(),
            absl::StatusCode::kInvalidArgument);
}

TEST(MlpClassifierTest, OneSeedGivesTheSameClassifierBitForBitAnotherAnother) {
  const TrainingRows rows = Rings(50, 1);
  MlpOptions options = Small();
  options.epochs = 5;
  const std::string first = MlpClassifier::Fit(rows, options)->Serialize();
  EXPECT_EQ(MlpClassifier::Fit(rows, options)->Serialize(), first);
  options.seed = 2;
  EXPECT_NE(MlpClassifier::Fit(rows, options)->Serialize(), first);
}

TEST(MlpClassifierTest, ParseOfSerializeAnswersBitForBit) {
  const MlpClassifier net = *MlpClassifier::Fit(Rings(50, 1), Small());
  const std::string bytes = net.Serialize();
  EXPECT_EQ(static_cast<int64_t>(bytes.size()),
            8 + 4 * 3 + 4 * 3 + 4 * (2 * 4 + net.parameters()) + 4);
  const absl::StatusOr<MlpClassifier> parsed = MlpClassifier::Parse(bytes);
  ASSERT_TRUE(parsed.ok()) << parsed.status();
  const TrainingRows query = Rings(5, 9);
  EXPECT_EQ(*parsed->Probabilities(query.features), *net.Probabilities(query.features));
  EXPECT_EQ(parsed->Serialize(), bytes);
}

TEST(MlpClassifierTest, ParseRefusesWhatIsNotAWholeClassifier) {
  const std::string bytes = MlpClassifier::Fit(Rings(20, 1), Small())->Serialize();
  auto code = [](const std::string& b) { return MlpClassifier::Parse(b).status().code(); };
  EXPECT_EQ(code(""), absl::StatusCode::kDataLoss);
  EXPECT_EQ(code(bytes.substr(0, bytes.size() - 1)), absl::StatusCode::kDataLoss);
  EXPECT_EQ(code(bytes + "x"), absl::StatusCode::kDataLoss);
  std::string flipped = bytes;
  flipped[bytes.size() / 2] ^= 0x10;
  EXPECT_THAT(MlpClassifier::Parse(flipped).status().message(), HasSubstr("checksum"));
  std::string version = bytes.substr(0, bytes.size() - 4);
  version[8] = 9;
  const uint32_t version_crc = Crc32Of(version);
  for (int i = 0; i < 4; ++i) version.push_back(static_cast<char>((version_crc >> (8 * i)) & 0xff));
  EXPECT_THAT(MlpClassifier::Parse(version).status().message(), HasSubstr("format version 9"));
  // A NaN with a checksum that matches it: refused for the value, not the checksum.
  std::string nan = bytes.substr(0, bytes.size() - 4);
  const float not_a_number = std::numeric_limits<float>::quiet_NaN();
  std::memcpy(&nan[8 + 12 + 12], &not_a_number, 4);
  const uint32_t crc = Crc32Of(nan);
  for (int i = 0; i < 4; ++i) nan.push_back(static_cast<char>((crc >> (8 * i)) & 0xff));
  EXPECT_THAT(MlpClassifier::Parse(nan).status().message(), HasSubstr("non-finite"));
}

TEST(MlpClassifierTest, FitRefusesRowsItCannotLearnFrom) {
  TrainingRows rows = Rings(5, 1);
  auto message = [](const TrainingRows& r, const MlpOptions& o) {
    return std::string(MlpClassifier::Fit(r, o).status().message());
  };
  EXPECT_THAT(message(TrainingRows{4, 3, {}, {}}, Small()), HasSubstr("no rows"));
  TrainingRows bad_class = rows;
  bad_class.classes[3] = 3;
  EXPECT_THAT(message(bad_class, Small()), HasSubstr("row 3: class 3 not in [0, 3)"));
  TrainingRows not_finite = rows;
  not_finite.features[4 * 2 + 1] = std::numeric_limits<float>::infinity();
  EXPECT_THAT(message(not_finite, Small()), HasSubstr("row 2: feature 1 is not finite"));
  TrainingRows short_rows = rows;
  short_rows.features.pop_back();
  EXPECT_THAT(message(short_rows, Small()), HasSubstr("not rows * dimension"));
  MlpOptions options = Small();
  options.hidden = {0};
  EXPECT_THAT(message(rows, options), HasSubstr("hidden layer units"));
  options = Small();
  options.dropout = 1;
  EXPECT_THAT(message(rows, options), HasSubstr("dropout"));
}

TEST(MlpClassifierTest, ProgressSeesTheFitAdvanceAndCanStopIt) {
  const TrainingRows rows = Rings(20, 1);
  std::vector<double> seen;
  ASSERT_TRUE(MlpClassifier::Fit(rows, Small(), [&](double done) {
                seen.push_back(done);
                return absl::OkStatus();
              }).ok());
  ASSERT_FALSE(seen.empty());
  EXPECT_EQ(seen.front(), 0.0);
  EXPECT_EQ(seen.back(), 1.0);
  EXPECT_TRUE(std::is_sorted(seen.begin(), seen.end()));
  int calls = 0;
  const absl::Status stopped =
      MlpClassifier::Fit(rows, Small(), [&](double) {
        return ++calls == 3 ? absl::CancelledError("stop") : absl::OkStatus();
      }).status();
  EXPECT_EQ(stopped.code(), absl::StatusCode::kCancelled);
  EXPECT_EQ(calls, 3);
}

TEST(MlpClassifierTest, AConstantFeatureIsIgnoredNotBlownUp) {
  TrainingRows rows = Rings(50, 1);
  for (int64_t r = 0; r < rows.rows(); ++r) rows.features[r * 4 + 2] = 7.0f;
  const MlpClassifier net = *MlpClassifier::Fit(rows, Small());
  std::vector<float> query = {1, 0, 1e30f, 1000};  // the constant feature far off: no effect
  std::vector<float> same = {1, 0, 7, 1000};
  EXPECT_EQ(*net.Probabilities(query), *net.Probabilities(same));
}

}  // namespace
}  // namespace shapeid
