#!/usr/bin/env bash
# Issue 39's lockout, tried as a lab hits it: one server with --max_caller_backlog_seconds=1,
# then from one loopback host (one caller: every process of the host together) 20 trainings
# of ModelNet10 in a row (3,991 clouds each, the default dfsd, 4 jobs, a fresh gallery each
# time) and 100,000 small Classify calls (the 908 test clouds, 111 rounds). Before the fix the
# first training lost half its files to RESOURCE_EXHAUSTED and every later call was refused
# for good. Prints the refusals per step and the server's caller backlog (/metrics) once
# idle; exits 1 if anything was refused for backlog or the backlog is not back to 0.
#
#   bench/caller_backlog.sh [BUILD_DIR]      (default build/release; needs ../shared/data)
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build/release}
data=../shared/data/modelnet10
[ -d "$data" ] || { echo "caller_backlog.sh: $data is absent" >&2; exit 2; }
work=$(mktemp -d)
trap 'kill "$server_pid" 2>/dev/null || true; rm -rf "$work"' EXIT

metrics_port=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')
"$build/server/shapeid-server" --listen=127.0.0.1:0 --data_dir="$work/data" \
  --max_caller_backlog_seconds=1 --metrics_listen=127.0.0.1:$metrics_port \
  --log_level=warning >"$work/server.log" 2>&1 &
server_pid=$!
for _ in $(seq 100); do grep -q '^listening on ' "$work/server.log" && break; sleep 0.1; done
export SHAPEID_SERVER=$(sed -n 's/^listening on //p' "$work/server.log" | head -1)
cli=$build/client/cli/shapeid
backlog() {
  python3 -c 'import sys, urllib.request
for line in urllib.request.urlopen(sys.argv[1]).read().decode().splitlines():
    if line.startswith("shapeid_caller_backlog_seconds "): print(line.split()[1])' \
    "http://127.0.0.1:$metrics_port/metrics"
}

refused_total=0
start=$SECONDS
for round in $(seq 20); do
  "$cli" gallery create "mn10-$round" >/dev/null
  "$cli" train --gallery "mn10-$round" --jobs 4 "$data" >"$work/train.out" 2>"$work/train.err" || true
  refused=$(grep -c 'RESOURCE_EXHAUSTED\|caller already has' "$work/train.err" || true)
  refused_total=$((refused_total + refused))
  printf 'train %2d: %s; refused %d; backlog now %s s\n' "$round" \
    "$(tail -1 "$work/train.out")" "$refused" "$(backlog)"
done
echo "20 trainings: $((SECONDS - start)) s"
start=$SECONDS
calls=0
for round in $(seq 111); do
  "$cli" classify --gallery mn10-1 --jobs 4 --format csv "$data"/*/test >"$work/classify.out" \
    2>"$work/classify.err" || true
  refused=$(grep -c 'RESOURCE_EXHAUSTED\|caller already has' "$work/classify.err" || true)
  refused_total=$((refused_total + refused))
  calls=$((calls + 908))
done
echo "classify: $calls calls in $((SECONDS - start)) s; refused $refused_total in all"
sleep 1
idle_backlog=$(backlog)
echo "caller backlog once idle: $idle_backlog s (shapeid_caller_backlog_seconds)"
[ "$refused_total" -eq 0 ] && [ "$idle_backlog" = "0" ]
