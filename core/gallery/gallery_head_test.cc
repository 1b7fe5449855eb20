#include "core/gallery/gallery_head.h"

#include <memory>
#include <string>
#include <vector>

#include "core/binary_codec.h"
#include "core/gallery/gallery.h"
#include "core/gallery/gallery_snapshot.h"
#include "core/testing/gallery_shapes.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using gallery_testing::Box;
using gallery_testing::Line;
using gallery_testing::Sphere;
using ::testing::HasSubstr;

HeadOptions FastHead() {
  HeadOptions options;
  options.mlp.hidden = {32};
  options.mlp.epochs = 30;
  options.mlp.batch_size = 16;
  options.min_samples = 6;
  return options;
}

// Ten boxes, spheres and lines each (ids 1-30), with two augmented views each.
std::shared_ptr<Gallery> ShapesGallery(int per_label = 10) {
  GalleryOptions options;
  options.augment.views = 2;
  std::shared_ptr<Gallery> gallery = *Gallery::Create("shapes", options, GalleryLimits{}, nullptr);
  std::vector<LabeledCloud> samples;
  uint64_t id = 1;
  for (uint32_t seed = 1; seed <= static_cast<uint32_t>(per_label); ++seed) {
    samples.push_back({id++, "box", Box(seed)});
    samples.push_back({id++, "sphere", Sphere(seed)});
    samples.push_back({id++, "line", Line(seed)});
  }
  EXPECT_TRUE(gallery->Train(samples).ok());
  return gallery;
}

TEST(GalleryHeadTest, FitsOverEverySampleAndViewHoldingASliceOut) {
  const std::shared_ptr<Gallery> gallery = ShapesGallery();
  const std::shared_ptr<const GallerySnapshot> snapshot = gallery->Snapshot();
  HeadOptions options = FastHead();
  options.holdout_per_mille = 300;
  const absl::StatusOr<GalleryHead> head = FitGalleryHead(*snapshot, options);
  ASSERT_TRUE(head.ok()) << head.status();
  EXPECT_THAT(head->labels, ::testing::ElementsAre("box", "line", "sphere"));
  EXPECT_EQ(head->fitted_version, snapshot->version());
  EXPECT_EQ(head->fitted_samples + head->holdout_samples, 30);
  EXPECT_GT(head->holdout_samples, 0);
  EXPECT_EQ(head->fitted_rows + head->holdout_rows, snapshot->index().num_rows());
  EXPECT_GE(head->holdout_accuracy(), 0.9);  // three shapes no one confuses
  EXPECT_GT(head->fit_time, absl::ZeroDuration());
  // Deterministic: the same snapshot and options give the same head.
  EXPECT_EQ(FitGalleryHead(*snapshot, options)->classifier.Serialize(),
            head->classifier.Serialize());
}

TEST(GalleryHeadTest, ALargeGallerysFitReadsAboutMaxVectorsEveryOwnDescriptorFirst) {
  const std::shared_ptr<const GallerySnapshot> snapshot = ShapesGallery()->Snapshot();
  ASSERT_EQ(snapshot->index().num_rows(), 90);  // 30 samples, 2 views each
  HeadOptions options = FastHead();
  options.max_vectors = 45;  // the 30 own descriptors and about 15 of the 60 views
  const GalleryHead head = *FitGalleryHead(*snapshot, options);
  const int64_t read = head.fitted_rows + head.holdout_rows;
  EXPECT_GE(read, 30);
  EXPECT_LE(read, 60);
  EXPECT_EQ(FitVectors(*snapshot, options), 45);
  EXPECT_EQ(FitGalleryHead(*snapshot, options)->fitted_rows, head.fitted_rows);  // same draw
  options.max_vectors = 15;  // fewer than the samples: half of the own descriptors, no view
  const GalleryHead fewer = *FitGalleryHead(*snapshot, options);
  EXPECT_GT(fewer.fitted_rows + fewer.holdout_rows, 5);
  EXPECT_LT(fewer.fitted_rows + fewer.holdout_rows, 25);
  options.max_vectors = 1;
  EXPECT_EQ(FitGalleryHead(*snapshot, options).status().code(), absl::StatusCode::kInvalidArgument);
}

