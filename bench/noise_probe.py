#!/usr/bin/python3
"""Issue 27's probe of noise: does smoothing the points before describing keep DFSD's accuracy?

Writes ModelNet10's official split as folders `shapeid eval --local` reads, one per smoothing
and noise level: the training clouds clean, the test clouds with Gaussian noise of sigma =
LEVEL x the cloud's bounding-box diagonal on every coordinate (numpy, seeded per file; shares
no code with core/views' perturbations), both sides smoothed alike: each point replaced by the
mean of its K nearest points (itself included). Then runs the CLI on each and prints a table.

  bench/noise_probe.py --out build/noise-probe            # smoothing none, knn16, knn32
  bench/noise_probe.py --smooth 8 16 --levels 0 0.02 --spec "dfsd:frame=axes"

A probe to decide what to build in C++ (a smoothing pass before describing), not a product
path. Data: ../shared/data/modelnet10 (SHAPEID_DATA overrides). Run by /usr/bin/python3.
"""

import argparse
import glob
import hashlib
import json
import os
import subprocess

import numpy as np
import open3d as o3d

from independent_views import read_cloud


def knn_mean(points, k):
    """Each point replaced by the mean of its k nearest points (brute force: 1,024-point clouds)."""
    if k <= 1:
        return points
    squared = ((points[:, None, :] - points[None, :, :]) ** 2).sum(-1)
    nearest = np.argpartition(squared, k - 1, axis=1)[:, :k]
    return points[nearest].mean(1)


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
    parser.add_argument("--spec", default="dfsd")
    parser.add_argument("--shapeid", default=os.path.join(root, "build/release/client/cli/shapeid"))
    args = parser.parse_args()
    args.out = os.path.abspath(args.out)  # the eval folders link into it

    files = sorted(glob.glob(os.path.join(data, "modelnet10", "*", "*", "*.pcd")))
    if not files:
        raise SystemExit(f"noise_probe: no ModelNet10 clouds under {data}")
    for k in args.smooth:
        # One marker per smoothing and level set: a run with more levels writes them.
        levels_key = "-".join(f"{level:g}" for level in args.levels)
        done = os.path.join(args.out, f"knn{k}-{levels_key}.done")
        if os.path.exists(done):
            continue
        for path in files:
            label, split, name = path.split(os.sep)[-3:]
            points = read_cloud(path)
            if split == "train":
                write(os.path.join(args.out, f"knn{k}", "train", label, name), knn_mean(points, k))
                continue
            diagonal = np.linalg.norm(points.max(0) - points.min(0))
            seed = int.from_bytes(hashlib.sha256(f"{label}/{name}".encode()).digest()[:8], "little")
            unit_noise = np.random.default_rng(seed).normal(0.0, 1.0, points.shape)
            for level in args.levels:
                noisy = points + level * diagonal * unit_noise
                write(os.path.join(args.out, f"knn{k}", f"test{level:g}", label, name),
                      knn_mean(noisy, k))
        open(done, "w").close()

    print(f"| smoothing | {' | '.join(f'noise {100 * l:g} %' for l in args.levels)} |")
    print("|---|" + "---|" * len(args.levels))
    for k in args.smooth:
        cells = []
        for level in args.levels:
            # eval --local reads <label>/train and <label>/test: link them per level.
            folder = os.path.join(args.out, f"eval-knn{k}-{level:g}")
            for label in sorted(os.listdir(os.path.join(args.out, f"knn{k}", "train"))):
                os.makedirs(os.path.join(folder, label), exist_ok=True)
                for split, source in (("train", "train"), ("test", f"test{level:g}")):
                    link = os.path.join(folder, label, split)
                    if not os.path.islink(link):
                        os.symlink(os.path.join(args.out, f"knn{k}", source, label), link)
            result = json.loads(subprocess.run(
                [args.shapeid, "eval", "--local", "--quiet", "--format", "json", "--jobs", "2",
                 "--spec", *args.spec.split(), folder],
                check=True, capture_output=True, text=True).stdout)
            cells.append(f"{100 * result['correct'] / result['tests']:.1f} %")
        print(f"| {'none' if k <= 1 else f'{k} nearest'} | {' | '.join(cells)} |", flush=True)


if __name__ == "__main__":
    main()
