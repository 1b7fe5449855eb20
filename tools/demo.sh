#!/usr/bin/env bash
# The main job (README): on a fresh Debian 12 machine, installs the packages, builds, starts
# shapeid-server with its built-in store, creates a gallery, trains it on real labeled data,
# batch-classifies held-out data with the CLI, prints the accuracy table and timings, recognizes
# the objects of a composed tabletop frame (colored frame and picture), and stops the server.
#
# The data: real 3D models that Debian ships (the chess pieces of `brutalchess` and furniture
# of `minetest-mod-homedecor`, fetched with `apt-get download` and unpacked, never installed),
# turned by `shapeid views` into what a depth sensor sees of each object: single-view partial
# scans with depth noise. Training views and held-out test views come from different
# directions. Every step is seeded: the same machine gives the same numbers.
#
#   tools/demo.sh                 the object-recognition demo (about 2 minutes after the build)
#   tools/demo.sh --modelnet      also the ModelNet10 benchmark (official split, 4,899 clouds),
#                                 when ../shared/data/modelnet10 exists
#
# Work files go to build/demo/ (SHAPEID_DEMO_DIR overrides): meshes, views, server log,
# predictions.csv, report.html (the confusion matrix, to open in a browser), scene.png and
# scene.ply.
set -euo pipefail
cd "$(dirname "$0")/.."
repo=$(pwd)

modelnet=0
for arg in "$@"; do
  case "$arg" in
    --modelnet) modelnet=1 ;;
    -h|--help) sed -n '2,20p' "$0"; exit 0 ;;
    *) echo "demo: unknown argument $arg (see --help)" >&2; exit 2 ;;
  esac
done

step() { printf '\n==> %s\n' "$*"; }
now() { date +%s.%N; }
since() { awk -v a="$1" -v b="$(now)" 'BEGIN { printf "%.1f s", b - a }'; }

step "Installing packages and building (release preset)"
tools/install-deps.sh
cmake --preset release >/dev/null
cmake --build --preset release -j "$(nproc)"
bin=$repo/build/release
shapeid=$bin/client/cli/shapeid
server_bin=$bin/server/shapeid-server

demo=${SHAPEID_DEMO_DIR:-$repo/build/demo}
mkdir -p "$demo"

# --- Data: meshes from Debian packages -----------------------------------------------------
# label=path inside the unpacked packages. Six chess pieces (similar, rotationally symmetric
# shapes: the hard part) and eighteen pieces of furniture.
models=(
  chess-bishop=usr/share/games/brutalchess/models/bishop.obj
  chess-king=usr/share/games/brutalchess/models/king.obj
  chess-knight=usr/share/games/brutalchess/models/knight.obj
  chess-pawn=usr/share/games/brutalchess/models/pawn.obj
  chess-queen=usr/share/games/brutalchess/models/queen.obj
  chess-rook=usr/share/games/brutalchess/models/rook.obj
)
homedecor=usr/share/games/minetest/mods/homedecor
for name in armchair:lrfurn_armchair sofa:lrfurn_sofa_long bed:homedecor_bed_regular \
    kitchen-chair:homedecor_kitchen_chair office-chair:homedecor_office_chair_basic \
    round-table:homedecor_table_small_round square-table:homedecor_table_large_square \
    desk:homedecor_desk refrigerator:homedecor_refrigerator toilet:homedecor_toilet_closed \
    bathtub:homedecor_bathtub_clawfoot piano:homedecor_piano standing-lamp:homedecor_standing_lamp \
    table-lamp:homedecor_table_lamp grandfather-clock:homedecor_grandfather_clock \
    trash-can:homedecor_trash_can doghouse:homedecor_doghouse well:homedecor_well; do
  models+=("${name%%:*}=${name#*:}.obj")
done

