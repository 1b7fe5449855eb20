#include "core/gallery/gallery.h"

#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "core/descriptor_registry.h"
#include "core/gallery/gallery_registry.h"
#include "core/gallery/gallery_store.h"
#include "core/testing/gallery_shapes.h"
#include "core/version.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using gallery_testing::Box;
using gallery_testing::BoxWithNaN;
using gallery_testing::Line;
using gallery_testing::Sphere;
using ::testing::AllOf;
using ::testing::ElementsAre;
using ::testing::HasSubstr;
using ::testing::Pair;

std::shared_ptr<Gallery> MakeGallery(GalleryOptions options = {}, GalleryLimits limits = {},
                                     std::shared_ptr<GalleryStore> store = nullptr) {
  absl::StatusOr<std::shared_ptr<Gallery>> g =
      Gallery::Create("shapes", options, limits, std::move(store));
  EXPECT_TRUE(g.ok()) << g.status();
  return *g;
}

// Three boxes (ids 1-3), three spheres (4-6), three lines (7-9), seeds 1-3.
StoredGallery EmptyStored(std::string name) {
  StoredGallery stored;
  stored.name = std::move(name);
  return stored;
}

std::vector<LabeledCloud> ThreeShapes() {
  std::vector<LabeledCloud> samples;
  uint64_t id = 1;
  for (uint32_t seed = 1; seed <= 3; ++seed) samples.push_back({id++, "box", Box(seed)});
  for (uint32_t seed = 1; seed <= 3; ++seed) samples.push_back({id++, "sphere", Sphere(seed)});
  for (uint32_t seed = 1; seed <= 3; ++seed) samples.push_back({id++, "line", Line(seed)});
  return samples;
}

TEST(GalleryTest, CreateCanonicalisesTheSpec) {
  auto g = MakeGallery();
  auto snap = g->Snapshot();
  auto expected = CreateDescriptor(kDefaultDescriptorSpec);
  ASSERT_TRUE(expected.ok());
  EXPECT_EQ(snap->options().descriptor_spec, (*expected)->spec().ToString());
  EXPECT_NE(snap->options().descriptor_spec, kDefaultDescriptorSpec);  // parameters filled in
  EXPECT_EQ(snap->index().dimension(), static_cast<int>((*expected)->dimension()));
  EXPECT_EQ(snap->name(), "shapes");
  EXPECT_EQ(snap->version(), 0u);
  EXPECT_EQ(snap->num_samples(), 0);
  EXPECT_EQ(snap->created(), snap->updated());
}

