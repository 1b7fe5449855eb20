#!/usr/bin/env bash
# The test command (README, .ci/run). On a fresh Debian 12 machine it installs the packages,
# then runs six stages; the first failure (a sanitizer report included) stops it, non-zero:
#   format     every tracked C++ file (.h .cc .inc) as clang-format-14 writes it (.clang-format);
#              `clang-format -i FILE` fixes one; a few seconds;
#   ci         the `ci` preset (optimized, assertions on, warnings are errors): every test;
#   container  deploy/test_container.sh: the image of deploy/Dockerfile built with buildah,
#              run, trained, restarted on its volume (base images and layers are reused
#              between runs on one machine);
#   asan       the `asan` preset: every test again under AddressSanitizer + UndefinedBehavior-
#              Sanitizer, leaks included;
#   tsan       the `tsan` preset: the tests marked CONCURRENT under ThreadSanitizer;
#   fuzz       the `fuzz` preset (clang, libFuzzer): each fuzz target for
#              $SHAPEID_FUZZ_SECONDS (default 60) seconds (fuzz/run_fuzzers.sh).
# `tools/test.sh asan tsan` runs only those stages. Tests that need ../shared/data skip with a
# message where it is absent. docs/reliability.md says what each stage proves.
set -euo pipefail
cd "$(dirname "$0")/.."

stages=("$@")
[ ${#stages[@]} -gt 0 ] || stages=(format ci container asan tsan fuzz)

tools/install-deps.sh

# ccache is shared by every clone on this machine (CI tests a fresh clone each time): paths
# under the clone are hashed relative to it, and the sanitizer builds need more room than
# ccache's default 5 GB. Only compiler outputs are cached, never test results.
export CCACHE_BASEDIR=$PWD CCACHE_NOHASHDIR=true
export CCACHE_MAXSIZE=${CCACHE_MAXSIZE:-16G}
export ASAN_SYMBOLIZER_PATH=/usr/lib/llvm-14/bin/llvm-symbolizer
# install-deps installs PostgreSQL: here a test that cannot start one fails rather than skips.
export SHAPEID_REQUIRE_POSTGRES=1
# The report test opens the eval report in Chromium (installed above): never a silent skip here.
export SHAPEID_REQUIRE_BROWSER=1

# Every stage's build tree lives in the clone (about 8 GB for all six): warn at once when the
# disk cannot hold them, rather than fail in a link with "No space left on device".
free_gb=$(df -Pk . | awk 'NR == 2 { print int($4 / 1048576) }')
if [ "$free_gb" -lt 10 ]; then
  echo "test.sh: WARNING: only $free_gb GB free under $PWD; all stages need about 10 GB" >&2
fi

timings=()
stage() {  # NAME COMMAND...
  local name=$1 start=$SECONDS
  shift
  echo "=== test.sh: $name"
  "$@"
  timings+=("$(printf '%-10s %3d min %02d s' "$name" $(((SECONDS - start) / 60)) $(((SECONDS - start) % 60)))")
}
preset() {  # NAME: configure, build and test one preset
  cmake --preset "$1"
  cmake --build --preset "$1" -j "$(nproc)"
  # testing::TempDir() honours TEST_TMPDIR: each run's test files go to a fresh folder of the
  # build tree, not to /tmp, where thousands of runs' leftovers once filled the disk.
  export TEST_TMPDIR="$PWD/build/$1/test-tmp"
  rm -rf "$TEST_TMPDIR" && mkdir -p "$TEST_TMPDIR"
  ctest --preset "$1"
}

for s in "${stages[@]}"; do
  case $s in
    format)
      stage format bash -c "git ls-files -z '*.h' '*.cc' '*.inc' | xargs -0 clang-format --dry-run -Werror" ;;
    ci|asan|tsan) stage "$s" preset "$s" ;;
    container) stage container deploy/test_container.sh build/ci/client/cli/shapeid ;;
    fuzz)
      stage fuzz bash -c 'cmake --preset fuzz && cmake --build --preset fuzz -j "$(nproc)" &&
        fuzz/run_fuzzers.sh build/fuzz "${SHAPEID_FUZZ_SECONDS:-60}"' ;;
    *) echo "test.sh: unknown stage '$s' (format, ci, container, asan, tsan, fuzz)" >&2; exit 2 ;;
  esac
done
echo "=== test.sh: all stages passed"
printf '  %s\n' "${timings[@]}"
