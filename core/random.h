#ifndef SHAPEID_CORE_RANDOM_H_
#define SHAPEID_CORE_RANDOM_H_

// The project's seeded generator. Standard library distributions differ between
// implementations; this one is defined bit for bit, so a seed gives the same samples, views
// and folds on every platform.

#include <cstdint>

namespace shapeid {

// splitmix64 (Steele, Lea and Flood 2014): a small, fast generator with a fixed definition.
class SplitMix64 {
 public:
  explicit SplitMix64(uint64_t seed) : state_(seed) {}
  uint64_t Next() {
    uint64_t z = (state_ += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
  }
  // Uniform in [0, 1), 53 random bits.
  double Uniform() { return static_cast<double>(Next() >> 11) * 0x1.0p-53; }

 private:
  uint64_t state_;
};

}  // namespace shapeid

#endif  // SHAPEID_CORE_RANDOM_H_