TEST(GalleryTest, CreateRejectsBadSpecWithTheRegistrysMessage) {
  GalleryOptions options;
  options.descriptor_spec = "nosuch:x=1";
  auto g = Gallery::Create("g", options, {}, nullptr);
  ASSERT_EQ(g.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(g.status(), CreateDescriptor("nosuch:x=1").status());

  options.descriptor_spec = "rphsd:bins=-3";
  g = Gallery::Create("g", options, {}, nullptr);
  EXPECT_EQ(g.status(), CreateDescriptor("rphsd:bins=-3").status());

  options = {};
  options.knn.k = 0;
  EXPECT_EQ(Gallery::Create("g", options, {}, nullptr).status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(Gallery::Create("bad name", {}, {}, nullptr).status().code(),
            absl::StatusCode::kInvalidArgument);
}

TEST(GalleryTest, TrainPublishesOneSnapshotPerBatch) {
  auto g = MakeGallery();
  auto result = g->Train(ThreeShapes());
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_THAT(result->ids, ElementsAre(1, 2, 3, 4, 5, 6, 7, 8, 9));
  EXPECT_EQ(result->version, 1u);
  auto snap = g->Snapshot();
  EXPECT_EQ(snap->num_samples(), 9);
  EXPECT_EQ(snap->version(), 1u);
  EXPECT_GE(snap->updated(), snap->created());
  EXPECT_THAT(snap->LabelCounts(), ElementsAre(Pair("box", 3), Pair("line", 3), Pair("sphere", 3)));
  EXPECT_THAT(snap->IdsWithLabel("sphere"), ElementsAre(4, 5, 6));
  EXPECT_THAT(snap->IdsWithLabel("cone"), ElementsAre());
}

TEST(GalleryTest, ClassifyGivesNeighborsVotesAndConfidence) {
  GalleryOptions options;
  // A frame without pose variants, so the distance below is the plain one (with the
  // default box frame it is the least over the query's variants).
  options.descriptor_spec = "dfsd:frame=axes";
  options.knn.k = 5;
  auto g = MakeGallery(options);
  ASSERT_TRUE(g->Train(ThreeShapes()).ok());
  auto snap = g->Snapshot();

  const PointCloud query = Sphere(42);
  auto answer = snap->Classify(query);
  ASSERT_TRUE(answer.ok()) << answer.status();
  EXPECT_EQ(answer->label, "sphere");
  EXPECT_FALSE(answer->unknown);
  // The three spheres are the three nearest; two others fill k = 5.
  ASSERT_EQ(answer->knn.neighbors.size(), 5u);
  for (int i = 0; i < 3; ++i) EXPECT_EQ(answer->knn.neighbors[i].label, "sphere");
  for (int i = 3; i < 5; ++i) EXPECT_NE(answer->knn.neighbors[i].label, "sphere");
  EXPECT_DOUBLE_EQ(answer->confidence, 3.0 / 5.0);
  EXPECT_EQ(answer->confidence, answer->knn.confidence);
  ASSERT_FALSE(answer->knn.votes.empty());
  EXPECT_EQ(answer->knn.votes[0].label, "sphere");
  EXPECT_EQ(answer->knn.votes[0].weight, 3.0);
  double total = 0;
  for (const ClassVote& v : answer->knn.votes) total += v.weight;
  EXPECT_EQ(total, 5.0);

  // Distances are Euclidean between the descriptors (no scaling by default).
  auto q = snap->Describe(query);
  ASSERT_TRUE(q.ok());
  const Neighbor& nearest = answer->knn.neighbors[0];
  auto clouds = ThreeShapes();
  auto x = snap->Describe(clouds[nearest.id - 1].cloud);
  ASSERT_TRUE(x.ok());
  double sum = 0;
  for (size_t j = 0; j < q->size(); ++j) sum += std::pow((*q)[j] - (*x)[j], 2);
  EXPECT_NEAR(nearest.distance, std::sqrt(sum), 1e-4 * (1 + std::sqrt(sum)));
  EXPECT_GE(answer->describe_time, absl::ZeroDuration());
  EXPECT_GE(answer->search_time, absl::ZeroDuration());

  // Each shape is recognized.
  EXPECT_EQ(snap->Classify(Box(77))->label, "box");
  EXPECT_EQ(snap->Classify(Line(77))->label, "line");
}

TEST(GalleryTest, ClassifyFeaturesMatchesClassify) {
  auto g = MakeGallery();
  ASSERT_TRUE(g->Train(ThreeShapes()).ok());
  auto snap = g->Snapshot();
  auto features = snap->Describe(Line(5));
  ASSERT_TRUE(features.ok());
  auto a = snap->ClassifyFeatures(*features);
  auto b = snap->Classify(Line(5));
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_EQ(a->label, b->label);
  EXPECT_EQ(a->knn.neighbors[0].id, b->knn.neighbors[0].id);
  EXPECT_EQ(a->describe_time, absl::ZeroDuration());
  EXPECT_EQ(snap->ClassifyFeatures(std::vector<float>(3, 0.f)).status().code(),
            absl::StatusCode::kInvalidArgument);
}

TEST(GalleryTest, RejectDistanceAnswersUnknown) {
  // Nearest distance of a sphere query, measured in a gallery without rejection.
  auto plain = MakeGallery();
  ASSERT_TRUE(plain->Train(ThreeShapes()).ok());
  auto measured = plain->Snapshot()->Classify(Sphere(42));
  ASSERT_TRUE(measured.ok());
  const double d = measured->knn.neighbors[0].distance;
  ASSERT_GT(d, 0);

  GalleryOptions options;
  options.reject_distance = d / 2;
  auto strict = MakeGallery(options);
  ASSERT_TRUE(strict->Train(ThreeShapes()).ok());
  auto rejected = strict->Snapshot()->Classify(Sphere(42));
  ASSERT_TRUE(rejected.ok());
  EXPECT_TRUE(rejected->unknown);
  EXPECT_EQ(rejected->label, "unknown");
  EXPECT_EQ(rejected->confidence, 0.0);
  EXPECT_EQ(rejected->knn.label, "sphere");  // the raw result is kept
  EXPECT_EQ(rejected->knn.neighbors[0].distance, d);

  options.reject_distance = d * 2;
  auto lenient = MakeGallery(options);
  ASSERT_TRUE(lenient->Train(ThreeShapes()).ok());
  auto accepted = lenient->Snapshot()->Classify(Sphere(42));
  ASSERT_TRUE(accepted.ok());
  EXPECT_FALSE(accepted->unknown);
  EXPECT_EQ(accepted->label, "sphere");
}

TEST(GalleryTest, ClassifyOnEmptyGalleryIsFailedPrecondition) {
  auto g = MakeGallery();
  auto answer = g->Snapshot()->Classify(Box(1));
  EXPECT_EQ(answer.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(answer.status().message(), HasSubstr("'shapes'"));
}

TEST(GalleryTest, ClassifyPassesCloudErrorsThrough) {
  auto g = MakeGallery();
  ASSERT_TRUE(g->Train(ThreeShapes()).ok());
  auto snap = g->Snapshot();
  const PointCloud bad = BoxWithNaN(1, 17);
  EXPECT_EQ(snap->Classify(bad).status(), snap->shared_descriptor()->Compute(bad).status());
  EXPECT_THAT(snap->Classify(bad).status().message(), HasSubstr("point 17"));
  auto big = snap->Classify(Box(1), CloudLimits{100});
  EXPECT_EQ(big.status().code(), absl::StatusCode::kResourceExhausted);
  EXPECT_THAT(big.status().message(), AllOf(HasSubstr("256"), HasSubstr("100")));
}

TEST(GalleryTest, BatchWithBadSampleFailsWholeAndNamesSampleAndPoint) {
  auto g = MakeGallery();
  ASSERT_TRUE(g->Train({{1, "box", Box(1)}}).ok());
  const auto before = g->Snapshot();

  TrainBatch batch = g->NewBatch();
  ASSERT_TRUE(batch.AddSample(10, "box", Box(2)).ok());
  ASSERT_TRUE(batch.AddSample(11, "sphere", Sphere(2)).ok());
  const absl::Status bad = batch.AddSample(12, "box", BoxWithNaN(3, 41));
  EXPECT_EQ(bad.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(bad.message(), AllOf(HasSubstr("sample 2"), HasSubstr("point 41")));
  // Poisoned: a later good sample and the commit report the first error.
  EXPECT_EQ(batch.AddSample(13, "line", Line(1)), bad);
  EXPECT_EQ(batch.Commit().status(), bad);

  EXPECT_EQ(g->Snapshot(), before);
  EXPECT_EQ(g->Snapshot()->num_samples(), 1);
  EXPECT_FALSE(g->Snapshot()->Contains(10));

  // Train() stops at the same sample.
  auto train = g->Train({{20, "box", Box(2)}, {21, "box", Box(4)}, {22, "box", BoxWithNaN(5, 0)}});
  EXPECT_THAT(train.status().message(), AllOf(HasSubstr("sample 2"), HasSubstr("point 0")));
  EXPECT_EQ(g->Snapshot(), before);
}

TEST(GalleryTest, BadLabelsAndCloudsFailAtTheirSample) {
  auto g = MakeGallery();
  TrainBatch batch = g->NewBatch();
  EXPECT_THAT(batch.AddSample(0, "unknown", Box(1)).message(),
              AllOf(HasSubstr("sample 0"), HasSubstr("reserved")));
  TrainBatch b2 = g->NewBatch();
  ASSERT_TRUE(b2.AddSample(0, "box", Box(1)).ok());
  EXPECT_THAT(b2.AddSample(0, "", Box(1)).message(), HasSubstr("sample 1: label is empty"));
  TrainBatch b3 = g->NewBatch();
  const absl::Status few = b3.AddSample(0, "box", PointCloud({{0, 0, 0}, {1, 1, 1}}));
  EXPECT_EQ(few.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(few.message(), HasSubstr("at least 3"));
  EXPECT_EQ(g->Snapshot()->num_samples(), 0);
}

TEST(GalleryTest, DroppedBatchLeavesNoTrace) {
  auto store = std::make_shared<InMemoryGalleryStore>();
  ASSERT_TRUE(store->SaveGallery(EmptyStored("shapes")).ok());
  auto g = MakeGallery({}, {}, store);
  const auto before = g->Snapshot();
  {
    TrainBatch batch = g->NewBatch();
    ASSERT_TRUE(batch.AddSample(5, "box", Box(1)).ok());
    ASSERT_TRUE(batch.AddSample(0, "box", Box(2)).ok());
  }
  EXPECT_EQ(g->Snapshot(), before);
  EXPECT_EQ(store->NumSamples("shapes"), 0);
  // The dropped batch reserved nothing: id 5 is free and assignment starts afresh.
  auto result = g->Train({{5, "box", Box(1)}, {0, "box", Box(2)}});
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_THAT(result->ids, ElementsAre(5, kFirstAssignedId));
}

TEST(GalleryTest, DuplicateIdsFailTheBatch) {
  auto g = MakeGallery();
  ASSERT_TRUE(g->Train({{7, "box", Box(1)}}).ok());

  auto in_gallery = g->Train({{8, "box", Box(2)}, {7, "sphere", Sphere(1)}});
  EXPECT_EQ(in_gallery.status().code(), absl::StatusCode::kAlreadyExists);
  EXPECT_THAT(in_gallery.status().message(),
              AllOf(HasSubstr("sample 1"), HasSubstr("id 7"), HasSubstr("'shapes'")));

  auto in_batch = g->Train({{9, "box", Box(2)}, {9, "sphere", Sphere(1)}});
  EXPECT_EQ(in_batch.status().code(), absl::StatusCode::kAlreadyExists);
  EXPECT_THAT(in_batch.status().message(), AllOf(HasSubstr("id 9"), HasSubstr("twice")));
  EXPECT_EQ(g->Snapshot()->num_samples(), 1);

  // Two open batches claim id 20: the first to commit wins, the other fails whole.
  TrainBatch a = g->NewBatch();
  TrainBatch b = g->NewBatch();
  ASSERT_TRUE(a.AddSample(20, "box", Box(3)).ok());
  ASSERT_TRUE(b.AddSample(21, "box", Box(4)).ok());
  ASSERT_TRUE(b.AddSample(20, "sphere", Sphere(4)).ok());
  ASSERT_TRUE(a.Commit().ok());
  auto late = b.Commit();
  EXPECT_EQ(late.status().code(), absl::StatusCode::kAlreadyExists);
  EXPECT_THAT(late.status().message(), HasSubstr("sample 1: sample id 20"));
  EXPECT_FALSE(g->Snapshot()->Contains(21));
  EXPECT_EQ(b.Commit().status().code(), absl::StatusCode::kFailedPrecondition);  // spent
}

TEST(GalleryTest, AssignedIdsNeverCollideAndAreNotReused) {
  constexpr uint64_t kA = kFirstAssignedId;
  auto g = MakeGallery();
  auto r1 = g->Train({{0, "box", Box(1)}, {0, "box", Box(2)}});
  ASSERT_TRUE(r1.ok());
  EXPECT_THAT(r1->ids, ElementsAre(kA, kA + 1));
  auto r2 = g->Train({{0, "box", Box(3)}, {100, "sphere", Sphere(1)}, {0, "line", Line(1)}});
  ASSERT_TRUE(r2.ok());
  EXPECT_THAT(r2->ids, ElementsAre(kA + 2, 100, kA + 3));
  ASSERT_TRUE(g->RemoveSamples({kA + 2, kA + 3}).ok());
  auto r3 = g->Train({{0, "box", Box(4)}});
  ASSERT_TRUE(r3.ok());
  EXPECT_THAT(r3->ids, ElementsAre(kA + 4));  // removed ids are not handed out again
  EXPECT_EQ(g->Snapshot()->next_assigned_id(), kA + 5);
  // The largest client id is accepted; assigned-range ids are refused, naming the range.
  EXPECT_TRUE(g->Train({{kA - 1, "box", Box(5)}}).ok());
  for (uint64_t reserved : {kA, kA + 77, UINT64_MAX}) {
    auto r = g->Train({{reserved, "box", Box(6)}});
    EXPECT_EQ(r.status().code(), absl::StatusCode::kInvalidArgument);
    EXPECT_THAT(r.status().message(), AllOf(HasSubstr("sample 0"), HasSubstr("reserved"),
                                            HasSubstr("9223372036854775807")));
  }
}

TEST(GalleryTest, RemoveByIdAndByLabel) {
  auto store = std::make_shared<InMemoryGalleryStore>();
  ASSERT_TRUE(store->SaveGallery(EmptyStored("shapes")).ok());
  auto g = MakeGallery({}, {}, store);
  ASSERT_TRUE(g->Train(ThreeShapes()).ok());
  EXPECT_EQ(store->NumSamples("shapes"), 9);

  auto removed = g->RemoveSamples({1, 4, 4});  // duplicates ignored
  ASSERT_TRUE(removed.ok());
  EXPECT_EQ(*removed, 2);
  EXPECT_EQ(g->Snapshot()->version(), 2u);
  EXPECT_THAT(g->Snapshot()->LabelCounts(),
              ElementsAre(Pair("box", 2), Pair("line", 3), Pair("sphere", 2)));

  const auto before = g->Snapshot();
  auto missing = g->RemoveSamples({2, 999});
  EXPECT_EQ(missing.status().code(), absl::StatusCode::kNotFound);
  EXPECT_THAT(missing.status().message(), HasSubstr("999"));
  EXPECT_EQ(g->Snapshot(), before);  // nothing removed, not even id 2

  auto by_label = g->RemoveSamples({}, {"line"});
  ASSERT_TRUE(by_label.ok());
  EXPECT_EQ(*by_label, 3);
  EXPECT_THAT(g->Snapshot()->LabelCounts(), ElementsAre(Pair("box", 2), Pair("sphere", 2)));
  EXPECT_FALSE(g->Snapshot()->Contains(7));
  EXPECT_EQ(store->NumSamples("shapes"), 4);
  EXPECT_EQ(g->RemoveSamples({}, {"line"}).status().code(), absl::StatusCode::kNotFound);
  EXPECT_EQ(g->Snapshot()->Classify(Line(9))->knn.neighbors[0].label != "line", true);

  auto none = g->RemoveSamples({});
  ASSERT_TRUE(none.ok());
  EXPECT_EQ(*none, 0);
}

// GalleryLimits::approximate: every commit and removal keeps the kNN index's inverted
// lists in step, and a gallery that shrinks below the threshold searches exactly again.
TEST(GalleryTest, ApproximateIndexFollowsCommitsAndRemovals) {
  GalleryLimits limits;
  limits.approximate.min_vectors = 64;
  auto g = MakeGallery({}, limits);
  std::vector<LabeledCloud> samples;
  for (uint32_t i = 0; i < 100; ++i) {
    samples.push_back({i + 1, i % 2 == 0 ? "box" : "sphere", i % 2 == 0 ? Box(i) : Sphere(i)});
  }
  ASSERT_TRUE(g->Train(absl::MakeConstSpan(samples).subspan(0, 40)).ok());
  EXPECT_FALSE(g->Snapshot()->index().approximate());
  ASSERT_TRUE(g->Train(absl::MakeConstSpan(samples).subspan(40)).ok());
  ASSERT_TRUE(g->Snapshot()->index().approximate());
  EXPECT_EQ(g->Snapshot()->index().approximate_filed_vectors(), 96);
  auto answer = g->Snapshot()->Classify(Box(2));
  ASSERT_TRUE(answer.ok()) << answer.status();
  EXPECT_TRUE(answer->knn.approximate);
  EXPECT_EQ(answer->label, "box");
  auto exact = g->Snapshot()->Classify(Box(2), {}, 0, SearchMode::kExact);
  ASSERT_TRUE(exact.ok());
  EXPECT_FALSE(exact->knn.approximate);

  ASSERT_TRUE(g->RemoveSamples({1, 2, 3, 4, 5}).ok());
  EXPECT_TRUE(g->Snapshot()->index().approximate());
  EXPECT_EQ(g->Snapshot()->index().approximate_filed_vectors(), 64);  // 91 kept, whole blocks
  std::vector<uint64_t> doomed;
  for (uint64_t id = 6; id <= 45; ++id) doomed.push_back(id);
  ASSERT_TRUE(g->RemoveSamples(doomed).ok());
  EXPECT_FALSE(g->Snapshot()->index().approximate());  // 55 < 64
}

TEST(GalleryTest, ApproximateIndexCanBeBuiltAfterRestore) {
  GalleryLimits limits;
  limits.approximate.min_vectors = 64;
  auto g = MakeGallery();
  std::vector<LabeledCloud> samples;
  for (uint32_t i = 0; i < 70; ++i) samples.push_back({0, "box", Box(i)});
  ASSERT_TRUE(g->Train(samples).ok());
  const StoredGallery stored = g->Snapshot()->ToStored();

  auto later = Gallery::Restore(stored, limits, nullptr, Gallery::ApproximateBuild::kLater);
  ASSERT_TRUE(later.ok()) << later.status();
  EXPECT_FALSE((*later)->Snapshot()->index().approximate());
  // A cancelled build publishes nothing.
  std::atomic<bool> cancel{true};
  EXPECT_EQ((*later)->UpdateApproximateIndex(&cancel).code(), absl::StatusCode::kCancelled);
  EXPECT_FALSE((*later)->Snapshot()->index().approximate());
  const auto before = (*later)->Snapshot();
  ASSERT_TRUE((*later)->UpdateApproximateIndex().ok());
  EXPECT_TRUE((*later)->Snapshot()->index().approximate());
  EXPECT_EQ((*later)->Snapshot()->version(), before->version());
  EXPECT_FALSE(before->index().approximate());  // readers' snapshots never change
  // In step now: nothing to publish.
  const auto built = (*later)->Snapshot();
  ASSERT_TRUE((*later)->UpdateApproximateIndex().ok());
  EXPECT_EQ((*later)->Snapshot(), built);

  auto now = Gallery::Restore(stored, limits, nullptr);
  ASSERT_TRUE(now.ok());
  EXPECT_TRUE((*now)->Snapshot()->index().approximate());
}

void ExpectSameMetadata(const GalleryMetadata& a, const GalleryMetadata& b) {
  EXPECT_EQ(a.name, b.name);
  EXPECT_EQ(a.options.descriptor_spec, b.options.descriptor_spec);
  EXPECT_EQ(a.options.knn.k, b.options.knn.k);
  EXPECT_EQ(a.options.reject_distance, b.options.reject_distance);
  EXPECT_EQ(a.options.augment.views, b.options.augment.views);
  EXPECT_EQ(a.created, b.created);
  EXPECT_EQ(a.updated, b.updated);
  EXPECT_EQ(a.descriptor_version, b.descriptor_version);
  EXPECT_EQ(a.software_version, b.software_version);
  EXPECT_EQ(a.dimension, b.dimension);
  EXPECT_EQ(a.version, b.version);
  EXPECT_EQ(a.incarnation, b.incarnation);
}

// One metadata value: the stored form carries the snapshot's, and a restore takes it back.
TEST(GalleryTest, StoredFormAndRestoreKeepTheMetadata) {
  GalleryOptions options;
  options.knn.k = 3;
  options.reject_distance = 0.25;
  auto g = MakeGallery(options);
  ASSERT_TRUE(g->Train(ThreeShapes()).ok());
  const std::shared_ptr<const GallerySnapshot> snapshot = g->Snapshot();
  EXPECT_EQ(snapshot->metadata().version, 1u);
  EXPECT_NE(snapshot->metadata().incarnation, 0u);
  EXPECT_EQ(snapshot->metadata().dimension, snapshot->index().dimension());
  const StoredGallery stored = snapshot->ToStored();
  ExpectSameMetadata(stored, snapshot->metadata());
  auto restored = Gallery::Restore(stored, {}, nullptr);
  ASSERT_TRUE(restored.ok()) << restored.status();
  ExpectSameMetadata((*restored)->Snapshot()->metadata(), snapshot->metadata());
}

TEST(GalleryTest, SnapshotsAreImmutable) {
  auto g = MakeGallery();
  ASSERT_TRUE(g->Train({{1, "box", Box(1)}}).ok());
  const std::shared_ptr<const GallerySnapshot> old = g->Snapshot();
  ASSERT_TRUE(g->Train({{2, "sphere", Sphere(1)}}).ok());
  ASSERT_TRUE(g->RemoveSamples({1}).ok());
  EXPECT_EQ(old->num_samples(), 1);
  EXPECT_TRUE(old->Contains(1));
  EXPECT_EQ(old->version(), 1u);
  EXPECT_EQ(old->Classify(Sphere(9))->label, "box");  // the only sample it knows
  EXPECT_EQ(g->Snapshot()->Classify(Sphere(9))->label, "sphere");
  EXPECT_EQ(g->Snapshot()->version(), 3u);
}

TEST(GalleryTest, LimitsAreResourceExhaustedWithTheNumbers) {
  GalleryLimits limits;
  limits.max_points_per_cloud = 200;
  limits.max_samples_per_gallery = 3;
  auto g = MakeGallery({}, limits);
  TrainBatch big = g->NewBatch();
  const absl::Status too_many_points = big.AddSample(0, "box", Box(1));  // 256 points
  EXPECT_EQ(too_many_points.code(), absl::StatusCode::kResourceExhausted);
  EXPECT_THAT(too_many_points.message(),
              AllOf(HasSubstr("sample 0"), HasSubstr("256"), HasSubstr("200")));

  limits.max_points_per_cloud = 1000;
  g = MakeGallery({}, limits);
  ASSERT_TRUE(g->Train({{0, "box", Box(1)}, {0, "box", Box(2)}}).ok());
  auto over = g->Train({{0, "box", Box(3)}, {0, "box", Box(4)}});
  EXPECT_EQ(over.status().code(), absl::StatusCode::kResourceExhausted);
  EXPECT_THAT(over.status().message(),
              AllOf(HasSubstr("holds 2"), HasSubstr("adding 2"), HasSubstr("= 3")));
  TrainBatch huge = g->NewBatch();
  for (uint32_t i = 0; i < 3; ++i) ASSERT_TRUE(huge.AddSample(0, "box", Box(i)).ok());
  EXPECT_EQ(huge.AddSample(0, "box", Box(9)).code(), absl::StatusCode::kResourceExhausted);
  EXPECT_EQ(g->Snapshot()->num_samples(), 2);
}

TEST(GalleryTest, StoreFailurePublishesNothing) {
  auto store = std::make_shared<InMemoryGalleryStore>();
  ASSERT_TRUE(store->SaveGallery(EmptyStored("shapes")).ok());
  auto g = MakeGallery({}, {}, store);
  ASSERT_TRUE(g->Train({{0, "box", Box(1)}, {0, "sphere", Sphere(1)}}).ok());
  const auto before = g->Snapshot();

  store->SetFailure(absl::UnavailableError("disk full"));
  auto train = g->Train({{0, "line", Line(1)}});
  EXPECT_EQ(train.status(), absl::UnavailableError("disk full"));
  EXPECT_EQ(g->RemoveSamples({kFirstAssignedId}).status(), absl::UnavailableError("disk full"));
  EXPECT_EQ(g->Snapshot(), before);

  store->SetFailure(absl::OkStatus());
  auto retry = g->Train({{0, "line", Line(1)}});
  ASSERT_TRUE(retry.ok());
  EXPECT_THAT(retry->ids, ElementsAre(kFirstAssignedId + 2));
  EXPECT_EQ(store->NumSamples("shapes"), 3);
}

TEST(GalleryTest, RestoreRebuildsFromTheStore) {
  auto store = std::make_shared<InMemoryGalleryStore>();
  GalleryOptions options;
  options.knn.k = 3;
  auto g = MakeGallery(options, {}, store);
  ASSERT_TRUE(store->SaveGallery(g->Snapshot()->ToStored()).ok());
  ASSERT_TRUE(g->Train(ThreeShapes()).ok());
  ASSERT_TRUE(g->RemoveSamples({9}).ok());

  auto stored = store->LoadAll();
  ASSERT_TRUE(stored.ok());
  ASSERT_EQ(stored->size(), 1u);
  auto restored = Gallery::Restore((*stored)[0], {}, store);
  ASSERT_TRUE(restored.ok()) << restored.status();
  auto a = g->Snapshot();
  auto b = (*restored)->Snapshot();
  EXPECT_EQ(b->options().descriptor_spec, a->options().descriptor_spec);
  EXPECT_EQ(b->options().knn.k, 3);
  EXPECT_EQ(b->num_samples(), 8);
  EXPECT_EQ(b->LabelCounts(), a->LabelCounts());
  EXPECT_EQ(b->created(), a->created());
  EXPECT_EQ(b->updated(), a->updated());
  EXPECT_EQ(b->next_assigned_id(), kFirstAssignedId);  // only client ids were stored
  auto qa = a->Classify(Sphere(3));
  auto qb = b->Classify(Sphere(3));
  ASSERT_TRUE(qa.ok() && qb.ok());
  EXPECT_EQ(qa->knn.neighbors[0].id, qb->knn.neighbors[0].id);
  EXPECT_EQ(qa->knn.neighbors[0].distance, qb->knn.neighbors[0].distance);

  StoredGallery with_assigned = (*stored)[0];
  with_assigned.samples[0].id = kFirstAssignedId + 41;
  auto continued = Gallery::Restore(with_assigned, {}, nullptr);
  ASSERT_TRUE(continued.ok());
  EXPECT_EQ((*continued)->Snapshot()->next_assigned_id(), kFirstAssignedId + 42);

  StoredGallery corrupt = (*stored)[0];
  corrupt.samples[2].features.pop_back();
  auto bad = Gallery::Restore(corrupt, {}, store);
  EXPECT_EQ(bad.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(bad.status().message(),
              AllOf(HasSubstr("restoring gallery 'shapes'"), HasSubstr("sample id 3")));
}

TEST(GalleryTest, ToStoredRestoresBitForBit) {
  GalleryOptions options;
  options.knn.k = 3;
  options.knn.scaling = FeatureScaling::kZScore;
  auto g = MakeGallery(options);
  ASSERT_TRUE(g->Train(ThreeShapes()).ok());
  ASSERT_TRUE(g->RemoveSamples({2}).ok());
  ASSERT_TRUE(g->Train({{0, "box", Box(7)}}).ok());
  const auto a = g->Snapshot();
  const StoredGallery stored = a->ToStored();
  EXPECT_EQ(stored.dimension, a->dimension());
  EXPECT_EQ(stored.descriptor_version, FindDescriptorKind("rphsd")->version);
  EXPECT_EQ(stored.software_version, kShapeidVersion);
  ASSERT_EQ(stored.samples.size(), static_cast<size_t>(a->num_samples()));
  EXPECT_EQ(stored.samples.back().id, kFirstAssignedId);

  auto restored = Gallery::Restore(stored, {}, nullptr);
  ASSERT_TRUE(restored.ok()) << restored.status();
  const auto b = (*restored)->Snapshot();
  EXPECT_TRUE(b->incompatible().empty());
  EXPECT_EQ(b->ToStored().samples.size(), stored.samples.size());
  for (uint32_t q = 0; q < 6; ++q) {
    auto qa = a->Classify(q % 2 ? Sphere(q + 20) : Box(q + 20));
    auto qb = b->Classify(q % 2 ? Sphere(q + 20) : Box(q + 20));
    ASSERT_TRUE(qa.ok() && qb.ok());
    ASSERT_EQ(qa->knn.neighbors.size(), qb->knn.neighbors.size());
    for (size_t i = 0; i < qa->knn.neighbors.size(); ++i) {
      EXPECT_EQ(qa->knn.neighbors[i].id, qb->knn.neighbors[i].id);
      // Bitwise: a restart must not change a single distance.
      EXPECT_EQ(std::memcmp(&qa->knn.neighbors[i].distance, &qb->knn.neighbors[i].distance,
                            sizeof(double)),
                0);
    }
  }
  // Assigned ids continue where they stopped.
  auto more = (*restored)->Train({{0, "box", Box(8)}});
  ASSERT_TRUE(more.ok());
  EXPECT_THAT(more->ids, ElementsAre(kFirstAssignedId + 1));
}

// Stored features come from outside too (an import, a store's file, another replica's
// write): beyond KnnIndex::kMaxFeatureMagnitude, where distances would overflow, they are
// refused wherever they enter, naming the gallery, the sample and the bound; nothing changes.
TEST(GalleryTest, StoredFeaturesBeyondTheBoundAreRefusedOnEveryWayIn) {
  auto g = MakeGallery();
  ASSERT_TRUE(g->Train(ThreeShapes()).ok());
  StoredGallery stored = g->Snapshot()->ToStored();
  stored.samples[1].features[4] = -3e38f;

  const absl::Status restored = Gallery::Restore(stored, {}, nullptr).status();
  EXPECT_EQ(restored.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(std::string(restored.message()),
              AllOf(HasSubstr("restoring gallery 'shapes'"), HasSubstr("sample id 2"),
                    HasSubstr("feature 4 is -3e+38"), HasSubstr("within +-1e+08")));

  auto store = std::make_shared<InMemoryGalleryStore>();
  ASSERT_TRUE(store->SaveGallery(stored).ok());
  GalleryRegistry registry({}, store);
  EXPECT_EQ(registry.LoadFromStore().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(registry.size(), 0u);

  StoredSample far{100, "box", std::vector<float>(static_cast<size_t>(g->Snapshot()->dimension()))};
  far.features[0] = 3e38f;
  const uint64_t version = g->Snapshot()->version();
  const absl::Status appended = g->ApplyStoredAppend({far}, absl::Now(), version + 1);
  EXPECT_EQ(appended.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(std::string(appended.message()), HasSubstr("sample 100: feature 0 is 3e+38"));
  EXPECT_EQ(g->Snapshot()->version(), version);
  EXPECT_EQ(g->Snapshot()->num_samples(), 9);
}

TEST(GalleryTest, AugmentedGalleryKeepsViewsPerSampleAndVotesPerObject) {
  GalleryOptions options;
  options.descriptor_spec = "dfsd:frame=box";
  options.knn.k = 3;
  options.augment.views = 4;
  auto g = MakeGallery(options);
  ASSERT_TRUE(g->Train(ThreeShapes()).ok());
  const auto snapshot = g->Snapshot();
  EXPECT_EQ(snapshot->options().augment.views, 4);
  EXPECT_EQ(snapshot->num_samples(), 9);
  EXPECT_GT(snapshot->index().num_rows(), 9 * 3);  // most clouds got their 4 views
  EXPECT_LE(snapshot->index().num_rows(), 9 * 5);
  const StoredGallery stored = snapshot->ToStored();
  for (const StoredSample& sample : stored.samples) {
    EXPECT_EQ(sample.features.size() % static_cast<size_t>(stored.dimension), 0u);
  }

  // A sparse, noisy, turned scan of one side of a trained box: its neighbors are three
  // distinct samples, whatever views of one box lie nearest.
  SensorViewOptions sensor;
  const PointCloud scan = *SensorView(Box(1), sensor, 99);
  auto answer = snapshot->Classify(scan);
  ASSERT_TRUE(answer.ok()) << answer.status();
  EXPECT_EQ(answer->label, "box");
  ASSERT_EQ(answer->knn.neighbors.size(), 3u);
  EXPECT_NE(answer->knn.neighbors[0].id, answer->knn.neighbors[1].id);
  EXPECT_NE(answer->knn.neighbors[1].id, answer->knn.neighbors[2].id);
  EXPECT_NE(answer->knn.neighbors[0].id, answer->knn.neighbors[2].id);

  // The same cloud gets the same views: a second gallery trained alike stores equal bits.
  auto twin = MakeGallery(options);
  ASSERT_TRUE(twin->Train(ThreeShapes()).ok());
  const StoredGallery twin_stored = twin->Snapshot()->ToStored();
  ASSERT_EQ(twin_stored.samples.size(), stored.samples.size());
  for (size_t i = 0; i < stored.samples.size(); ++i) {
    EXPECT_EQ(twin_stored.samples[i].features, stored.samples[i].features) << i;
  }

  // Restored from the store's form: the same answer, bit for bit.
  auto restored = Gallery::Restore(stored, {}, nullptr);
  ASSERT_TRUE(restored.ok()) << restored.status();
  auto again = (*restored)->Snapshot()->Classify(scan);
  ASSERT_TRUE(again.ok());
  ASSERT_EQ(again->knn.neighbors.size(), answer->knn.neighbors.size());
  for (size_t i = 0; i < again->knn.neighbors.size(); ++i) {
    EXPECT_EQ(again->knn.neighbors[i].id, answer->knn.neighbors[i].id);
    EXPECT_EQ(again->knn.neighbors[i].distance, answer->knn.neighbors[i].distance);
  }

  // A batch may override the gallery's setting for its own samples.
  TrainBatch batch = g->NewBatch();
  AugmentOptions none;
  ASSERT_TRUE(batch.SetAugment(none).ok());
  ASSERT_TRUE(batch.AddSample(100, "box", Box(9)).ok());
  ASSERT_TRUE(batch.Commit().ok());
  const StoredGallery after = g->Snapshot()->ToStored();
  EXPECT_EQ(after.samples.back().id, 100u);
  EXPECT_EQ(after.samples.back().features.size(), static_cast<size_t>(after.dimension));
  AugmentOptions too_many;
  too_many.views = AugmentOptions::kMaxViews + 1;
  TrainBatch bad = g->NewBatch();
  EXPECT_THAT(bad.SetAugment(too_many).message(), HasSubstr("views 65"));
  EXPECT_FALSE(bad.AddSample(101, "box", Box(9)).ok());  // the batch stays failed
}

TEST(GalleryTest, InvalidAugmentationIsRefusedAtCreation) {
  GalleryOptions options;
  options.augment.views = -1;
  auto g = Gallery::Create("shapes", options, {}, nullptr);
  EXPECT_EQ(g.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(g.status().message(), HasSubstr("views -1"));
}

TEST(GalleryTest, IncompatibleDescriptorLoadsButRefusesWork) {
  auto g = MakeGallery();
  ASSERT_TRUE(g->Train(ThreeShapes()).ok());
  StoredGallery other_version = g->Snapshot()->ToStored();
  other_version.descriptor_version += 1;
  other_version.software_version = "9.9.9";
  auto restored = Gallery::Restore(other_version, {}, nullptr);
  ASSERT_TRUE(restored.ok()) << restored.status();
  const auto snap = (*restored)->Snapshot();
  EXPECT_THAT(snap->incompatible(),
              AllOf(HasSubstr("dfsd version"), HasSubstr("9.9.9"), HasSubstr("not comparable")));
  EXPECT_EQ(snap->num_samples(), 9);  // nothing dropped
  EXPECT_EQ(snap->Classify(Box(3)).status().code(), absl::StatusCode::kFailedPrecondition);
  auto train = (*restored)->Train({{0, "box", Box(3)}});
  EXPECT_EQ(train.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_EQ((*restored)->Snapshot()->num_samples(), 9);
  // Removal and export still work: the operator can salvage or prune it.
  EXPECT_TRUE((*restored)->RemoveSamples({1}).ok());
  EXPECT_EQ((*restored)->Snapshot()->ToStored().descriptor_version,
            other_version.descriptor_version);

  StoredGallery unknown = g->Snapshot()->ToStored();
  unknown.options.descriptor_spec = "esf:bins=10";
  auto unknown_restored = Gallery::Restore(unknown, {}, nullptr);
  ASSERT_TRUE(unknown_restored.ok()) << unknown_restored.status();
  EXPECT_THAT((*unknown_restored)->Snapshot()->incompatible(), HasSubstr("cannot compute"));
  EXPECT_EQ((*unknown_restored)->Snapshot()->options().descriptor_spec, "esf:bins=10");
}

}  // namespace
}  // namespace shapeid

namespace shapeid {
namespace {

// ThreeShapes with a source per sample ("<label>_<id>.pcd") and, on the boxes, metadata.
std::vector<LabeledCloud> ThreeShapesWithProvenance() {
  std::vector<LabeledCloud> samples = ThreeShapes();
  for (LabeledCloud& s : samples) {
    s.provenance.source = absl::StrCat(s.label, "_", s.id, ".pcd");
    if (s.label == "box") s.provenance.metadata = {{"session", "2"}, {"camera", "d435"}};
  }
  return samples;
}

TEST(GalleryProvenanceTest, NeighborsCarryTheirProvenance) {
  auto g = MakeGallery();
  std::vector<LabeledCloud> samples = ThreeShapesWithProvenance();
  samples.push_back({0, "sphere", Sphere(9)});  // one without
  ASSERT_TRUE(g->Train(samples).ok());
  const auto answer = g->Snapshot()->Classify(Box(40), {}, 10);
  ASSERT_TRUE(answer.ok()) << answer.status();
  ASSERT_EQ(answer->provenance.size(), answer->knn.neighbors.size());
  int without = 0;
  for (size_t i = 0; i < answer->knn.neighbors.size(); ++i) {
    const auto& neighbor = answer->knn.neighbors[i];
    const auto& provenance = answer->provenance[i];
    if (neighbor.id >= kFirstAssignedId) {
      EXPECT_EQ(provenance, nullptr);
      ++without;
      continue;
    }
    ASSERT_NE(provenance, nullptr) << neighbor.id;
    EXPECT_EQ(provenance->source, absl::StrCat(neighbor.label, "_", neighbor.id, ".pcd"));
    if (neighbor.label == "box") {
      // Sorted by key when trained.
      EXPECT_THAT(provenance->metadata, ElementsAre(Pair("camera", "d435"), Pair("session", "2")));
    } else {
      EXPECT_TRUE(provenance->metadata.empty());
    }
  }
  EXPECT_EQ(without, 1);
}

TEST(GalleryProvenanceTest, SurvivesStoreRestoreAndRemoval) {
  auto store = std::make_shared<InMemoryGalleryStore>();
  auto g = MakeGallery({}, {}, store);
  ASSERT_TRUE(store->SaveGallery(g->Snapshot()->ToStored()).ok());
  ASSERT_TRUE(g->Train(ThreeShapesWithProvenance()).ok());
  ASSERT_TRUE(g->RemoveSamples({1}).ok());
  EXPECT_EQ(g->Snapshot()->Provenance(1), nullptr);
  ASSERT_NE(g->Snapshot()->Provenance(2), nullptr);

  const absl::StatusOr<std::vector<StoredGallery>> loaded = store->LoadAll();
  ASSERT_TRUE(loaded.ok());
  ASSERT_EQ(loaded->size(), 1u);
  auto restored = Gallery::Restore(loaded->front(), {}, nullptr);
  ASSERT_TRUE(restored.ok()) << restored.status();
  const auto snap = (*restored)->Snapshot();
  EXPECT_EQ(snap->Provenance(1), nullptr);
  ASSERT_NE(snap->Provenance(4), nullptr);
  EXPECT_EQ(snap->Provenance(4)->source, "sphere_4.pcd");
  EXPECT_EQ(snap->ToStored().samples.front().provenance.metadata.size(), 2u);
}

TEST(GalleryProvenanceTest, BadProvenanceFailsTheSampleAndTheBatch) {
  auto g = MakeGallery();
  TrainBatch batch = g->NewBatch();
  ASSERT_TRUE(batch.AddSample(1, "box", Box(1), {"a.pcd", {}}).ok());
  SampleProvenance twice{"b.pcd", {{"k", "1"}, {"k", "2"}}};
  const absl::Status s = batch.AddSample(2, "box", Box(2), twice);
  EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(s.message(), AllOf(HasSubstr("sample 1"), HasSubstr("\"k\" is given twice")));
  EXPECT_FALSE(batch.Commit().ok());
  EXPECT_EQ(g->Snapshot()->num_samples(), 0);

  // A store's or an export's sample is checked too.
  StoredGallery stored = g->Snapshot()->ToStored();
  StoredSample sample;
  sample.id = 5;
  sample.label = "box";
  sample.features.assign(static_cast<size_t>(stored.dimension), 0.5f);
  sample.provenance.source = "bad\xff";
  stored.samples.push_back(sample);
  auto restored = Gallery::Restore(stored, {}, nullptr);
  ASSERT_EQ(restored.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(restored.status().message(), AllOf(HasSubstr("sample id 5"), HasSubstr("UTF-8")));
}

TEST(GalleryProvenanceTest, ListSamplesPagesByIdAndLabel) {
  auto g = MakeGallery();
  std::vector<LabeledCloud> samples = ThreeShapesWithProvenance();
  // Ids out of training order: paging is by id, whatever the order.
  for (LabeledCloud& s : samples) s.id = 100 - s.id;  // 99 .. 91
  ASSERT_TRUE(g->Train(samples).ok());
  auto snap = g->Snapshot();
  std::vector<uint64_t> seen;
  uint64_t after = 0;
  int pages = 0;
  while (true) {
    const SamplePage page = snap->ListSamples("", after, 4);
    ++pages;
    for (const SampleInfo& s : page.samples) {
      seen.push_back(s.id);
      ASSERT_NE(s.provenance, nullptr);
      EXPECT_EQ(s.provenance->source, absl::StrCat(s.label, "_", 100 - s.id, ".pcd"));
      EXPECT_EQ(s.views, 1);
    }
    if (!page.more) break;
    after = page.samples.back().id;
  }
  EXPECT_EQ(pages, 3);  // 4 + 4 + 1
  EXPECT_THAT(seen, ElementsAre(91, 92, 93, 94, 95, 96, 97, 98, 99));

  const SamplePage spheres = snap->ListSamples("sphere", 0, 10);
  EXPECT_FALSE(spheres.more);
  ASSERT_EQ(spheres.samples.size(), 3u);
  EXPECT_EQ(spheres.samples.front().id, 94u);
  EXPECT_EQ(spheres.samples.front().label, "sphere");
  // An exact page is not followed by an empty one.
  EXPECT_FALSE(snap->ListSamples("sphere", 0, 3).more);
  EXPECT_TRUE(snap->ListSamples("nosuch", 0, 3).samples.empty());

  // Changes between pages move no other sample: a removed one is skipped, a new one with a
  // larger id comes at the end.
  const SamplePage first = snap->ListSamples("", 0, 3);
  ASSERT_TRUE(g->RemoveSamples({94}).ok());
  ASSERT_TRUE(g->Train({{500, "box", Box(30)}}).ok());
  const SamplePage rest = g->Snapshot()->ListSamples("", first.samples.back().id, 100);
  std::vector<uint64_t> rest_ids;
  for (const SampleInfo& s : rest.samples) rest_ids.push_back(s.id);
  EXPECT_THAT(rest_ids, ElementsAre(95, 96, 97, 98, 99, 500));
}

}  // namespace
}  // namespace shapeid
