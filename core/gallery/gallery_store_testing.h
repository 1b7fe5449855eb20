#ifndef SHAPEID_CORE_GALLERY_GALLERY_STORE_TESTING_H_
#define SHAPEID_CORE_GALLERY_GALLERY_STORE_TESTING_H_

// Test helper (header-only, gtest): the one definition of "two stored galleries are the
// same", shared by the store's and the export's round-trip tests.

#include <cstring>

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
  EXPECT_EQ(std::memcmp(&a.options.reject_distance, &b.options.reject_distance, sizeof(double)),
            0);
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
    ASSERT_EQ(a.samples[i].features.size(), b.samples[i].features.size()) << i;
    EXPECT_EQ(std::memcmp(a.samples[i].features.data(), b.samples[i].features.data(),
                          a.samples[i].features.size() * sizeof(float)),
              0)
        << "sample " << i << " features differ bitwise";
  }
}

}  // namespace gallery_testing
}  // namespace shapeid

#endif  // SHAPEID_CORE_GALLERY_GALLERY_STORE_TESTING_H_
