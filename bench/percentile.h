#ifndef SHAPEID_BENCH_PERCENTILE_H_
#define SHAPEID_BENCH_PERCENTILE_H_

// The quantile the benchmarks report latencies by.

#include <algorithm>
#include <cstddef>
#include <vector>

namespace shapeid::bench {

// The q-quantile (q in [0, 1]) of `values` by nearest rank, one of the values; 0 when empty.
template <typename T>
T Percentile(std::vector<T> values, double q) {
  if (values.empty()) return 0;
  std::sort(values.begin(), values.end());
  return values[std::min(values.size() - 1,
                         static_cast<size_t>(q * static_cast<double>(values.size() - 1) + 0.5))];
}

}  // namespace shapeid::bench

#endif  // SHAPEID_BENCH_PERCENTILE_H_
