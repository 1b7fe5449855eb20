#!/usr/bin/env bash
# The container image, built and run for real (issue 8). Run as root on Debian 12, from CI or by
# hand:
#
#   deploy/test_container.sh [PATH-TO-HOST-shapeid-CLI]     (default: build/ci/client/cli/shapeid,
#                                                             or $SHAPEID_CLI)
#
# 1. checks the compose and Kubernetes manifests and the Grafana dashboard offline
#    (deploy/check_manifests.py; both variants: one server, replicas over PostgreSQL);
# 2. makes the debian:bookworm and debian:bookworm-slim base images offline with debootstrap
#    when podman does not have them yet (nothing is pulled from a registry; later runs reuse them);
# 3. builds deploy/Dockerfile with `buildah bud --layers` (cached layers and a ccache mount make
#    a rebuild fast);
# 4. starts the server from the image with `buildah run --isolation chroot` (podman's OCI runtime
#    cannot set resource limits in this sandbox) on a host directory mounted as its volume, as
#    the image's user; creates a gallery, trains and classifies from the host CLI; runs the
#    image's HEALTHCHECK command; stops the server with SIGTERM (it must exit 0);
# 5. starts it again on the same volume: the gallery, its samples and every answer are unchanged;
# 6. starts it a third time with a read-only root file system and a tmpfs /tmp, as compose and
#    Kubernetes run it, and writes to the volume;
# 7. checks the user is non-root and owns the data, and that the image is under the size limit.
#
# Environment: SHAPEID_CLI (host CLI), SHAPEID_TEST_IMAGE (tag, default localhost/shapeid:test),
# SHAPEID_IMAGE_MAX_MB (default 150), SHAPEID_BUILD_JOBS (compile jobs in the image, default all
# cores), SHAPEID_KEEP_WORK=1 (keep the work directory: logs, volume, dataset).
# Prints a PASS or FAIL line per check and the time of every step; exits non-zero on any FAIL.
set -euo pipefail
cli=${1:-${SHAPEID_CLI:-}}
[ -z "$cli" ] || cli=$(realpath -m "$cli")  # before the cd below: relative to the caller
cd "$(dirname "$0")/.."
repo=$(pwd)
cli=${cli:-$repo/build/ci/client/cli/shapeid}
image=${SHAPEID_TEST_IMAGE:-localhost/shapeid:test}
max_mb=${SHAPEID_IMAGE_MAX_MB:-150}
base=docker.io/library/debian
mirror=http://deb.debian.org/debian

# --- reporting ---------------------------------------------------------------------------------
script_start=$(date +%s.%N)
step_start=$script_start
step_name=
timings=()
elapsed() { awk -v a="$1" -v b="$(date +%s.%N)" 'BEGIN { printf "%.1f", b - a }'; }
step() {
  end_step
  step_name=$1
  step_start=$(date +%s.%N)
  printf '\n==> %s\n' "$step_name"
}
end_step() {
  [ -n "$step_name" ] || return 0
  local took
  took=$(elapsed "$step_start")
  timings+=("$(printf '%7.1f s  %s' "$took" "$step_name")")
  step_name=
}
passed=0
pass() {
  printf 'PASS: %s\n' "$*"
  passed=$((passed + 1))
}
fail() {
  printf 'FAIL: %s\n' "$*" >&2
  exit 1
}

