#!/bin/sh
# Link launcher for the shapeid CLI (CMake's RULE_LAUNCH_LINK): runs the link command it is
# given with each system shared library swapped for its static archive where Debian ships one
# (gRPC, protobuf, Abseil, OpenSSL, re2, c-ares). Libraries without an archive stay shared.
# Why: loading and relocating ~60 shared libraries cost the CLI ~11 ms at every start
# (docs/performance.md, "Whole process"), more than reading a 12 MB cloud.
set -eu
for arg in "$@"; do
  shift
  case "$arg" in
    /usr/lib/*.so | /usr/lib/*.so.*)
      archive="${arg%%.so*}.a"
      if [ -f "$archive" ]; then arg="$archive"; fi
      ;;
    -lc | -lm | -ldl | -lrt | -lpthread | -latomic | -lgcc | -lgcc_s | -lstdc++) ;;  # C runtime
    -l*)
      for dir in /usr/lib/x86_64-linux-gnu /usr/lib/aarch64-linux-gnu /usr/lib; do
        if [ -f "$dir/lib${arg#-l}.a" ]; then
          arg="-l:lib${arg#-l}.a"
          break
        fi
      done
      ;;
  esac
  set -- "$@" "$arg"
done
exec "$@"
