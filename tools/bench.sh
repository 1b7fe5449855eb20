#!/usr/bin/env bash
# Builds the release preset and runs the benchmarks as docs/performance.md quotes them:
# medians of 5 repetitions, single thread. Raw JSON goes to build/release/bench-results/.
# Usage: tools/bench.sh [extra Google Benchmark flags, e.g. --benchmark_filter=Rphsd]
set -euo pipefail
cd "$(dirname "$0")/.."
tools/install-deps.sh
cmake --preset release >/dev/null
cmake --build --preset release -j "$(nproc)"
out=build/release/bench-results
mkdir -p "$out"
lscpu | grep -E 'Model name|^CPU\(s\)|MHz|L2|L3' || true
for b in descriptor_bench knn_bench; do
  build/release/bench/$b --benchmark_repetitions=5 --benchmark_report_aggregates_only=true \
    --benchmark_out="$out/$b.json" --benchmark_out_format=json "$@"
done
