#!/usr/bin/python3
"""Issue 27's probe of noise: does smoothing the points before describing keep DFSD's accuracy?

Writes ModelNet10's official split (or DALES Objects' five folds, --dataset dales-objects) as
folders `shapeid eval --local` reads, one per smoothing and noise level: the training clouds
clean, the test clouds with Gaussian noise of sigma = LEVEL x the cloud's bounding-box
diagonal on every coordinate (numpy, seeded per file; shares no code with core/views'
perturbations), both sides smoothed alike in numpy: each point replaced by the mean of its K
nearest points (itself included). Then runs the CLI on each and prints a table.

  bench/noise_probe.py --out build/noise-probe            # smoothing none, knn16, knn32
  bench/noise_probe.py --smooth 8 16 --levels 0 0.02 --spec "dfsd:frame=axes"
  bench/noise_probe.py --smooth 1 --spec "dfsd:smooth=0.015"    # shapeid's own smoothing
  bench/noise_probe.py --dataset dales-objects --spec "dfsd:frame=upright,size=0.15"
  bench/noise_probe.py --dataset dales-objects --fold 0 --smooth 1 --levels 0.02 \
      --spec "dfsd:smooth=0.015" --min-accuracy 85        # CI's slice (bench/CMakeLists.txt)

A probe to decide what to build in C++ (a smoothing pass before describing), not a product
path. Data: ../shared/data (SHAPEID_DATA overrides). Run by /usr/bin/python3.
"""

import argparse
import hashlib
import json
import os
import subprocess

import numpy as np
import open3d as o3d

from independent_views import dales_split, modelnet_split, read_cloud


def knn_mean(points, k):
    """Each point replaced by the mean of its k nearest points (brute force, 256 rows at a time:
    DALES buildings have 28,000 points)."""
    if k <= 1:
        return points
    out = np.empty_like(points)
    for first in range(0, len(points), 256):
        rows = points[first:first + 256]
        squared = ((rows[:, None, :] - points[None, :, :]) ** 2).sum(-1)
        nearest = np.argpartition(squared, k - 1, axis=1)[:, :k]
        out[first:first + 256] = points[nearest].mean(1)
    return out


def write(path, points):
    os.makedirs(os.path.dirname(path), exist_ok=True)
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    o3d.io.write_point_cloud(path, cloud, write_ascii=False)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    data = os.environ.get("SHAPEID_DATA", os.path.join(root, "..", "shared", "data"))
    parser.add_argument("--out", default=os.path.join(root, "build", "noise-probe"))
    parser.add_argument("--smooth", type=int, nargs="+", default=[1, 16, 32],
                        help="K nearest points averaged (1: no smoothing)")
    parser.add_argument("--levels", type=float, nargs="+", default=[0, 0.01, 0.02, 0.03])
    parser.add_argument("--dataset", choices=["modelnet10", "dales-objects"], default="modelnet10")
    parser.add_argument("--spec", default="dfsd",
                        help="the spec, and any eval flags after it (quoted as one argument)")
    parser.add_argument("--shapeid", default=os.environ.get(
        "SHAPEID_CLI", os.path.join(root, "build/release/client/cli/shapeid")))
    parser.add_argument("--fold", type=int, choices=range(5), help="DALES: this fold only")
    parser.add_argument("--min-accuracy", type=float,
                        help="exit 1 when any figure (in %%) is below this floor (CI's slice)")
    args = parser.parse_args()
    args.out = os.path.abspath(args.out)  # the eval folders link into it

    root_of = {"modelnet10": os.path.join(data, "modelnet10"),
               "dales-objects": os.path.join(data, "dales-objects")}
    if not os.path.isdir(root_of[args.dataset]):
        print(f"noise_probe: skipped: no {args.dataset} under {data}")
        raise SystemExit(77)  # ctest's skip code
    # ModelNet10: the official split; DALES: the five folds of bench/independent_views.py.
    if args.dataset == "modelnet10":
        if args.fold is not None:
            parser.error("--fold is for DALES (ModelNet10 has its official split)")
        folds = [None]
    else:
        folds = list(range(5)) if args.fold is None else [args.fold]
    levels_key = "-".join(f"{level:g}" for level in args.levels)
    for fold in folds:
        base = os.path.join(args.out, args.dataset, "official" if fold is None else f"fold{fold}")
        items = (modelnet_split(root_of[args.dataset]) if fold is None else
                 dales_split(root_of[args.dataset], fold, 5, 1))
        items = list(items)
        for k in args.smooth:
            # One marker per smoothing and level set: a run with more levels writes them.
            done = os.path.join(base, f"knn{k}-{levels_key}.done")
            if os.path.exists(done):
                continue
            for label, split, path in items:
                name = os.path.splitext(os.path.basename(path))[0] + ".pcd"
                points = read_cloud(path)
                if split == "train":
                    write(os.path.join(base, f"knn{k}", "train", label, name), knn_mean(points, k))
                    continue
                diagonal = np.linalg.norm(points.max(0) - points.min(0))
                seed = int.from_bytes(hashlib.sha256(f"{label}/{name}".encode()).digest()[:8],
                                      "little")
                unit_noise = np.random.default_rng(seed).normal(0.0, 1.0, points.shape)
                for level in args.levels:
                    noisy = points + level * diagonal * unit_noise
                    write(os.path.join(base, f"knn{k}", f"test{level:g}", label, name),
                          knn_mean(noisy, k))
            open(done, "w").close()

    lowest = 100.0
    print(f"| smoothing | {' | '.join(f'noise {100 * l:g} %' for l in args.levels)} |")
    print("|---|" + "---|" * len(args.levels))
    for k in args.smooth:
        cells = []
        for level in args.levels:
            correct = tests = 0
            for fold in folds:
                base = os.path.join(args.out, args.dataset,
                                    "official" if fold is None else f"fold{fold}")
                # eval --local reads <label>/train and <label>/test: link them per level.
                folder = os.path.join(base, f"eval-knn{k}-{level:g}")
                for label in sorted(os.listdir(os.path.join(base, f"knn{k}", "train"))):
                    os.makedirs(os.path.join(folder, label), exist_ok=True)
                    for split, source in (("train", "train"), ("test", f"test{level:g}")):
                        link = os.path.join(folder, label, split)
                        target = os.path.join(base, f"knn{k}", source, label)
                        if os.path.islink(link) and os.readlink(link) != target:
                            os.remove(link)
                        if not os.path.islink(link):
                            os.symlink(target, link)
                run = subprocess.run(
                    [args.shapeid, "eval", "--local", "--quiet", "--format", "json", "--jobs", "2",
                     "--spec", *args.spec.split(), folder], capture_output=True, text=True)
                if run.returncode != 0:
                    raise SystemExit(f"noise_probe: shapeid eval failed on {folder}:\n{run.stderr}")
                result = json.loads(run.stdout)
                correct += result["correct"]
                tests += result["tests"]
            if tests == 0:
                raise SystemExit(f"noise_probe: no test clouds for noise {level:g}")
            cells.append(f"{100 * correct / tests:.1f} %")
            lowest = min(lowest, 100 * correct / tests)
        print(f"| {'none' if k <= 1 else f'{k} nearest'} | {' | '.join(cells)} |", flush=True)
    if args.min_accuracy is not None and lowest < args.min_accuracy:
        raise SystemExit(f"noise_probe: {lowest:.1f} % with `{args.spec}` is below the floor of "
                         f"{args.min_accuracy:g} %")


if __name__ == "__main__":
    main()
