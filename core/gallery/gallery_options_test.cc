#include "core/gallery/gallery_options.h"

#include <cmath>
#include <limits>
#include <string>

#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;

TEST(ValidateGalleryNameTest, AcceptsThePattern) {
  for (const std::string name : {"a", "Z", "0", "modelnet10", "ycb_v2.1-test", "9-._"}) {
    EXPECT_TRUE(ValidateGalleryName(name).ok()) << name;
  }
  EXPECT_TRUE(ValidateGalleryName(std::string(128, 'x')).ok());
}

TEST(ValidateGalleryNameTest, RejectsOthersQuotingThePattern) {
  for (const std::string& name :
       {std::string(), std::string(129, 'x'), std::string("_a"), std::string(".hidden"),
        std::string("-a"), std::string("a/b"), std::string("a b"), std::string("../etc"),
        std::string("caf\xc3\xa9"), std::string("a\0b", 3)}) {
    const absl::Status s = ValidateGalleryName(name);
    EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument) << name;
    EXPECT_THAT(s.message(), HasSubstr("[A-Za-z0-9][A-Za-z0-9_.-]{0,127}"));
  }
}

TEST(ValidateLabelTest, AcceptsUtf8UpTo256Bytes) {
  EXPECT_TRUE(ValidateLabel("mug").ok());
  EXPECT_TRUE(ValidateLabel("W\xc3\xbcrfel").ok());     // Würfel
  EXPECT_TRUE(ValidateLabel("\xe6\x9d\xaf").ok());      // 杯
  EXPECT_TRUE(ValidateLabel("\xf0\x9f\x8d\xba").ok());  // U+1F37A
  EXPECT_TRUE(ValidateLabel("Unknown").ok());           // only the exact word is reserved
  EXPECT_TRUE(ValidateLabel(std::string(256, 'a')).ok());
}

TEST(ValidateLabelTest, RejectsEmptyLongInvalidAndReserved) {
  EXPECT_THAT(ValidateLabel("").message(), HasSubstr("empty"));
  const absl::Status long_label = ValidateLabel(std::string(257, 'a'));
  EXPECT_EQ(long_label.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(long_label.message(), HasSubstr("257 bytes, more than the limit of 256"));
  for (const std::string& bad : {
           std::string("\x80"),              // lone continuation byte
           std::string("a\xc0\xafz"),        // overlong '/'
           std::string("\xe6\x9d"),          // truncated sequence
           std::string("\xed\xa0\x80"),      // surrogate U+D800
           std::string("\xf4\x90\x80\x80"),  // above U+10FFFF
           std::string("\xff"),
       }) {
    const absl::Status s = ValidateLabel(bad);
    EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument);
    EXPECT_THAT(s.message(), HasSubstr("not valid UTF-8"));
  }
  const absl::Status reserved = ValidateLabel("unknown");
  EXPECT_EQ(reserved.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(reserved.message(), HasSubstr("reserved"));
}

TEST(ValidateGalleryOptionsTest, DefaultsAreValid) {
  const GalleryOptions options;
  EXPECT_EQ(options.descriptor_spec, "dfsd");
  EXPECT_EQ(options.knn.k, 1);
  EXPECT_EQ(options.reject_distance, 0.0);
  EXPECT_TRUE(ValidateGalleryOptions(options).ok());
}

TEST(ValidateGalleryOptionsTest, RejectsBadKAndRejectDistance) {
  GalleryOptions options;
  options.knn.k = 0;
  EXPECT_EQ(ValidateGalleryOptions(options).code(), absl::StatusCode::kInvalidArgument);
  options.knn.k = 3;
  for (double d : {-1.0, std::nan(""), std::numeric_limits<double>::infinity()}) {
    options.reject_distance = d;
    const absl::Status s = ValidateGalleryOptions(options);
    EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument) << d;
    EXPECT_THAT(s.message(), HasSubstr("reject_distance"));
  }
  options.reject_distance = 0.25;
  EXPECT_TRUE(ValidateGalleryOptions(options).ok());
}

TEST(GalleryLimitsTest, CloudLimitsCarryTheMaximum) {
  GalleryLimits limits;
  limits.max_points_per_cloud = 1234;
  EXPECT_EQ(limits.cloud_limits().max_points, 1234u);
  EXPECT_GE(GalleryLimits{}.max_points_per_cloud, 2'000'000u);  // the largest cloud
}

}  // namespace
}  // namespace shapeid
