#!/usr/bin/env bash
# Runs every libFuzzer target of a fuzz build (cmake --preset fuzz) for a bounded time each,
# one target per core at a time, and fails if any finds a crash, a sanitizer report, a
# broken oracle, a leak, an allocation over the malloc limit or an input slower than the
# timeout. Called by tools/test.sh; also by hand for a longer hunt:
#
#   fuzz/run_fuzzers.sh [BUILD_DIR [SECONDS_PER_TARGET [TARGET...]]]
#   fuzz/run_fuzzers.sh build/fuzz 600 pcd_fuzzer      # ten minutes on the PCD reader
#
# Seeds: a reader's files of its formats in tests/fuzz_seeds/testdata (checked in) and tests/bad_input/testdata
# (malformed), fuzz/testdata/corpus/TARGET (the spec fuzzer's), the service seeds written by the
# build, and, where ../shared/data exists, a few real ModelNet10 PCD and DALES XYZ files. The corpus each target
# grows is kept in $SHAPEID_FUZZ_CACHE (default /var/tmp/shapeid-fuzz), so that a later run
# on the same machine starts where the last one stopped; deleting it is always safe.
# A crash leaves its input in BUILD_DIR/fuzz-run/TARGET/; the message says how to keep it as
# a regression test (fuzz/testdata/regressions/TARGET/, replayed by ctest in every build).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=$(cd "${1:-$root/build/fuzz}" && pwd)
seconds=${2:-60}
shift $(( $# > 2 ? 2 : $# ))
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
  targets=(pcd_fuzzer ply_fuzzer off_fuzzer obj_fuzzer xyz_fuzzer las_fuzzer npy_fuzzer vtk_fuzzer
           stl_fuzzer gzip_fuzzer descriptor_spec_fuzzer head_fuzzer model_fuzzer service_fuzzer)
fi
cache=${SHAPEID_FUZZ_CACHE:-/var/tmp/shapeid-fuzz}
out=$build/fuzz-run
data=$root/../shared/data
symbolizer=/usr/lib/llvm-14/bin/llvm-symbolizer
rm -rf "$out"
mkdir -p "$out"

# A reader's files by format, as read-only seeds: those of tests/fuzz_seeds/testdata (fuzz/make_seeds.py),
# the bad-input corpus's malformed ones (tests/bad_input/testdata), and a few real files.
real_seeds() {  # TARGET -> prints a directory (maybe empty)
  local dir=$out/real/$1 from
  mkdir -p "$dir"
  for from in "$root/tests/fuzz_seeds/testdata" "$root/tests/bad_input/testdata"; do
    case $1 in
      pcd_fuzzer) cp "$from"/*.pcd "$dir"/ 2>/dev/null || true ;;
      ply_fuzzer) cp "$from"/*.ply "$dir"/ 2>/dev/null || true ;;
      off_fuzzer) cp "$from"/*.off "$dir"/ 2>/dev/null || true ;;
      obj_fuzzer) cp "$from"/*.obj "$dir"/ 2>/dev/null || true ;;
      xyz_fuzzer) cp "$from"/*.xyz "$from"/*.txt "$from"/*.csv "$from"/*.pts "$from"/*.xyzn \
                    "$from"/*.xyzrgb "$dir"/ 2>/dev/null || true ;;
      las_fuzzer) cp "$from"/*.las "$dir"/ 2>/dev/null || true ;;
      npy_fuzzer) cp "$from"/*.npy "$from"/*.npz "$dir"/ 2>/dev/null || true ;;
      vtk_fuzzer) cp "$from"/*.vtk "$dir"/ 2>/dev/null || true ;;
      stl_fuzzer) cp "$from"/*.stl "$dir"/ 2>/dev/null || true ;;
      gzip_fuzzer) cp "$from"/*.gz "$dir"/ 2>/dev/null || true ;;
    esac
  done
  case $1 in
    pcd_fuzzer)
      if [ -d "$data/modelnet10" ]; then
        for class in "$data"/modelnet10/*/; do
          find "$class/test" -name '*.pcd' | sort | head -n 1 | xargs -r cp -t "$dir"
        done
      fi ;;
    xyz_fuzzer)
      if [ -d "$data/dales-objects" ]; then
        # the smallest object of each class: real sparse scans, quick to mutate
        for class in "$data"/dales-objects/*/; do
          find "$class" -name '*.xyz' -printf '%s %p\n' | sort -n | head -n 1 | cut -d' ' -f2- |
            while read -r f; do cp "$f" "$dir/$(basename "$class")-$(basename "$f")"; done
        done
      fi ;;
  esac
  echo "$dir"
}

run_one() {  # TARGET
  local target=$1 binary=$build/fuzz/$1
  local seeds=("$(real_seeds "$target")")
  [ -d "$root/fuzz/testdata/corpus/$target" ] && seeds+=("$root/fuzz/testdata/corpus/$target")
  [ "$target" = service_fuzzer ] && seeds+=("$build/fuzz/corpus/service_fuzzer")
  [ -d "$root/fuzz/testdata/regressions/$target" ] && seeds+=("$root/fuzz/testdata/regressions/$target")
  mkdir -p "$cache/$target" "$out/$target"
  # -malloc_limit_mb: a header announcing 10^12 points must be refused, not allocated.
  # -timeout: no input of these sizes may take seconds (a quadratic path would).
  ASAN_OPTIONS=detect_leaks=1:symbolize=1:external_symbolizer_path=$symbolizer \
  UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
    "$binary" -max_total_time="$seconds" -timeout=20 -rss_limit_mb=3072 -malloc_limit_mb=1024 \
      -print_final_stats=1 -artifact_prefix="$out/$target/" "$cache/$target" "${seeds[@]}" \
      > "$out/$target.log" 2>&1
}

summary() {  # TARGET STATUS
  local log=$out/$1.log
  local execs cov corpus
  execs=$(grep -o 'stat::number_of_executed_units: [0-9]*' "$log" | tail -n 1 | grep -o '[0-9]*$' || true)
  cov=$(grep -o 'cov: [0-9]*' "$log" | tail -n 1 | grep -o '[0-9]*$' || true)
  corpus=$(find "$cache/$1" -type f | wc -l)
  printf '%-24s %-5s %9s runs  coverage %6s  corpus %5s inputs\n' "$1" "$2" "${execs:-?}" \
    "${cov:-?}" "$corpus"
}

echo "fuzz: ${#targets[@]} targets, ${seconds} s each, $(nproc) at a time; corpus kept in $cache"
failed=()
declare -A running=()  # pid -> target
reap() {  # waits for any one target to end and reports it
  local pid status=0
  wait -n -p pid || status=$?
  local target=${running[$pid]}
  unset "running[$pid]"
  if [ "$status" -eq 0 ]; then summary "$target" ok; else summary "$target" FAIL; failed+=("$target"); fi
}
for target in "${targets[@]}"; do
  [ -x "$build/fuzz/$target" ] || { echo "fuzz: $build/fuzz/$target is not built"; exit 2; }
  while [ ${#running[@]} -ge "$(nproc)" ]; do reap; done
  run_one "$target" &
  running[$!]=$target
done
while [ ${#running[@]} -gt 0 ]; do reap; done

if [ ${#failed[@]} -gt 0 ]; then
  for target in "${failed[@]}"; do
    echo
    echo "=== $target failed; the end of its log ($out/$target.log):"
    grep -v '^#[0-9]' "$out/$target.log" | tail -n 40
    for artifact in "$out/$target"/*; do
      [ -e "$artifact" ] || continue
      echo "input: $artifact"
      echo "  reproduce: $build/fuzz/$target $artifact"
      echo "  keep as a regression test: cp $artifact $root/fuzz/testdata/regressions/$target/"
    done
  done
  exit 1
fi
echo "fuzz: no target found anything"