# --- clean-up, also on failure -------------------------------------------------------------------
work=
containers=()
server_runner=  # the background job that runs the server (`buildah run` or chroot)
cleanup() {
  local status=$?
  set +e
  if [ -n "$server_runner" ] && kill -0 "$server_runner" 2>/dev/null; then
    local pid
    pid=$(server_pid)
    [ -n "$pid" ] && kill -TERM "$pid" 2>/dev/null
    if ! wait_gone "$server_runner" 15; then
      [ -n "$pid" ] && kill -KILL "$pid" 2>/dev/null
      kill -KILL "$server_runner" 2>/dev/null
    fi
    wait "$server_runner" 2>/dev/null
  fi
  [ -n "$work" ] && unmount_under "$work"  # the read-only root's mounts, before buildah rm
  for c in "${containers[@]}"; do buildah rm "$c" >/dev/null 2>&1; done
  if [ "$status" -ne 0 ] && [ -n "$work" ]; then
    for f in "$work"/server-*.log; do
      [ -f "$f" ] && { echo "--- $f (last 30 lines)" >&2; tail -n 30 "$f" >&2; }
    done
  fi
  if [ -n "$work" ] && [ "${SHAPEID_KEEP_WORK:-0}" != 1 ]; then
    unmount_under "$work"
    rm -rf --one-file-system "$work"
  fi
  [ -n "$work" ] && [ "${SHAPEID_KEEP_WORK:-0}" = 1 ] && echo "work directory kept: $work"
  end_step
  if [ ${#timings[@]} -gt 0 ]; then
    echo
    echo "Timings:"
    printf '%s\n' "${timings[@]}"
    printf '%7.1f s  total\n' "$(elapsed "$script_start")"
  fi
  # Not "N passed, N failed": CI would read that as the closing line of the whole run.
  if [ "$status" -eq 0 ]; then
    echo "test_container: all $passed checks passed"
  else
    echo "test_container: FAILED after $passed checks passed" >&2
  fi
  exit "$status"
}
trap cleanup EXIT
trap 'exit 130' INT TERM
# A command that fails outside a check still says where.
trap 'printf "FAIL: line %s: %s\n" "$LINENO" "$BASH_COMMAND" >&2' ERR

# Unmounts whatever a failed debootstrap may have left mounted (/proc, /dev...) under $1, so
# that removing $1 cannot reach into the host's.
unmount_under() {
  awk -v root="$1/" 'index($2, root) == 1 { print $2 }' /proc/mounts | sort -r |
    while read -r m; do umount -l "$m" || true; done
}

# Waits up to $2 seconds for process $1 to end; false if it is still running.
wait_gone() {
  local i
  for ((i = 0; i < $2 * 10; i++)); do
    kill -0 "$1" 2>/dev/null || return 0
    sleep 0.1
  done
  return 1
}

# The shapeid-server process: the background job itself or its descendant (buildah's chroot
# isolation forks a helper that runs the command).
server_pid() {
  local queue=("$server_runner") pid child
  if [ "$(cat "/proc/$server_runner/comm" 2>/dev/null)" = shapeid-server ]; then
    echo "$server_runner"
    return 0
  fi
  while [ ${#queue[@]} -gt 0 ]; do
    pid=${queue[0]}
    queue=("${queue[@]:1}")
    for child in $(ps -o pid= --ppid "$pid" 2>/dev/null); do
      if [ "$(cat "/proc/$child/comm" 2>/dev/null)" = shapeid-server ]; then
        echo "$child"
        return 0
      fi
      queue+=("$child")
    done
  done
}

# --- 0. prerequisites --------------------------------------------------------------------------
[ "$(id -u)" -eq 0 ] || fail "run as root (buildah and debootstrap need it)"
[ -x "$cli" ] || fail "host CLI not found at $cli (build it first, or pass its path / SHAPEID_CLI)"

work=$(mktemp -d /var/tmp/shapeid-container-test.XXXXXX)

step "Installing buildah, podman, debootstrap, python3-yaml (only those missing)"
missing=()
for p in buildah podman debootstrap python3-yaml; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "installing ${missing[*]}"
  { timeout 600 apt-get update -q &&
    DEBIAN_FRONTEND=noninteractive timeout 900 apt-get install -y -q --no-install-recommends \
      "${missing[@]}"; } >"$work/apt.log" 2>&1 ||
    { tail -n 20 "$work/apt.log" >&2; fail "apt-get install ${missing[*]}"; }
fi
pass "tools present ($(buildah --version | cut -d' ' -f1-3))"

# --- 1. manifests ------------------------------------------------------------------------------
step "Checking compose and Kubernetes manifests offline"
/usr/bin/python3 deploy/check_manifests.py || fail "deploy/check_manifests.py"
pass "manifests"
# kubectl cannot dry-run without an API server, but it builds the kustomization offline.
if command -v kubectl >/dev/null; then
  for dir in deploy/k8s deploy/k8s/scaled deploy/k8s/scaled/dev-postgres deploy/grafana; do
    timeout 60 kubectl kustomize "$dir" >"$work/kustomized.yaml" || fail "kubectl kustomize $dir"
    pass "kubectl kustomize $dir ($(grep -c '^kind:' "$work/kustomized.yaml") objects)"
  done
else
  echo "SKIP: kubectl kustomize (no kubectl on this machine)"
fi

# --- 2. base images ----------------------------------------------------------------------------
step "Base images $base:bookworm and :bookworm-slim (debootstrap, offline from registries)"
if podman image exists "$base:bookworm" && podman image exists "$base:bookworm-slim"; then
  pass "base images already present: reused"
else
  rootfs=$work/rootfs
  # minbase: essential packages and apt, as the official images.
  timeout 1200 debootstrap --variant=minbase bookworm "$rootfs" "$mirror" \
    >"$work/debootstrap.log" 2>&1 ||
    { tail -n 30 "$work/debootstrap.log" >&2; fail "debootstrap (log above)"; }
  unmount_under "$rootfs"
  # As the official image: updates and security suites, no package lists or .debs left.
  cat >"$rootfs/etc/apt/sources.list" <<EOF
deb $mirror bookworm main
deb $mirror bookworm-updates main
deb http://deb.debian.org/debian-security bookworm-security main
EOF
  rm -rf "${rootfs:?}"/var/cache/apt/archives/*.deb "${rootfs:?}"/var/cache/apt/*.bin \
    "${rootfs:?}"/var/lib/apt/lists/* "${rootfs:?}"/dev/* "${rootfs:?}"/var/log/*.log \
    "${rootfs:?}"/var/log/apt/* "${rootfs:?}"/tmp/*
  import() {  # import ROOTFS TAG
    tar --numeric-owner -C "$1" -c . |
      podman import --change 'CMD ["bash"]' \
        --change 'ENV PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin' \
        --quiet - "$2" >/dev/null
  }
  import "$rootfs" "$base:bookworm"
  # The slim variant, as the official one: no documentation, manual pages or translations,
  # and dpkg told to keep it so for every package installed later.
  cat >"$rootfs/etc/dpkg/dpkg.cfg.d/docker" <<'EOF'
# The "slim" variant: files normally unnecessary in containers are excluded.
path-exclude /usr/share/doc/*
path-include /usr/share/doc/*/copyright
path-exclude /usr/share/groff/*
path-exclude /usr/share/info/*
path-exclude /usr/share/linda/*
path-exclude /usr/share/lintian/*
path-exclude /usr/share/locale/*
path-include /usr/share/locale/locale.alias
path-exclude /usr/share/man/*
EOF
  find "$rootfs/usr/share/doc" -mindepth 1 ! -type d ! -name copyright -delete
  find "$rootfs/usr/share/locale" -mindepth 1 -maxdepth 1 ! -name locale.alias -exec rm -rf {} +
  rm -rf "${rootfs:?}"/usr/share/{groff,info,linda,lintian,man}/*
  import "$rootfs" "$base:bookworm-slim"
  rm -rf --one-file-system "$rootfs"
  pass "base images made with debootstrap and imported"
fi
for tag in bookworm bookworm-slim; do
  printf '  %s:%s  %s MB\n' "$base" "$tag" \
    $(($(podman image inspect --format '{{.Size}}' "$base:$tag") / 1000000))
done

# --- 3. build ----------------------------------------------------------------------------------
step "Building $image from deploy/Dockerfile (buildah bud --layers)"
old_id=$(podman image inspect --format '{{.Id}}' "$image" 2>/dev/null || true)
build_args=()
[ -n "${SHAPEID_BUILD_JOBS:-}" ] && build_args+=(--build-arg "BUILD_JOBS=$SHAPEID_BUILD_JOBS")
# buildah re-executes itself from a sealed in-memory copy for each RUN step; on a busy host the
# kernel can refuse the seal (EBUSY, "sealing memfd copy"), a transient fault of the host, not of
# the Dockerfile. Such a build is retried (its finished layers come from the cache); anything else
# fails at once.
for attempt in 1 2 3; do
  if timeout 1800 buildah bud --isolation chroot --network host --layers --force-rm --pull=never \
    --format docker "${build_args[@]}" -f deploy/Dockerfile -t "$image" . >"$work/build.log" 2>&1; then
    break
  fi
  if [ "$attempt" -lt 3 ] && grep -q 'sealing memfd copy' "$work/build.log"; then
    echo "  buildah could not seal its re-exec copy (EBUSY, a busy host); retrying ($attempt of 2)"
    sleep 5
    continue
  fi
  tail -n 40 "$work/build.log" >&2
  fail "buildah bud (last lines above)"
done
cached=$(grep -c -- '--> Using cache' "$work/build.log" || true)
steps=$(grep -cE 'STEP [0-9]+/[0-9]+: ' "$work/build.log" || true)
pass "image built ($cached of $steps steps from the layer cache)"
grep -iE '^\s*(hits|misses|cache hit|cache miss)' "$work/build.log" | sed 's/^/  ccache: /' || true
new_id=$(podman image inspect --format '{{.Id}}' "$image")
# The previous test image, now untagged, is not kept (a layer still in use stays).
if [ -n "$old_id" ] && [ "$old_id" != "$new_id" ]; then
  buildah rmi "$old_id" >/dev/null 2>&1 || true
fi

# --- image configuration -----------------------------------------------------------------------
step "Checking the image configuration"
# buildah's --format templates have no `json`: read the whole configuration once.
buildah inspect --type image "$image" >"$work/image.json"
config() {  # config PYTHON-EXPRESSION over c, the image's Docker configuration
  /usr/bin/python3 -c 'import json, sys
c = json.load(open(sys.argv[1]))["Docker"]["config"]
print(eval(sys.argv[2]))' "$work/image.json" "$1"
}
user=$(config 'c.get("User") or ""')
uid=${user%%:*}
case "$uid" in
  '' | 0 | root) fail "the image runs as root (User='$user')" ;;
  *[!0-9]*) fail "User '$user' is not numeric: Kubernetes runAsNonRoot cannot verify a name" ;;
esac
pass "image User is $user (non-root, numeric)"
entrypoint=$(config 'c.get("Entrypoint")')
[ "$entrypoint" = "['/usr/local/bin/shapeid-server']" ] || fail "Entrypoint is $entrypoint"
[ "$(config '"/var/lib/shapeid" in (c.get("Volumes") or {})')" = True ] ||
  fail "no VOLUME /var/lib/shapeid"
[ "$(config '"50051/tcp" in (c.get("ExposedPorts") or {})')" = True ] ||
  fail "port 50051 not exposed"
for e in SHAPEID_LISTEN=0.0.0.0:50051 SHAPEID_DATA_DIR=/var/lib/shapeid; do
  [ "$(config "\"$e\" in c.get('Env', [])")" = True ] || fail "image environment lacks $e"
done
# The HEALTHCHECK as a shell command, to run it for real below.
health_cmd=$(config '(lambda t: t[1] if t[0] == "CMD-SHELL" else " ".join(t[1:]))(
  (c.get("Healthcheck") or {}).get("Test") or ["NONE"])')
[[ $health_cmd == *shapeid*health* ]] ||
  fail "no HEALTHCHECK running 'shapeid health' (got '$health_cmd'; buildah needs --format docker)"
pass "entrypoint, volume, port 50051, SHAPEID_* environment, HEALTHCHECK"

size=$(podman image inspect --format '{{.Size}}' "$image")
size_mb=$(awk -v s="$size" 'BEGIN { printf "%.1f", s / 1e6 }')
echo "  runtime image size: $size_mb MB ($size bytes; limit $max_mb MB)"
awk -v s="$size" -v m="$max_mb" 'BEGIN { exit !(s <= m * 1e6) }' ||
  fail "image is $size_mb MB, over the $max_mb MB limit"
pass "image size $size_mb MB <= $max_mb MB"

# --- 4. run, train, classify -------------------------------------------------------------------
volume=$work/volume
mkdir -p "$volume"
# A fresh named volume starts as the image's /var/lib/shapeid (owned by the image user); a host
# directory must be given to that user by hand, as the README says.
chown "$user" "$volume"
ctr=$(timeout 120 buildah from --pull=never --name "shapeid-test-$$" "$image")
containers+=("$ctr")

# Every run listens on a free loopback port: port 0, and the server prints the one it got.
# launch_buildah: the image's entrypoint under `buildah run`, which runs it as the image's USER
# (as docker run does), with the host directory as the volume.
launch_buildah() {
  exec buildah run --isolation chroot --network host -v "$volume:/var/lib/shapeid" \
    --env SHAPEID_LISTEN=127.0.0.1:0 "$ctr" -- /usr/local/bin/shapeid-server
}

# start_server RUN LAUNCHER: starts the server in the background; waits until it serves.
start_server() {
  local log=$work/server-$1.log
  # Created here: the background job opens it later, and reading a missing file under
  # `set -e -o pipefail` would end the test (a busy CI host lost that race).
  : >"$log"
  "$2" >>"$log" 2>&1 &
  server_runner=$!
  local i
  address=
  for ((i = 0; i < 600; i++)); do  # 60 s: start-up is well under a second once running
    address=$(sed -n 's/^listening on //p' "$log" | head -1)
    [ -n "$address" ] && break
    kill -0 "$server_runner" 2>/dev/null ||
      { cat "$log" >&2; fail "server run $1 exited before listening"; }
    sleep 0.1
  done
  [ -n "$address" ] || { cat "$log" >&2; fail "server run $1 not listening after 60 s"; }
  for ((i = 0; i < 30; i++)); do
    "$cli" --server "$address" --timeout 2 --quiet health >/dev/null 2>&1 && break
    sleep 1
  done
  "$cli" --server "$address" --timeout 2 health || fail "server run $1 not SERVING after 30 s"
  local pid proc_uid
  pid=$(server_pid)
  [ -n "$pid" ] || fail "no shapeid-server process under job $server_runner"
  proc_uid=$(awk '/^Uid:/ { print $2 }' "/proc/$pid/status")
  [ "$proc_uid" = "$uid" ] || fail "the server process runs as uid $proc_uid, not the image's $uid"
  pass "server run $1 serving on $address as uid $proc_uid (pid $pid)"
}

# stop_server RUN: SIGTERM to the server process, as `docker stop` does; it must exit 0.
stop_server() {
  local pid
  pid=$(server_pid)
  [ -n "$pid" ] || fail "no shapeid-server process under job $server_runner"
  kill -TERM "$pid"
  wait_gone "$server_runner" 30 || fail "server run $1 still running 30 s after SIGTERM"
  local status=0
  wait "$server_runner" || status=$?
  server_runner=
  [ "$status" -eq 0 ] ||
    { cat "$work/server-$1.log" >&2; fail "server run $1 exited $status after SIGTERM"; }
  grep -q 'SIGTERM, shutting down' "$work/server-$1.log" ||
    fail "server run $1 did not log its SIGTERM shutdown"
  pass "server run $1 stopped by SIGTERM, exit 0"
}

# The host CLI against the running server.
run_cli() { "$cli" --server "$address" --timeout 60 --quiet "$@"; }

step "Starting the server from the image (buildah run, volume $volume)"
start_server 1 launch_buildah
in_uid=$(timeout 60 buildah run --isolation chroot "$ctr" -- id -u)
if [ "$in_uid" != "$uid" ] || [ "$in_uid" = 0 ]; then
  fail "id -u inside the container is $in_uid, want $uid"
fi
pass "id -u inside the container: $in_uid"

step "Training and classifying from the host CLI"
# Three meshes a sensor tells apart from any side (as tests/cli_e2e_test.cc), seen by
# `shapeid views` as depth scans: 8 training and 4 held-out views each.
mesh=$work/meshes
mkdir -p "$mesh"
box() {
  printf 'OFF\n8 6 0\n'
  local x=$1 y=$2 z=$3
  printf '%s %s %s\n' "-$x" "-$y" "-$z" "$x" "-$y" "-$z" "$x" "$y" "-$z" "-$x" "$y" "-$z" \
    "-$x" "-$y" "$z" "$x" "-$y" "$z" "$x" "$y" "$z" "-$x" "$y" "$z"
  printf '4 0 3 2 1\n4 4 5 6 7\n4 0 1 5 4\n4 2 3 7 6\n4 1 2 6 5\n4 0 4 7 3\n'
}
box 1 1 1 >"$mesh/cube.off"
box 3 0.4 0.4 >"$mesh/bar.off"
printf 'OFF\n5 5 0\n-1 -1 0\n1 -1 0\n1 1 0\n-1 1 0\n0 0 2\n%b\n' \
  '4 0 3 2 1\n3 0 1 4\n3 1 2 4\n3 2 3 4\n3 3 0 4' >"$mesh/pyramid.off"
"$cli" views --quiet --out "$work/views" --train-views 8 --test-views 4 --up z \
  "$mesh/cube.off" "$mesh/bar.off" "$mesh/pyramid.off" || fail "shapeid views"
run_cli gallery create shapes >/dev/null || fail "gallery create"
run_cli train --gallery shapes "$work/views" || fail "train"
# Answers without the per-file time column, to compare across restarts.
classify() {
  run_cli classify --gallery shapes --format csv "$work"/views/*/test | cut -d, -f1-5,7-
}
# The gallery's sample count and samples per label.
gallery_summary() {
  run_cli --format json gallery show shapes | /usr/bin/python3 -c 'import json, sys
g = json.load(sys.stdin)
print(g["sample_count"], sorted((c["label"], c["count"]) for c in g["label_counts"]))'
}
classify >"$work/classify-1.csv" || fail "classify"
# A view is right when its label is its folder's: VIEWS/LABEL/test/view-NNN.pcd.
correct=$(awk -F, 'NR > 1 { n = split($1, p, "/"); if (p[n - 2] == $2) right++ }
  END { print right + 0 }' "$work/classify-1.csv")
total=$(($(wc -l <"$work/classify-1.csv") - 1))
[ "$total" -eq 12 ] || fail "classified $total files, want 12"
[ "$correct" -eq 12 ] ||
  { cat "$work/classify-1.csv" >&2; fail "$correct of 12 held-out views right"; }
pass "trained 24 views; classified 12 held-out views, $correct right"
gallery_summary >"$work/gallery-1.txt" || fail "gallery show"
echo "  gallery: $(cat "$work/gallery-1.txt")"

step "Running the image's HEALTHCHECK command inside a container"
probe=$(timeout 120 buildah from --pull=never --name "shapeid-probe-$$" "$image")
containers+=("$probe")
# Network is the host's (chroot isolation): the check reaches the server at 127.0.0.1:PORT.
timeout 60 buildah run --isolation chroot --env "SHAPEID_LISTEN=0.0.0.0:${address##*:}" \
  "$probe" -- /bin/sh -c "$health_cmd" || fail "HEALTHCHECK command ($health_cmd) failed"
pass "HEALTHCHECK command exits 0 against the serving server"

step "Stopping the server (SIGTERM)"
stop_server 1

# --- 5. restart on the same volume -------------------------------------------------------------
step "Restarting on the same volume"
start_server 2 launch_buildah
gallery_summary >"$work/gallery-2.txt" || fail "gallery show after restart"
cmp -s "$work/gallery-1.txt" "$work/gallery-2.txt" ||
  fail "gallery changed across restart:" \
    "$(cat "$work/gallery-1.txt") -> $(cat "$work/gallery-2.txt")"
pass "gallery 'shapes' still there: $(cat "$work/gallery-2.txt")"
classify >"$work/classify-2.csv" || fail "classify after restart"
diff "$work/classify-1.csv" "$work/classify-2.csv" >&2 ||
  fail "classification changed across restart"
pass "classification identical after restart"
stop_server 2

# --- 6. read-only root ---------------------------------------------------------------------------
step "Restarting with a read-only root file system and a tmpfs /tmp (as compose and k8s run it)"
# buildah run cannot make the root read-only, so this run chroots, as the image's user, into a
# read-only bind mount of the container's file system, with the volume, a tmpfs /tmp, /proc
# and /dev mounted as a runtime would, and the image's environment.
ro=$work/read-only-root
mkdir -p "$ro"
mount --bind "$(buildah mount "$ctr")" "$ro"
mount --make-rprivate "$ro"  # nothing mounted or unmounted below reaches the host's mounts
mount -o remount,bind,ro "$ro"
mount --bind "$volume" "$ro/var/lib/shapeid"
mount -t tmpfs -o mode=1777,size=64m tmpfs "$ro/tmp"
mount -t proc proc "$ro/proc"
mount -t tmpfs -o mode=755,size=64k tmpfs "$ro/dev"
for node in null zero random urandom; do
  touch "$ro/dev/$node"
  mount --bind "/dev/$node" "$ro/dev/$node"
done
! touch "$ro/usr/local/bin/written" 2>/dev/null || fail "the root file system is writable"
mapfile -t image_env < <(config '"\n".join(c.get("Env", []))')
launch_read_only() {
  exec chroot --userspec="$user" "$ro" /usr/bin/env -i "${image_env[@]}" \
    SHAPEID_LISTEN=127.0.0.1:0 /usr/local/bin/shapeid-server
}
start_server 3 launch_read_only
cmp -s "$work/gallery-1.txt" <(gallery_summary) || fail "gallery changed (read-only root)"
# Writes go to the volume only; SQLite's temporary files, if any, to /tmp.
run_cli gallery create written >/dev/null || fail "gallery create (read-only root)"
run_cli train --gallery written --label cube "$work/views/cube/train" >/dev/null ||
  fail "train (read-only root)"
pass "gallery 'shapes' served and gallery 'written' trained with a read-only root"
stop_server 3
unmount_under "$work"

bad_owner=$(find "$volume" ! -uid "$uid" -printf '%u %p\n' | head -5)
[ -z "$bad_owner" ] || fail "data files not owned by uid $uid: $bad_owner"
pass "every file in the volume belongs to uid $uid ($(find "$volume" -type f | wc -l) files)"

end_step
