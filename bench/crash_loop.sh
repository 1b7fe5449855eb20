#!/usr/bin/env bash
# The crash test of issue 5 with more rounds than CI runs: kill -9 the server under 8 Train
# clients ROUNDS times, checking after every restart that each acknowledged stream is present
# in full and no stream is partial. Needs a built `ci` (or `dev`) preset.
#   bench/crash_loop.sh [ROUNDS=200] [BUILD_DIR=build/ci]
set -euo pipefail
cd "$(dirname "$0")/.."
rounds=${1:-200}
build=${2:-build/ci}
test_bin=$build/tests/persistence_e2e_test
[ -x "$test_bin" ] || { echo "crash_loop: build first: cmake --build --preset ci" >&2; exit 2; }
SHAPEID_CRASH_ROUNDS=$rounds "$test_bin" --gtest_filter='*KillDuringTraining*'
