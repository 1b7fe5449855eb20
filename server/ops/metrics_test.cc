#include "server/ops/metrics.h"

#include <limits>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "absl/strings/str_cat.h"
#include "core/gallery/gallery.h"
#include "core/gallery/gallery_registry.h"
#include "core/testing/test_clouds.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "prometheus/text_serializer.h"

namespace shapeid {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;
using testing_clouds::ShapeCloud;

// The exposition text Prometheus would scrape.
std::string Scrape(const ServerMetrics& metrics) {
  return prometheus::TextSerializer().Serialize(metrics.Collect());
}

// The value of the one series `name{labels}` in `metrics`, or -1 when absent. `labels` as in the
// exposition: `method="Train",code="OK"` (in the serializer's order: alphabetical).
double Value(const ServerMetrics& metrics, const std::string& series) {
  const std::string text = Scrape(metrics);
  const std::string prefix = series + " ";
  size_t at = 0;
  while ((at = text.find(prefix, at)) != std::string::npos) {
    if (at == 0 || text[at - 1] == '\n') return std::stod(text.substr(at + prefix.size()));
    at += prefix.size();
  }
  return -1;
}

CallMetrics Call(absl::string_view method, absl::string_view gallery, absl::StatusCode code,
                 absl::Duration elapsed = absl::Milliseconds(1)) {
  CallMetrics call;
  call.method = method;
  call.gallery = gallery;
  call.code = code;
  call.elapsed = elapsed;
  return call;
}

TEST(ServerMetricsTest, CountsCallsByMethodGalleryAndCode) {
  ServerMetrics metrics;
  auto registry = std::make_shared<GalleryRegistry>();
  ASSERT_TRUE(registry->Create("lab", {}).ok());
  metrics.SetSources(registry, {});
  CallMetrics train = Call("Train", "lab", absl::StatusCode::kOk);
  train.points = 3000;
  train.samples_trained = 3;
  metrics.RecordCall(train);
  metrics.RecordCall(Call("ClassifyCloud", "lab", absl::StatusCode::kOk));
  metrics.RecordCall(Call("ClassifyCloud", "lab", absl::StatusCode::kOk));
  metrics.RecordCall(Call("ListGalleries", "", absl::StatusCode::kOk));
  EXPECT_EQ(Value(metrics, R"(shapeid_requests_total{code="OK",gallery="lab",method="Train"})"), 1);
  EXPECT_EQ(
      Value(metrics, R"(shapeid_requests_total{code="OK",gallery="lab",method="ClassifyCloud"})"),
      2);
  EXPECT_EQ(
      Value(metrics, R"(shapeid_requests_total{code="OK",gallery="",method="ListGalleries"})"), 1);
  EXPECT_EQ(Value(metrics, R"(shapeid_points_received_total{method="Train"})"), 3000);
  EXPECT_EQ(Value(metrics, R"(shapeid_samples_trained_total{gallery="lab"})"), 3);
  EXPECT_EQ(Value(metrics, R"(shapeid_request_duration_seconds_count{method="ClassifyCloud"})"), 2);
  // 1 ms falls in the bucket le=0.001 and every one above it.
  EXPECT_EQ(
      Value(metrics,
            R"(shapeid_request_duration_seconds_bucket{method="ClassifyCloud",le="0.00075"})"),
      0);
  EXPECT_EQ(Value(metrics,
                  R"(shapeid_request_duration_seconds_bucket{method="ClassifyCloud",le="0.001"})"),
            2);
  EXPECT_EQ(metrics.points_received(), 3000u);
}

TEST(ServerMetricsTest, NamesNotHeldAreUnknownAndGalleriesPastTheLimitFold) {
  MetricsOptions options;
  options.max_gallery_labels = 2;
  ServerMetrics metrics(options);
  auto registry = std::make_shared<GalleryRegistry>();
  for (const char* name : {"a", "b", "c", "d"}) ASSERT_TRUE(registry->Create(name, {}).ok());
  metrics.SetSources(registry, {});
  // A failed call for a gallery the server does not hold: one "_unknown" series, however many
  // names clients invent.
  for (const char* typo : {"nope", "nope2", "nope3"}) {
    metrics.RecordCall(Call("GetGallery", typo, absl::StatusCode::kNotFound));
  }
  // A failed call for a gallery it holds keeps the name.
  metrics.RecordCall(Call("Classify", "a", absl::StatusCode::kFailedPrecondition));
  metrics.RecordCall(Call("GetGallery", "b", absl::StatusCode::kOk));
  metrics.RecordCall(Call("GetGallery", "c", absl::StatusCode::kOk));  // past the limit
  const std::string text = Scrape(metrics);
  EXPECT_EQ(
      Value(metrics,
            R"(shapeid_requests_total{code="NOT_FOUND",gallery="_unknown",method="GetGallery"})"),
      3);
  EXPECT_THAT(text, Not(HasSubstr("nope")));
  EXPECT_EQ(
      Value(metrics,
            R"(shapeid_requests_total{code="FAILED_PRECONDITION",gallery="a",method="Classify"})"),
      1);
  EXPECT_EQ(Value(metrics, R"(shapeid_requests_total{code="OK",gallery="b",method="GetGallery"})"),
            1);
  EXPECT_EQ(
      Value(metrics, R"(shapeid_requests_total{code="OK",gallery="_other",method="GetGallery"})"),
      1);
  // The scrape-time gauges fold the same way: a and b by name, c and d as _other.
  EXPECT_EQ(Value(metrics, "shapeid_galleries"), 4);
  EXPECT_EQ(Value(metrics, R"(shapeid_gallery_samples{gallery="a"})"), 0);
  EXPECT_EQ(Value(metrics, R"(shapeid_gallery_samples{gallery="_other"})"), 0);
  EXPECT_EQ(Value(metrics, "shapeid_gallery_labels_folded"), 2);
  EXPECT_EQ(Value(metrics, R"(shapeid_gallery_samples{gallery="c"})"), -1);
}

TEST(ServerMetricsTest, OnlyGalleriesTheServerHoldsBecomeLabels) {
  ServerMetrics metrics;
  auto registry = std::make_shared<GalleryRegistry>();
  ASSERT_TRUE(registry->Create("kept", {}).ok());
  metrics.SetSources(registry, {});
  // A Describe by spec answers OK whatever its gallery field says; a long or invalid name
  // never becomes a label, nor takes one of the limited slots.
  metrics.RecordCall(Call("DescribeCloud", std::string(5000, 'x'), absl::StatusCode::kOk));
  metrics.RecordCall(Call("DescribeCloud", "_other", absl::StatusCode::kOk));
  metrics.RecordCall(Call("DescribeCloud", "bad\xff", absl::StatusCode::kOk));
  metrics.RecordCall(Call("DeleteGallery", "gone", absl::StatusCode::kOk));  // just deleted
  metrics.RecordCall(Call("GetGallery", "kept", absl::StatusCode::kOk));
  EXPECT_EQ(Value(metrics,
                  R"(shapeid_requests_total{code="OK",gallery="_unknown",method="DescribeCloud"})"),
            3);
  EXPECT_EQ(
      Value(metrics, R"(shapeid_requests_total{code="OK",gallery="gone",method="DeleteGallery"})"),
      1);
  EXPECT_EQ(
      Value(metrics, R"(shapeid_requests_total{code="OK",gallery="kept",method="GetGallery"})"), 1);
  EXPECT_THAT(Scrape(metrics), Not(HasSubstr("xxxxxxxx")));
}

TEST(ServerMetricsTest, GallerySamplesAreReadAtScrapeTime) {
  ServerMetrics metrics;
  auto registry = std::make_shared<GalleryRegistry>();
  const std::shared_ptr<Gallery> gallery = *registry->Create("shelf", {});
  metrics.SetSources(registry, {});
  EXPECT_EQ(Value(metrics, R"(shapeid_gallery_samples{gallery="shelf"})"), 0);
  TrainBatch batch = gallery->NewBatch();
  ASSERT_TRUE(batch.AddSample(0, "cube", ShapeCloud(1, 7, 256)).ok());
  ASSERT_TRUE(batch.AddSample(0, "ball", ShapeCloud(2, 8, 256)).ok());
  ASSERT_TRUE(batch.Commit().ok());
  EXPECT_EQ(Value(metrics, R"(shapeid_gallery_samples{gallery="shelf"})"), 2);
  ASSERT_TRUE(registry->Delete("shelf").ok());
  EXPECT_EQ(Value(metrics, "shapeid_galleries"), 0);
  EXPECT_EQ(Value(metrics, R"(shapeid_gallery_samples{gallery="shelf"})"), -1);
}

TEST(ServerMetricsTest, LiveStateReplicationAndProcess) {
  ServerMetrics metrics;
  LiveSources live;
  live.calls_in_flight = [] { return int64_t{3}; };
  live.serving = [] { return false; };
  live.replication = [] {
    return std::optional<ReplicationState>(ReplicationState{true, 17, absl::Milliseconds(250)});
  };
  metrics.SetSources(std::weak_ptr<const GalleryRegistry>(), live);
  EXPECT_EQ(Value(metrics, "shapeid_requests_in_flight"), 3);
  EXPECT_EQ(Value(metrics, "shapeid_serving"), 0);
  EXPECT_EQ(Value(metrics, "shapeid_store_reachable"), 1);
  EXPECT_EQ(Value(metrics, "shapeid_replication_changes_applied_total"), 17);
  EXPECT_EQ(Value(metrics, "shapeid_replication_sync_age_seconds"), 0.25);
  EXPECT_GT(Value(metrics, "process_resident_memory_bytes"), 1e6);
  EXPECT_GT(Value(metrics, "process_open_fds"), 2);
  EXPECT_GT(Value(metrics, "process_threads"), 0);
  EXPECT_GT(Value(metrics, "process_start_time_seconds"), 1.7e9);
  EXPECT_GE(Value(metrics, "process_cpu_seconds_total"), 0);
  EXPECT_THAT(Scrape(metrics), HasSubstr("shapeid_build_info{version=\""));
  // A private store has no replication series at all.
  live.replication = [] { return std::optional<ReplicationState>(); };
  metrics.SetSources(std::weak_ptr<const GalleryRegistry>(), live);
  EXPECT_THAT(Scrape(metrics), Not(HasSubstr("shapeid_store_reachable")));
  // The learner's series only where the server learns (--learn=mlp).
  EXPECT_THAT(Scrape(metrics), Not(HasSubstr("shapeid_head_fits_total")));
  live.learner = [] { return std::optional<LearnerState>(LearnerState{4, 1, true}); };
  metrics.SetSources(std::weak_ptr<const GalleryRegistry>(), live);
  EXPECT_EQ(Value(metrics, "shapeid_head_fits_total"), 4);
  EXPECT_EQ(Value(metrics, "shapeid_head_fit_failures_total"), 1);
  EXPECT_EQ(Value(metrics, "shapeid_head_fitting"), 1);
}

TEST(ServerMetricsTest, DescribeSearchAndStoreWrites) {
  ServerMetrics metrics;
  metrics.ObserveDescribe("rphsd", absl::Microseconds(800));
  metrics.ObserveSearch(false, absl::Microseconds(40));
  metrics.ObserveSearch(true, absl::Microseconds(40));
  metrics.ObserveStoreWrite("append", absl::Milliseconds(3), true);
  metrics.ObserveStoreWrite("append", absl::Milliseconds(3), false);
  EXPECT_EQ(Value(metrics, R"(shapeid_describe_duration_seconds_count{descriptor="rphsd"})"), 1);
  EXPECT_EQ(Value(metrics, R"(shapeid_search_duration_seconds_count{index="exact"})"), 1);
  EXPECT_EQ(Value(metrics, R"(shapeid_search_duration_seconds_count{index="approximate"})"), 1);
  EXPECT_EQ(Value(metrics, R"(shapeid_store_write_duration_seconds_count{operation="append"})"), 2);
  EXPECT_EQ(Value(metrics, R"(shapeid_store_write_failures_total{operation="append"})"), 1);
}

TEST(ServerMetricsTest, MethodSummariesCountErrorsAndEstimateQuantiles) {
  ServerMetrics metrics;
  EXPECT_TRUE(metrics.MethodSummaries().empty());
  for (int i = 0; i < 98; ++i) {
    metrics.RecordCall(Call("ClassifyCloud", "", absl::StatusCode::kOk, absl::Microseconds(600)));
  }
  metrics.RecordCall(
      Call("ClassifyCloud", "", absl::StatusCode::kInvalidArgument, absl::Milliseconds(40)));
  metrics.RecordCall(
      Call("ClassifyCloud", "", absl::StatusCode::kUnavailable, absl::Milliseconds(40)));
  metrics.RecordCall(Call("Train", "", absl::StatusCode::kOk, absl::Seconds(2)));
  const std::vector<MethodSummary> summaries = metrics.MethodSummaries();
  ASSERT_EQ(summaries.size(), 2u);
  EXPECT_EQ(summaries[0].method, "ClassifyCloud");
  EXPECT_EQ(summaries[0].calls, 100u);
  EXPECT_EQ(summaries[0].errors, 2u);
  // 600 us lies in (500 us, 750 us]; the median interpolates within it.
  ASSERT_TRUE(summaries[0].p50.has_value());
  EXPECT_GT(*summaries[0].p50, absl::Microseconds(500));
  EXPECT_LE(*summaries[0].p50, absl::Microseconds(750));
  // The 99th of 100 is one of the 40 ms calls: in (25 ms, 50 ms].
  ASSERT_TRUE(summaries[0].p99.has_value());
  EXPECT_GT(*summaries[0].p99, absl::Milliseconds(25));
  EXPECT_LE(*summaries[0].p99, absl::Milliseconds(50));
  EXPECT_EQ(summaries[1].method, "Train");
  EXPECT_EQ(summaries[1].calls, 1u);
}

// Calls from many threads while Prometheus scrapes and galleries come and go: every call is
// counted once and nothing races (this file also runs under TSan: label concurrency).
TEST(ServerMetricsTest, CallsScrapesAndGalleryChangesFromManyThreads) {
  MetricsOptions options;
  options.max_gallery_labels = 4;
  ServerMetrics metrics(options);
  auto registry = std::make_shared<GalleryRegistry>();
  metrics.SetSources(registry, {});
  constexpr int kThreads = 4, kCalls = 2000;
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t) {
    threads.emplace_back([&, t] {
      for (int i = 0; i < kCalls; ++i) {
        const std::string gallery = absl::StrCat("g", (t + i) % 8);
        metrics.RecordCall(Call("ClassifyCloud", gallery,
                                i % 10 == 0 ? absl::StatusCode::kNotFound : absl::StatusCode::kOk));
        metrics.ObserveDescribe("dfsd", absl::Microseconds(i));
        metrics.ObserveStoreWrite("append", absl::Microseconds(i), i % 7 != 0);
      }
    });
  }
  threads.emplace_back([&] {
    for (int i = 0; i < 40; ++i) {
      const std::string name = absl::StrCat("g", i % 8);
      if (!registry->Create(name, {}).ok()) (void)registry->Delete(name);
    }
  });
  threads.emplace_back([&] {
    for (int i = 0; i < 20; ++i) {
      EXPECT_FALSE(Scrape(metrics).empty());
      (void)metrics.MethodSummaries();
    }
  });
  for (std::thread& thread : threads) thread.join();
  const std::vector<MethodSummary> summaries = metrics.MethodSummaries();
  ASSERT_EQ(summaries.size(), 1u);
  EXPECT_EQ(summaries[0].calls, uint64_t{kThreads * kCalls});
  EXPECT_EQ(Value(metrics, R"(shapeid_describe_duration_seconds_count{descriptor="dfsd"})"),
            kThreads * kCalls);
  // Never more gallery labels than the limit, plus _other and _unknown.
  std::set<std::string> labels;
  const std::string text = Scrape(metrics);
  for (size_t at = 0; (at = text.find("gallery=\"", at)) != std::string::npos;) {
    at += 9;
    labels.insert(text.substr(at, text.find('"', at) - at));
  }
  labels.erase("_other");
  labels.erase("_unknown");
  EXPECT_LE(labels.size(), 4u);
}

TEST(HistogramQuantileTest, InterpolatesLikePrometheus) {
  const double inf = std::numeric_limits<double>::infinity();
  // 10 observations in (0, 1], 10 in (1, 2].
  EXPECT_DOUBLE_EQ(*HistogramQuantile(0.5, {1, 2, inf}, {10, 20, 20}), 1.0);
  EXPECT_DOUBLE_EQ(*HistogramQuantile(0.75, {1, 2, inf}, {10, 20, 20}), 1.5);
  EXPECT_DOUBLE_EQ(*HistogramQuantile(0.25, {1, 2, inf}, {10, 20, 20}), 0.5);
  // Past the last finite bound: that bound, as histogram_quantile answers.
  EXPECT_DOUBLE_EQ(*HistogramQuantile(0.99, {1, 2, inf}, {0, 0, 5}), 2.0);
  EXPECT_FALSE(HistogramQuantile(0.5, {1, 2, inf}, {0, 0, 0}).has_value());
  EXPECT_FALSE(HistogramQuantile(0.5, {}, {}).has_value());
}

}  // namespace
}  // namespace shapeid