meshes=$demo/meshes
if [ ! -f "$meshes/.complete" ]; then
  step "Fetching 3D models from Debian packages (apt-get download, unpacked, not installed)"
  rm -rf "$demo/debs" "$meshes"
  mkdir -p "$demo/debs/root" "$meshes"
  (
    cd "$demo/debs"
    # _apt cannot write here when run as root; apt then downloads as root and says so.
    apt-get download brutalchess minetest-mod-homedecor 2>/dev/null ||
      { apt-get update -q && apt-get download brutalchess minetest-mod-homedecor 2>/dev/null; }
    for deb in ./*.deb; do dpkg-deb -x "$deb" root; done
  )
  for entry in "${models[@]}"; do
    label=${entry%%=*}
    path=${entry#*=}
    if [[ $path != usr/* ]]; then  # a homedecor model: find its sub-folder
      path=$(cd "$demo/debs/root" && find "$homedecor" -name "$path" -print -quit)
    fi
    cp "$demo/debs/root/$path" "$meshes/$label.obj"
  done
  touch "$meshes/.complete"
fi
echo "$(ls "$meshes" | wc -l) models in $meshes"

step "Simulating depth-sensor scans: 12 training and 6 held-out views per model"
views=$demo/views
rm -rf "$views"
t=$(now)
"$shapeid" views --out "$views" --train-views 12 --test-views 6 --up y --noise 0.005 \
  --seed 1 "$meshes"/*.obj
echo "views made in $(since "$t")"

# --- The server ------------------------------------------------------------------------------
step "Starting shapeid-server (built-in store, loopback, a free port)"
log=$demo/server.log
# The built-in store: galleries persist in $demo/data (SQLite, one file per gallery). The demo
# starts from an empty store each run so that its figures are reproducible.
rm -rf "$demo/data"
"$server_bin" --listen=127.0.0.1:0 --data_dir="$demo/data" >"$log" 2>&1 &
server_pid=$!
trap 'kill "$server_pid" 2>/dev/null; wait "$server_pid" 2>/dev/null || true' EXIT
for _ in $(seq 100); do
  grep -q '^listening on ' "$log" && break
  kill -0 "$server_pid" 2>/dev/null || { cat "$log" >&2; exit 1; }
  sleep 0.1
done
address=$(sed -n 's/^listening on //p' "$log" | head -1)
[ -n "$address" ] || { echo "demo: the server did not start" >&2; cat "$log" >&2; exit 1; }
export SHAPEID_SERVER=$address
"$shapeid" health

# The views are rendered with the models' +y up (`shapeid views --up y`), as a robot that
# knows gravity would send them: the upright frame keeps that vertical and ignores yaw
# (95.83 % here; the default box frame, which assumes nothing about the pose, 88.19 %).
step "Creating gallery 'objects' (DFSD in the upright frame, +y up; 1-NN)"
"$shapeid" gallery delete objects --missing-ok >/dev/null
"$shapeid" gallery create objects --spec dfsd:frame=upright,up=y

step "Training: every training view, 4 parallel streams"
"$shapeid" train --gallery objects --jobs 4 "$views"

# Train is instant (kNN over the stored views); once the gallery has been quiet for 2 s the
# server fits it a trained head in the background (--learn=mlp, the default; docs/accuracy.md),
# which then answers Classify together with the kNN vote.
step "The gallery learns: the server fits its trained head in the background"
for _ in $(seq 600); do
  "$shapeid" gallery show objects --format json | grep -q '"head"' && break
  sleep 0.2
done
"$shapeid" gallery show objects | grep '^learned'
echo "what the head adds on these views, in this process with the server's own code:"
for learn in off mlp; do
  printf '  --learn %-4s ' "$learn"
  "$shapeid" eval --local --quiet --spec dfsd:frame=upright,up=y --learn "$learn" --jobs 4 \
    "$views" | sed -n 2p
done

step "Batch-classifying the held-out views (first lines; all in $demo/predictions.csv)"
"$shapeid" classify --gallery objects --jobs 4 --quiet "$views"/chess-knight/test "$views"/sofa/test |
  head -8
"$shapeid" classify --gallery objects --jobs 4 --format csv "$views"/*/test >"$demo/predictions.csv"

step "Accuracy on the held-out views"
"$shapeid" eval --gallery objects --test "$views" --jobs 4 --report "$demo/report.html"

# A robot's frame holds a table and several things on it. `shapeid views --scenes` composes one:
# five of the models (real sizes, any yaw, apart) on a table, seen by one simulated depth camera,
# with each point's truth beside it (docs/scenes.md). `shapeid scene` finds and names them.
step "A scene: five of the models on a table, one depth-camera frame, recognized in one call"
"$shapeid" views --out "$demo/scene" --train-views 0 --test-views 0 --scenes 1 --scene-objects 5 \
  --touching 0 --up y --seed 5 "$meshes"/*.obj >/dev/null
"$shapeid" scene --gallery objects --colored "$demo/scene.ply" --picture "$demo/scene.png" \
  "$demo/scene/scenes/0000.pcd"
echo "what was placed (the truth): $(tail -n +2 "$demo/scene/scenes/0000.objects.csv" |
  cut -d, -f2 | paste -sd' ')"

if [ "$modelnet" = 1 ]; then
  data=$repo/../shared/data/modelnet10
  if [ -d "$data" ]; then
    step "ModelNet10, official split (3,991 train / 908 test clouds), DFSD 1-NN"
    "$shapeid" gallery delete modelnet10 --missing-ok >/dev/null
    "$shapeid" gallery create modelnet10 >/dev/null
    "$shapeid" train --gallery modelnet10 --jobs 4 "$data"
    "$shapeid" eval --gallery modelnet10 --test "$data" --jobs 4 \
      --report "$demo/modelnet10-report.html"
  else
    echo "ModelNet10 not found at $data: skipped"
  fi
fi

step "What the server saw (shapeid stats; one log line per call in $log, docs/operations.md)"
"$shapeid" stats

step "Stopping the server"
kill -TERM "$server_pid"
wait "$server_pid" && echo "shapeid-server stopped cleanly"
trap - EXIT
echo "report: $demo/report.html"
echo "scene:  $demo/scene.png (and $demo/scene.ply, each object's points colored by its label)"
