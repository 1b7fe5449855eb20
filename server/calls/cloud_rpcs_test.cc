#include "server/calls/cloud_rpcs.h"

#include <memory>
#include <string>
#include <vector>

#include "core/gallery/gallery_registry.h"
#include "core/testing/gallery_shapes.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "server/calls/service_options.h"

namespace shapeid {
namespace {

using gallery_testing::Box;
using gallery_testing::Sphere;
using ::testing::HasSubstr;

class CloudRpcsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(registry_.Create("lab", {}).ok());
    std::shared_ptr<Gallery> lab = *registry_.Get("lab");
    ASSERT_TRUE(
        lab->Train(std::vector<LabeledCloud>{{1, "box", Box(1)}, {2, "sphere", Sphere(1)}}).ok());
    runtime_.registry = &registry_;
    runtime_.options = &options_;
  }

  // Replaces gallery "lab" with one this server cannot describe for, as a replica running an
  // older version holds a gallery that a newer one created in the shared store.
  void MakeLabIncompatible() {
    StoredGallery stored = (*registry_.Get("lab"))->Snapshot()->ToStored();
    stored.options.descriptor_spec = "esf:bins=10";
    stored.incarnation += 1;  // another gallery of that name replaces it
    ASSERT_TRUE(registry_.ApplyStoredGallery(stored).ok());
    ASSERT_FALSE((*registry_.Get("lab"))->Snapshot()->incompatible().empty());
  }

  GalleryRegistry registry_;
  ServiceOptions options_;
  ServiceRuntime runtime_;
  CallRecord record_;
};

TEST_F(CloudRpcsTest, AnIncompatibleGalleryIsRefusedAtTheHeaderByEveryCloudRpc) {
  MakeLabIncompatible();
  v1::DescribeHeader describe;
  describe.set_gallery("lab");
  const absl::Status described = DescribeRpc::PlanOf(runtime_, describe, record_).status();
  EXPECT_EQ(described.code(), absl::StatusCode::kFailedPrecondition) << described;
  EXPECT_THAT(std::string(described.message()), HasSubstr("cannot compute"));
  EXPECT_EQ(record_.gallery, "lab");

  v1::ClassifyHeader classify;
  classify.set_gallery("lab");
  EXPECT_EQ(ClassifyRpc::PlanOf(runtime_, classify, record_).status().code(),
            absl::StatusCode::kFailedPrecondition);
  v1::SceneHeader scene;
  scene.set_gallery("lab");
  EXPECT_EQ(RecognizeSceneRpc::PlanOf(runtime_, scene, record_).status().code(),
            absl::StatusCode::kFailedPrecondition);
}

TEST_F(CloudRpcsTest, APlanKeepsTheSnapshotItsHeaderWasCheckedAgainst) {
  v1::ClassifyHeader header;
  header.set_gallery("lab");
  header.set_k(1);
  absl::StatusOr<ClassifyRpc::Plan> plan = ClassifyRpc::PlanOf(runtime_, header, record_);
  ASSERT_TRUE(plan.ok()) << plan.status();
  ASSERT_TRUE((*registry_.Get("lab"))->Train(std::vector<LabeledCloud>{{3, "box", Box(2)}}).ok());
  EXPECT_EQ(plan->snapshot->num_samples(), 2);
  EXPECT_EQ((*registry_.Get("lab"))->Snapshot()->num_samples(), 3);
}

TEST_F(CloudRpcsTest, HeaderErrorsNameTheMethodAsCalled) {
  record_.method = "ClassifyCloud";
  v1::ClassifyHeader header;
  const absl::Status empty = ClassifyRpc::PlanOf(runtime_, header, record_).status();
  EXPECT_EQ(empty.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(std::string(empty.message()), HasSubstr("ClassifyCloud: the gallery name is empty"));
  header.set_gallery("nope");
  EXPECT_EQ(ClassifyRpc::PlanOf(runtime_, header, record_).status().code(),
            absl::StatusCode::kNotFound);
  EXPECT_EQ(record_.gallery, "nope");
}

}  // namespace
}  // namespace shapeid
