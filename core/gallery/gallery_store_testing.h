#ifndef SHAPEID_CORE_GALLERY_GALLERY_STORE_TESTING_H_
#define SHAPEID_CORE_GALLERY_GALLERY_STORE_TESTING_H_

// Test helpers (header-only, gtest): the one definition of "two stored galleries are the
// same", shared by the stores' and the export's round-trip tests, and the gallery they store.

#include <cstdint>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/time/time.h"
#include "core/gallery/gallery.h"
#include "core/gallery/gallery_store.h"
#include "core/views/augment.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace gallery_testing {

// Every field equal, and every double and float equal bit for bit (a lossy copy, e.g. via
// text, would change -0.0, subnormals or the last bits).
inline void ExpectSameStoredGallery(const StoredGallery& a, const StoredGallery& b) {
  EXPECT_EQ(a.name, b.name);
  EXPECT_EQ(a.options.descriptor_spec, b.options.descriptor_spec);
  EXPECT_EQ(a.options.knn.k, b.options.knn.k);
  EXPECT_EQ(a.options.knn.weighting, b.options.knn.weighting);
  EXPECT_EQ(a.options.knn.scaling, b.options.knn.scaling);
  EXPECT_EQ(std::memcmp(&a.options.reject_distance, &b.options.reject_distance, sizeof(double)), 0);
  EXPECT_EQ(AugmentOptionsToString(a.options.augment), AugmentOptionsToString(b.options.augment));
  EXPECT_EQ(a.created, b.created);
  EXPECT_EQ(a.updated, b.updated);
  EXPECT_EQ(a.descriptor_version, b.descriptor_version);
  EXPECT_EQ(a.software_version, b.software_version);
  EXPECT_EQ(a.dimension, b.dimension);
  ASSERT_EQ(a.samples.size(), b.samples.size());
  for (size_t i = 0; i < a.samples.size(); ++i) {
    EXPECT_EQ(a.samples[i].id, b.samples[i].id) << i;
    EXPECT_EQ(a.samples[i].label, b.samples[i].label) << i;
    EXPECT_EQ(a.samples[i].provenance.source, b.samples[i].provenance.source) << i;
    EXPECT_EQ(a.samples[i].provenance.metadata, b.samples[i].provenance.metadata) << i;
    ASSERT_EQ(a.samples[i].features.size(), b.samples[i].features.size()) << i;
    EXPECT_EQ(std::memcmp(a.samples[i].features.data(), b.samples[i].features.data(),
                          a.samples[i].features.size() * sizeof(float)),
              0)
        << "sample " << i << " features differ bitwise";
  }
}

// A stored gallery of `samples` random samples of `dimension` floats, `seed` choosing them,
// for the stores' round-trip tests: client ids and assigned ids (>= 2^63) alternate, the first
// label is not ASCII, and bit patterns a lossy path would change (-0, a subnormal, the largest
// float) lead the first sample; every third sample has provenance. It has an incarnation, as
// a created gallery has.
inline StoredGallery MakeGallery(std::string name, int dimension, int samples, uint32_t seed) {
  StoredGallery g;
  g.name = std::move(name);
  g.incarnation = NewGalleryIncarnation();
  g.options.descriptor_spec = "rphsd:bins=100,refs=cubic27,variant=complete";
  g.options.knn.k = 3;
  g.options.knn.weighting = VoteWeighting::kDistance;
  g.options.knn.scaling = FeatureScaling::kMaxAbs;
  g.options.reject_distance = 0.1 + 1e-17;  // a double that text round trips could lose
  g.created = absl::FromUnixNanos(1'700'000'000'123'456'789);
  g.updated = g.created + absl::Nanoseconds(7);
  g.descriptor_version = 1;
  g.software_version = "0.1.0";
  g.dimension = dimension;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  for (int i = 0; i < samples; ++i) {
    StoredSample s;
    s.id = i % 2 ? (uint64_t{1} << 63) + static_cast<uint64_t>(i) : static_cast<uint64_t>(i + 1);
    s.label = absl::StrCat("class-", i % 5, i == 0 ? " \xc3\xa9t\xc3\xa9" : "");
    s.features.resize(static_cast<size_t>(dimension));
    for (float& f : s.features) f = u(rng);
    // Provenance on every third sample (the others have none, as most do).
    if (i % 3 == 0) {
      s.provenance.source = absl::StrCat("scans/", i, i == 0 ? "/caf\xc3\xa9.pcd" : ".pcd");
      if (i % 2 == 0) s.provenance.metadata = {{"camera", "d435"}, {"seed", absl::StrCat(seed)}};
    }
    g.samples.push_back(std::move(s));
  }
  if (samples > 0 && dimension >= 3) {
    g.samples[0].features[0] = -0.0f;
    g.samples[0].features[1] = std::numeric_limits<float>::denorm_min();
    g.samples[0].features[2] = std::numeric_limits<float>::max();
  }
  return g;
}

// Provenance at the limits of sample_provenance.h, different for every `i`: a 4,096-byte
// source and 64 pairs of a 16-byte key and a 48-byte value (4,096 bytes of keys and values).
inline SampleProvenance ProvenanceAtLimits(uint64_t i) {
  const auto filled = [](const std::string& text, size_t bytes) {
    std::string out;
    while (out.size() < bytes) out += text;
    return std::string(out.data(), bytes);  // no spare capacity, as a copy has none
  };
  SampleProvenance p;
  p.source = filled(absl::StrCat("/data/scans/cloud-", i, ".pcd/"), kMaxSourceBytes);
  for (int k = 0; k < 64; ++k) {
    p.metadata.emplace_back(filled(absl::StrCat("key", k < 10 ? "0" : "", k, "-"), 16),
                            filled(absl::StrCat("value of ", i, " at ", k, "; "), 48));
  }
  return p;
}

}  // namespace gallery_testing
}  // namespace shapeid

#endif  // SHAPEID_CORE_GALLERY_GALLERY_STORE_TESTING_H_