TEST(GalleryHeadTest, ASmallOrOneLabelGalleryIsLeftToKnn) {
  const std::shared_ptr<Gallery> gallery = ShapesGallery(1);
  HeadOptions options = FastHead();
  options.min_samples = 20;
  const absl::Status status = FitGalleryHead(*gallery->Snapshot(), options).status();
  EXPECT_EQ(status.code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(status.message(), HasSubstr("3 samples of 3 labels"));
  ASSERT_TRUE(gallery->RemoveSamples({}, {"sphere", "line"}).ok());
  options.min_samples = 2;
  EXPECT_THAT(FitGalleryHead(*gallery->Snapshot(), options).status().message(),
              HasSubstr("1 samples of 1 labels"));
}

TEST(GalleryHeadTest, AnswersClassifyOnlyWhileItsLabelsAreTheGallerys) {
  const std::shared_ptr<Gallery> gallery = ShapesGallery();
  const uint64_t version = gallery->Snapshot()->version();
  EXPECT_FALSE(gallery->Snapshot()->Classify(Sphere(99))->by_head);
  auto head =
      std::make_shared<const GalleryHead>(*FitGalleryHead(*gallery->Snapshot(), FastHead()));
  ASSERT_TRUE(gallery->SetHead(head).ok());
  const std::shared_ptr<const GallerySnapshot> with_head = gallery->Snapshot();
  EXPECT_EQ(with_head->version(), version);  // derived state: the samples did not change
  EXPECT_EQ(with_head->head(), head);
  EXPECT_TRUE(with_head->head_answers());
  const GalleryClassification answer = *with_head->Classify(Sphere(99));
  EXPECT_TRUE(answer.by_head);
  EXPECT_EQ(answer.label, "sphere");
  EXPECT_GT(answer.confidence, 0.5);
  EXPECT_FALSE(answer.knn.neighbors.empty());  // the neighbors come with the head's answer
  // More of a known label: the head still answers. A new label: it cannot, kNN does.
  ASSERT_TRUE(gallery->Train({{0, "box", Box(77)}}).ok());
  EXPECT_TRUE(gallery->Snapshot()->Classify(Box(98))->by_head);
  ASSERT_TRUE(gallery->Train({{0, "cup", Sphere(55)}}).ok());
  EXPECT_EQ(gallery->Snapshot()->head(), head);
  EXPECT_FALSE(gallery->Snapshot()->head_answers());
  EXPECT_FALSE(gallery->Snapshot()->Classify(Box(98))->by_head);
  // The label removed again: the head's labels are the gallery's once more.
  ASSERT_TRUE(gallery->RemoveSamples({}, {"cup"}).ok());
  EXPECT_TRUE(gallery->Snapshot()->head_answers());
  ASSERT_TRUE(gallery->SetHead(nullptr).ok());
  EXPECT_FALSE(gallery->Snapshot()->Classify(Box(98))->by_head);
}

TEST(GalleryHeadTest, AnUnknownAnswerStaysUnknown) {
  GalleryOptions options;
  options.reject_distance = 1e-9;  // everything is too far
  std::shared_ptr<Gallery> gallery = *Gallery::Create("far", options, GalleryLimits{}, nullptr);
  std::vector<LabeledCloud> samples;
  for (uint32_t seed = 1; seed <= 4; ++seed) {
    samples.push_back({0, "box", Box(seed)});
    samples.push_back({0, "line", Line(seed)});
  }
  ASSERT_TRUE(gallery->Train(samples).ok());
  ASSERT_TRUE(gallery
                  ->SetHead(std::make_shared<const GalleryHead>(
                      *FitGalleryHead(*gallery->Snapshot(), FastHead())))
                  .ok());
  const GalleryClassification answer = *gallery->Snapshot()->Classify(Box(50));
  EXPECT_TRUE(answer.unknown);
  EXPECT_FALSE(answer.by_head);
  EXPECT_EQ(answer.label, kUnknownLabel);
}

TEST(GalleryHeadTest, ParseOfSerializeIsEqualAndRefusesDamage) {
  const GalleryHead head = *FitGalleryHead(*ShapesGallery()->Snapshot(), FastHead());
  const std::string bytes = head.Serialize();
  const absl::StatusOr<GalleryHead> parsed = GalleryHead::Parse(bytes);
  ASSERT_TRUE(parsed.ok()) << parsed.status();
  EXPECT_EQ(parsed->labels, head.labels);
  EXPECT_EQ(parsed->fitted_version, head.fitted_version);
  EXPECT_EQ(parsed->holdout_right, head.holdout_right);
  EXPECT_EQ(parsed->fit_time, absl::Microseconds(absl::ToInt64Microseconds(head.fit_time)));
  EXPECT_EQ(parsed->Serialize(), bytes);
  EXPECT_EQ(GalleryHead::Parse(bytes.substr(0, 20)).status().code(), absl::StatusCode::kDataLoss);
  std::string flipped = bytes;
  flipped[40] ^= 1;
  EXPECT_THAT(GalleryHead::Parse(flipped).status().message(), HasSubstr("checksum"));
  EXPECT_THAT(GalleryHead::Parse("SHPDMLP").status().message(), HasSubstr("no magic"));
}

}  // namespace
}  // namespace shapeid
