#!/usr/bin/env bash
# The test command (README, .ci/run): on a fresh Debian 12 machine, installs the packages,
# builds the `ci` preset (optimised, assertions on, warnings are errors) and runs every test,
# then the container test (deploy/test_container.sh: the image built from deploy/Dockerfile
# with buildah, run, trained, restarted on its volume; base images and layers are reused
# between runs on one machine). Tests that need ../shared/data skip with a message where it
# is absent.
set -euo pipefail
cd "$(dirname "$0")/.."

tools/install-deps.sh
cmake --preset ci
cmake --build --preset ci -j "$(nproc)"
ctest --preset ci
deploy/test_container.sh build/ci/client/cli/shapeid
