#!/usr/bin/env bash
# Installs every Debian 12 package shapeid needs to build, test and benchmark.
# Idempotent: apt-get skips what is already installed. Runs `apt-get update` itself,
# at most once an hour, so repeated test runs on one machine stay fast.
set -euo pipefail

packages=(
  # toolchain
  build-essential cmake ninja-build pkg-config ccache git
  # the format stage of tools/test.sh: C++ as clang-format 14 writes it (.clang-format)
  clang-format
  # core science
  libeigen3-dev libnanoflann-dev libabsl-dev
  # RPC stack (server, client library)
  libgrpc++-dev protobuf-compiler-grpc libprotobuf-dev protobuf-compiler
  zlib1g-dev  # CRC-32 of gallery exports; gzipped clouds and .npz members (core/io/gzip.cc)
  # CLI argument parsing: subcommands with typed options and generated --help
  libcli11-dev
  # LZF decompression of PCD DATA binary_compressed (core/io/pcd_reader.cc)
  liblzf-dev
  # OBJ meshes (core/io/obj_reader.cc): a maintained OBJ parser rather than a hand-written one
  libtinyobjloader-dev
  # the embedded gallery store (server/storage): SQLite, WAL mode, synchronous commits
  libsqlite3-dev
  # security (server/security/api_keys.cc, server/security/security.cc): libcrypto's SHA-256, CRYPTO_memcmp and
  # RAND_bytes for API keys, and the start-up check of TLS files; gRPC uses the same OpenSSL
  libssl-dev
  # the shared gallery store for several replicas (server/storage/postgres_gallery_store.cc):
  # libpq, PostgreSQL's own C client
  libpq-dev
  # Prometheus metrics (server/ops/metrics.cc): prometheus-cpp's registry, text format and /metrics
  # HTTP endpoint
  prometheus-cpp-dev
  # tests and benchmarks
  libgtest-dev libgmock-dev libbenchmark-dev
  # the operations test parses the server's JSON log lines and /metrics with a real JSON parser
  nlohmann-json3-dev
  # the scale-out tests start a private PostgreSQL server (server/storage/testing/postgres_instance.h)
  postgresql
  # the security tests make their certificates with the openssl CLI (tests/make_test_certificates.sh)
  openssl
  # reliability (docs/reliability.md): clang and libFuzzer for the fuzz targets, and
  # llvm-symbolizer for readable sanitizer reports (GCC's sanitizers use it too)
  clang-14 libclang-rt-14-dev llvm-14
  # the Python package (client/python): its stubs made by grpc_python_plugin (above), run by
  # Debian's /usr/bin/python3 over these
  python3-grpcio python3-protobuf python3-numpy
  # installing the Python package as docs/python.md says: pip, setuptools and wheel (offline,
  # --no-build-isolation), and venv for a --system-site-packages environment
  python3-pip python3-setuptools python3-wheel python3-venv
  # the Python package's tests (pytest) and the clouds robots hold: Open3D point clouds, ROS 1
  # sensor_msgs PointCloud2 messages (Debian's message classes import without a ROS master)
  python3-pytest python3-open3d python3-sensor-msgs
  # files as other tools write them, for the readers' tests: PCL's converters (VTK, PLY, PCD,
  # OBJ; tests/formats/cross_tool_formats.py, core/io/vtk_reader_test.cc), VTK's own writer
  # and numpy-stl (core/io/vtk_reader_test.cc, core/io/stl_reader_test.cc)
  pcl-tools python3-vtk9 python3-stl
  # the eval report's browser test (tests/report/report_browser_test.py): the page opened in
  # headless Chromium, its screenshot's pixels read with Pillow
  chromium python3-pil
)

sudo_if_needed() { if [ "$(id -u)" -eq 0 ]; then "$@"; else sudo "$@"; fi; }

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages present"
  exit 0
fi

stamp=/var/lib/apt/periodic/shapeid-update-stamp
if [ ! -f "$stamp" ] || [ -n "$(find "$stamp" -mmin +60 2>/dev/null)" ]; then
  sudo_if_needed apt-get update -q
  sudo_if_needed mkdir -p "$(dirname "$stamp")"
  sudo_if_needed touch "$stamp"
fi
echo "install-deps: installing ${missing[*]}"
DEBIAN_FRONTEND=noninteractive sudo_if_needed apt-get install -y -q --no-install-recommends "${missing[@]}"
