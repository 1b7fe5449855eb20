// DFSD's output pinned bit for bit: hashes of ComputeWithPoseVariants (descriptor and pose
// variants, or the error) over many clouds and specs, recorded from the implementation that
// held whole clouds in memory, before the frames were computed in passes. Galleries store
// descriptors, so any change here needs a descriptor_version bump instead.
//
// To record after an intended change: SHAPEID_DFSD_GOLDEN_RECORD=1 ./dfsd_golden_test prints
// the tables below.

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <string>
#include <vector>

#include "Eigen/Core"
#include "absl/strings/str_cat.h"
#include "core/descriptor_registry.h"
#include "core/descriptors/dfsd_golden_clouds.h"
#include "core/fnv1a.h"
#include "gtest/gtest.h"

namespace shapeid {
namespace {

using dfsd_golden::MakeCloud;
using dfsd_golden::Shapes;

// Eigen sums the box frame's covariance in blocks whose size it derives from the L1 cache it
// detects (kc for a 3 x 10^5 by 10^5 x 3 product); the hashes hold for the blocking they were
// recorded with.
constexpr Eigen::Index kRecordedBlocking = 504;

Eigen::Index EigenBlocking() {
  Eigen::Index k = 100000, m = 3, n = 3;
  Eigen::internal::computeProductBlockingSizes<double, double, 1>(k, m, n, Eigen::Index{1});
  return k;
}

bool Recording() { return std::getenv("SHAPEID_DFSD_GOLDEN_RECORD") != nullptr; }

class Hash : public Fnv1a {
 public:
  using Fnv1a::Add;
  void Add(uint64_t v) { Add(&v, sizeof(v)); }
  void Add(const std::vector<float>& v) {
    Add(v.size());
    if (!v.empty()) Add(v.data(), v.size() * sizeof(float));
  }
};

const std::vector<std::string>& FrameSpecs() {
  static const std::vector<std::string> specs = {
      "dfsd",
      "dfsd:frame=pca",
      "dfsd:frame=axes",
      "dfsd:frame=upright",
      "dfsd:frame=upright,up=y",
      "dfsd:frame=upright,up=x",
      "dfsd:frame=upright,up=-z",
      "dfsd:frame=upright,up=-y",
      "dfsd:frame=upright,up=-x",
  };
  return specs;
}

// Every frame at its defaults, then other fields, sizes and grids for the four frames.
std::vector<std::string> AllSpecs() {
  std::vector<std::string> specs = FrameSpecs();
  for (const char* frame : {"box", "pca", "axes", "upright"}) {
    for (const char* rest : {"fields=isotropic", "fields=anisotropic,size=0.15",
                             "grid=7,order=5,size=1000", "grid=4,order=10"}) {
      specs.push_back(absl::StrCat("dfsd:frame=", frame, ",", rest));
    }
  }
  return specs;
}

// Folds every spec's result for `cloud` into `hash`; also checks that Compute agrees with
// ComputeWithPoseVariants.
void HashCloud(const PointCloud& cloud, const std::vector<std::string>& specs, bool check_compute,
               Hash* hash) {
  for (const std::string& text : specs) {
    auto descriptor = CreateDescriptor(text);
    ASSERT_TRUE(descriptor.ok()) << text << ": " << descriptor.status();
    std::vector<float> out, variants;
    const absl::Status status = (*descriptor)->ComputeWithPoseVariants(cloud, &out, &variants);
    hash->Add(static_cast<uint64_t>(status.code()));
    if (!status.ok()) continue;
    hash->Add(out);
    hash->Add(variants);
    if (check_compute) {
      auto alone = (*descriptor)->Compute(cloud);
      ASSERT_TRUE(alone.ok()) << text;
      EXPECT_EQ(std::memcmp(alone->data(), out.data(), out.size() * sizeof(float)), 0) << text;
    }
  }
}

void Check(const std::string& name, uint64_t value, const std::map<std::string, uint64_t>& golden) {
  if (Recording()) {
    std::printf("      {\"%s\", 0x%016llxULL},\n", name.c_str(),
                static_cast<unsigned long long>(value));
    return;
  }
  const auto it = golden.find(name);
  ASSERT_NE(it, golden.end()) << "no recorded hash for " << name;
  EXPECT_EQ(value, it->second) << name << ": DFSD's output changed";
}

// clang-format off
const std::map<std::string, uint64_t>& SmallGolden() {
  static const std::map<std::string, uint64_t> golden = {
      {"surface/3", 0x0ec58c14577a2e7bULL},
      {"surface/5", 0x1138fc9f2651ef33ULL},
      {"surface/14", 0x52b06f89e9973270ULL},
      {"surface/16", 0x47edc0b1d086b950ULL},
      {"surface/17", 0x54b565501fdc4b9fULL},
      {"surface/49", 0xd3549736c4781c22ULL},
      {"surface/505", 0xd9e6e65355e1b2c3ULL},
      {"surface/1009", 0xe2967d07c43db2aeULL},
      {"surface/4100", 0x9f882689bb5aa1caULL},
      {"surface_rotated/3", 0x04d8dd13745150a1ULL},
      {"surface_rotated/5", 0x0bdb2a53426fee30ULL},
      {"surface_rotated/14", 0x8668d4c53e9f43aaULL},
      {"surface_rotated/16", 0x58f22ec8d6cb240bULL},
      {"surface_rotated/17", 0x7aee4864793ddd87ULL},
      {"surface_rotated/49", 0x60f5d6c9e545fe77ULL},
      {"surface_rotated/505", 0xc0e2daa7d4ceb749ULL},
      {"surface_rotated/1009", 0x37d622b3a8f83f66ULL},
      {"surface_rotated/4100", 0xfb40327384bb4f38ULL},
      {"offset/3", 0x895b8b2874e0cf1cULL},
      {"offset/5", 0xf4a9c3c61e019839ULL},
      {"offset/14", 0xd40e6e841f95bbaeULL},
      {"offset/16", 0x30c89ceb88a8802cULL},
      {"offset/17", 0x7f696034007f8c0dULL},
      {"offset/49", 0x50c0a4fddba1a7c5ULL},
      {"offset/505", 0xa7821191b373c1d1ULL},
      {"offset/1009", 0x70269254c8752344ULL},
      {"offset/4100", 0xf1c2f3ac2f638865ULL},
      {"tiny/3", 0x6baa049dd926f842ULL},
      {"tiny/5", 0x530ebae6e2923b9eULL},
      {"tiny/14", 0x944e5012ccd74f3cULL},
      {"tiny/16", 0x3ff2a387f3176e48ULL},
      {"tiny/17", 0x35e34e9e892afd55ULL},
      {"tiny/49", 0x14175d160787897bULL},
      {"tiny/505", 0x392f429c00a26d26ULL},
      {"tiny/1009", 0xbd4b6097437731a9ULL},
      {"tiny/4100", 0xb6eee27dbf251f52ULL},
      {"uniform/3", 0x7c93f450d81f8f75ULL},
      {"uniform/5", 0xb37c42df5a31c2a5ULL},
      {"uniform/14", 0x4e2727adc42e04e3ULL},
      {"uniform/16", 0xf2c5e69553445666ULL},
      {"uniform/17", 0x55c91b3e17d06936ULL},
      {"uniform/49", 0x2c6a16a2180e970dULL},
      {"uniform/505", 0x56f5acaaa35d71f7ULL},
      {"uniform/1009", 0x6b4d6b6f2ab1f304ULL},
      {"uniform/4100", 0x38d528eff97795d1ULL},
      {"sphere/3", 0x71dc0268e72cfd10ULL},
      {"sphere/5", 0x89444c2434aa0d0fULL},
      {"sphere/14", 0x9fc10307dbcb8a05ULL},
      {"sphere/16", 0x24d8a7c0c3a75ea1ULL},
      {"sphere/17", 0x62c75d114d8ee9e7ULL},
      {"sphere/49", 0x7e7a20732118568eULL},
      {"sphere/505", 0x2f567603ea6512a9ULL},
      {"sphere/1009", 0x05ee7a26ba9cfec9ULL},
      {"sphere/4100", 0x569236d8ca63823eULL},
      {"flat/3", 0x8984f4a8d4f77cc1ULL},
      {"flat/5", 0x82c31e8971857417ULL},
      {"flat/14", 0xaba99fd839e26ebcULL},
      {"flat/16", 0x312d7ea9745faa07ULL},
      {"flat/17", 0x4ab84d648b31f5e7ULL},
      {"flat/49", 0x1ca410a5627a970fULL},
      {"flat/505", 0x0a6f4ffcdc12129dULL},
      {"flat/1009", 0xa139208a6cd8f555ULL},
      {"flat/4100", 0xe146adeb037acdd4ULL},
      {"flat_rotated/3", 0x5c729e2dd9639848ULL},
      {"flat_rotated/5", 0x09d67d91e4a184d3ULL},
      {"flat_rotated/14", 0x9f09b68914d4c201ULL},
      {"flat_rotated/16", 0x77aaa163b9a82285ULL},
      {"flat_rotated/17", 0x951068bd23ebf2b1ULL},
      {"flat_rotated/49", 0x356ee7bedffe959bULL},
      {"flat_rotated/505", 0xf062417d0e61d9bfULL},
      {"flat_rotated/1009", 0x3fbce986b1fcdf6aULL},
      {"flat_rotated/4100", 0xd9c1f81374c10e36ULL},
      {"flat_grid/3", 0x43c47ef31db7fc66ULL},
      {"flat_grid/5", 0xc77684294bea747cULL},
      {"flat_grid/14", 0x99d4b679e85e8140ULL},
      {"flat_grid/16", 0xaf3968905c2929d4ULL},
      {"flat_grid/17", 0xaf3968905c2929d4ULL},
      {"flat_grid/49", 0x5c2938b0ce3198b0ULL},
      {"flat_grid/505", 0xcf3b2b260ba29848ULL},
      {"flat_grid/1009", 0x95b8a3d4b3201fd8ULL},
      {"flat_grid/4100", 0xd6e3ecb9d7cabf24ULL},
      {"straight/3", 0x3cbc9c25c96a7b4dULL},
      {"straight/5", 0xdd452e073dc18685ULL},
      {"straight/14", 0xdb0603fb272d7e8dULL},
      {"straight/16", 0xd3f9982689f88a19ULL},
      {"straight/17", 0x0e512e04d616e4b9ULL},
      {"straight/49", 0xcecd10e9c6cf6dadULL},
      {"straight/505", 0xa8800397155522e1ULL},
      {"straight/1009", 0x40190465a35f1889ULL},
      {"straight/4100", 0x64c76b2059c55b69ULL},
      {"straight_noisy/3", 0xe0b698463ff26478ULL},
      {"straight_noisy/5", 0xd4fd345432ef3bc8ULL},
      {"straight_noisy/14", 0xe9027f7097924b33ULL},
      {"straight_noisy/16", 0x86492f4e457a7612ULL},
      {"straight_noisy/17", 0xb104f8947055f7c4ULL},
      {"straight_noisy/49", 0x6edf7bf438ccb7f3ULL},
      {"straight_noisy/505", 0xedcbacd4a3ed712dULL},
      {"straight_noisy/1009", 0x867dfe3d5b8afd40ULL},
      {"straight_noisy/4100", 0xad5adaf767cb775dULL},
      {"symmetric/3", 0x43c47ef31db7fc66ULL},
      {"symmetric/5", 0x43c47ef31db7fc66ULL},
      {"symmetric/14", 0xeb4c2170ee3a36ddULL},
      {"symmetric/16", 0x481007a13b595bcaULL},
      {"symmetric/17", 0xaf4ea0d9e1685dd0ULL},
      {"symmetric/49", 0x0be8609ca0f0eeaaULL},
      {"symmetric/505", 0x232a4b248157b206ULL},
      {"symmetric/1009", 0x43b5c50075ffec92ULL},
      {"symmetric/4100", 0xf97b0ba993a4ea3eULL},
      {"near_symmetric/3", 0x43c47ef31db7fc66ULL},
      {"near_symmetric/5", 0x43c47ef31db7fc66ULL},
      {"near_symmetric/14", 0xee2a5ce83b45e0ebULL},
      {"near_symmetric/16", 0x31ba5a8148c820e9ULL},
      {"near_symmetric/17", 0xb052d59d3425f732ULL},
      {"near_symmetric/49", 0xa281fea496b2ff71ULL},
      {"near_symmetric/505", 0xd71867eac862d84fULL},
      {"near_symmetric/1009", 0x0a77fc45c2f02a9aULL},
      {"near_symmetric/4100", 0x49260acfb5b70ac5ULL},
      {"duplicates/3", 0x43c47ef31db7fc66ULL},
      {"duplicates/5", 0x9e69019f2302d47bULL},
      {"duplicates/14", 0xb72208e0d8165f0dULL},
      {"duplicates/16", 0x5826d47e07c5722fULL},
      {"duplicates/17", 0xf24255e7fb09f3adULL},
      {"duplicates/49", 0x5115f00e3d372e48ULL},
      {"duplicates/505", 0xc47931ac6ee3e7ceULL},
      {"duplicates/1009", 0x2850a6245e0ad629ULL},
      {"duplicates/4100", 0xa140e02ab06a495aULL},
      {"few_distinct/3", 0x7361d29fcd0c64a3ULL},
      {"few_distinct/5", 0x65a72a0e17b767a8ULL},
      {"few_distinct/14", 0x0af1086eba84f3fdULL},
      {"few_distinct/16", 0x263e99c6b532721dULL},
      {"few_distinct/17", 0xb4264076ec5d78acULL},
      {"few_distinct/49", 0x1c59c7af8eef8497ULL},
      {"few_distinct/505", 0x82fe28d1777a1748ULL},
      {"few_distinct/1009", 0x2e55ff93034fdb24ULL},
      {"few_distinct/4100", 0x824fc5f98234fc1dULL},
      {"cube_lattice/3", 0x43c47ef31db7fc66ULL},
      {"cube_lattice/5", 0x43c47ef31db7fc66ULL},
      {"cube_lattice/14", 0x4aaa08f0da083eb5ULL},
      {"cube_lattice/16", 0x4aaa08f0da083eb5ULL},
      {"cube_lattice/17", 0x4aaa08f0da083eb5ULL},
      {"cube_lattice/49", 0x452cf29c35b23b3dULL},
      {"cube_lattice/505", 0xb9ca0045a915deddULL},
      {"cube_lattice/1009", 0xfadcbf0ab0fa0215ULL},
      {"cube_lattice/4100", 0x2b018bf356ded9e1ULL},
      {"cylinder/3", 0xf74fc6c969d59e7bULL},
      {"cylinder/5", 0xb979df1a0ac14e41ULL},
      {"cylinder/14", 0xeb730330f982f583ULL},
      {"cylinder/16", 0x2113d0169a8879d0ULL},
      {"cylinder/17", 0x59bd59a2d3aa09d5ULL},
      {"cylinder/49", 0x86194bd57a876c9fULL},
      {"cylinder/505", 0x273b32d8d1b9d33bULL},
      {"cylinder/1009", 0x9bfe0e9662465879ULL},
      {"cylinder/4100", 0x1aae861da6c9a549ULL},
      {"signed_zeros/3", 0x43c47ef31db7fc66ULL},
      {"signed_zeros/5", 0x756cb923937e4604ULL},
      {"signed_zeros/14", 0x35bbcb5c83f781abULL},
      {"signed_zeros/16", 0x7befee86c17bab70ULL},
      {"signed_zeros/17", 0xe2853d2d49deb66dULL},
      {"signed_zeros/49", 0xf79bd74e10b2917bULL},
      {"signed_zeros/505", 0x8ad54efce6951690ULL},
      {"signed_zeros/1009", 0x951fc4f433fe844aULL},
      {"signed_zeros/4100", 0x3978ce5bc626b470ULL},
      {"square_prism/3", 0x56b7ed4548567e96ULL},
      {"square_prism/5", 0x1b4ebc8c1cef9577ULL},
      {"square_prism/14", 0x444112dea6763a0fULL},
      {"square_prism/16", 0x14a07af84f0b11afULL},
      {"square_prism/17", 0x69a7d89478497eeaULL},
      {"square_prism/49", 0x91f4e24b8e903396ULL},
      {"square_prism/505", 0x9f288b133c9c665eULL},
      {"square_prism/1009", 0xa251973a2e37cb94ULL},
      {"square_prism/4100", 0xfb1662645e4a6315ULL},
  };
  return golden;
}

const std::map<std::string, uint64_t>& LargeGolden() {
  static const std::map<std::string, uint64_t> golden = {
      {"surface_rotated/300000", 0x3f36eb223fe99e17ULL},
      {"surface/262145", 0x628d44417703ebd2ULL},
      {"flat_grid/300000", 0xd72cd8fa7206fd9dULL},
      {"straight/262145", 0x1a44ae2f6171bafbULL},
      {"cylinder/270000", 0x2f35664ffd27fdf9ULL},
      {"signed_zeros/262148", 0x4b7d99cd8223c435ULL},
      {"duplicates/300000", 0x3a9d772223ddfa5fULL},
      {"symmetric/280000", 0x62a20e073c69871fULL},
  };
  return golden;
}
// clang-format on

TEST(DfsdGoldenTest, SmallCloudsEverySpec) {
  if (EigenBlocking() != kRecordedBlocking) {
    GTEST_SKIP() << "Eigen blocks this machine's products by " << EigenBlocking() << ", not "
                 << kRecordedBlocking << " (another L1 cache size), so box-frame "
                 << "covariances round differently here than where the hashes were recorded";
  }
  const std::vector<std::string> specs = AllSpecs();
  for (const std::string& shape : Shapes()) {
    for (size_t n : {3, 5, 14, 16, 17, 49, 505, 1009, 4100}) {
      Hash hash;
      HashCloud(MakeCloud(shape, n), specs, /*check_compute=*/true, &hash);
      Check(absl::StrCat(shape, "/", n), hash.value(), SmallGolden());
    }
  }
}

// Above 2^18 points the distance kernel runs in chunks; the frames see every point.
TEST(DfsdGoldenTest, LargeClouds) {
  if (EigenBlocking() != kRecordedBlocking) {
    GTEST_SKIP() << "Eigen blocks this machine's products by " << EigenBlocking() << ", not "
                 << kRecordedBlocking << " (another L1 cache size)";
  }
  struct Case {
    const char* shape;
    size_t n;
    std::vector<std::string> specs;
  };
  const std::vector<Case> cases = {
      {"surface_rotated", 300000, FrameSpecs()},
      {"surface", 262145, {"dfsd", "dfsd:frame=axes,fields=anisotropic,size=0.15"}},
      {"flat_grid", 300000, {"dfsd", "dfsd:frame=upright"}},
      {"straight", 262145, {"dfsd", "dfsd:frame=pca"}},
      {"cylinder", 270000, {"dfsd", "dfsd:frame=upright"}},
      {"signed_zeros", 262148, {"dfsd", "dfsd:frame=upright,up=-x"}},
      {"duplicates", 300000, {"dfsd", "dfsd:frame=pca"}},
      {"symmetric", 280000, {"dfsd"}},
  };
  for (const Case& c : cases) {
    Hash hash;
    HashCloud(MakeCloud(c.shape, c.n), c.specs, /*check_compute=*/false, &hash);
    Check(absl::StrCat(c.shape, "/", c.n), hash.value(), LargeGolden());
  }
}

// clang-format off
const std::map<std::string, uint64_t>& SmoothedGolden() {
  static const std::map<std::string, uint64_t> golden = {
      {"surface/5", 0xb70ab6dd97f25203ULL},
      {"surface/505", 0xe68c7ddfc5407189ULL},
      {"surface/5000", 0x1725c400ca417f79ULL},
      {"surface_rotated/5", 0x524dcea61e6e220fULL},
      {"surface_rotated/505", 0x5ce970d61dcac729ULL},
      {"surface_rotated/5000", 0x3ec94e28e5a3b51dULL},
      {"offset/5", 0x3def693dbcf05fbfULL},
      {"offset/505", 0x4b11153de8e559fdULL},
      {"offset/5000", 0x8ca7ab61f2c03cf1ULL},
      {"tiny/5", 0xa5af8e7c328511e7ULL},
      {"tiny/505", 0x8b6610c7f7d49595ULL},
      {"tiny/5000", 0x56e87c13e216baa9ULL},
      {"uniform/5", 0xfc877589c7a49ac9ULL},
      {"uniform/505", 0x3ec1a0a4c47eaffdULL},
      {"uniform/5000", 0x3dc5e25ba115eb29ULL},
      {"sphere/5", 0x4a2a09135f177b63ULL},
      {"sphere/505", 0xa00f93bd19c8d65bULL},
      {"sphere/5000", 0x205139f24016ce9bULL},
      {"flat/5", 0x1818d3291fa417bfULL},
      {"flat/505", 0xdb72b6aa4012584dULL},
      {"flat/5000", 0xda992decbeac2e8dULL},
      {"flat_rotated/5", 0x3844f88d43d5dce5ULL},
      {"flat_rotated/505", 0x7f5a24872647a019ULL},
      {"flat_rotated/5000", 0x853f32aa55658785ULL},
      {"flat_grid/5", 0x9b802e9ed885aa9dULL},
      {"flat_grid/505", 0xcfcb3d30bacc2b7dULL},
      {"flat_grid/5000", 0x9ce7969f2b02fb89ULL},
      {"straight/5", 0xaa8c2accfaea54e3ULL},
      {"straight/505", 0x0df6319a584502f1ULL},
      {"straight/5000", 0xf426cf31ba10c221ULL},
      {"straight_noisy/5", 0xe883c48fdc66176cULL},
      {"straight_noisy/505", 0x996f8793fded4c65ULL},
      {"straight_noisy/5000", 0xff9093c1278cc4a9ULL},
      {"symmetric/5", 0xb8236e7869253285ULL},
      {"symmetric/505", 0x5d3c7458a8268e95ULL},
      {"symmetric/5000", 0x6b8e8e413cae00edULL},
      {"near_symmetric/5", 0xb8236e7869253285ULL},
      {"near_symmetric/505", 0xd1565bbc5bb03019ULL},
      {"near_symmetric/5000", 0xc914c95ca4a4e545ULL},
      {"duplicates/5", 0x4a5881cf1c08a20aULL},
      {"duplicates/505", 0xcd0b43efcbbcbcf9ULL},
      {"duplicates/5000", 0x674c61ea2e6c6725ULL},
      {"few_distinct/5", 0x55b65e03cccad8c2ULL},
      {"few_distinct/505", 0x77b31202357460c5ULL},
      {"few_distinct/5000", 0x7c1517b6f106c8d7ULL},
      {"cube_lattice/5", 0xb8236e7869253285ULL},
      {"cube_lattice/505", 0x2774520c186bac2fULL},
      {"cube_lattice/5000", 0xae690f28bbb06e17ULL},
      {"cylinder/5", 0xda00414b37cad7f2ULL},
      {"cylinder/505", 0xa08e9c3e0205a391ULL},
      {"cylinder/5000", 0x488ec6f3396d8a9dULL},
      {"signed_zeros/5", 0x69d3081269557275ULL},
      {"signed_zeros/505", 0x4a0f57c02249c215ULL},
      {"signed_zeros/5000", 0xc9453d2dbd2e4061ULL},
      {"square_prism/5", 0x2427a587ecfbf3f5ULL},
      {"square_prism/505", 0xa0289fbada257e1dULL},
      {"square_prism/5000", 0x360c97f749e099a1ULL},
  };
  return golden;
}
// clang-format on

// Smoothing (step 0 of docs/descriptors.md section 5): its neighbors, ties, reduction seed
// and floor shape stored vectors too. Below and past the 4,096 points it reduces to.
TEST(DfsdGoldenTest, SmoothedClouds) {
  if (EigenBlocking() != kRecordedBlocking) {
    GTEST_SKIP() << "Eigen blocks this machine's products by " << EigenBlocking() << ", not "
                 << kRecordedBlocking << " (another L1 cache size)";
  }
  const std::vector<std::string> specs = {"dfsd:smooth=0.015", "dfsd:frame=upright,smooth=0.05"};
  for (const std::string& shape : Shapes()) {
    for (size_t n : {5, 505, 5000}) {
      Hash hash;
      HashCloud(MakeCloud(shape, n), specs, /*check_compute=*/false, &hash);
      Check(absl::StrCat(shape, "/", n), hash.value(), SmoothedGolden());
    }
  }
}

}  // namespace
}  // namespace shapeid
