#!/usr/bin/python3
"""Issue 27's probe of "verify before answering": does a geometric fit re-rank the shortlist?

Reads the JSON of `shapeid eval --local --format json --predictions --k 30 ...` (each test
view's neighbors with the training file each came from), aligns the test view to each
distinct training cloud among its first --shortlist neighbors (Open3D: FPFH features, RANSAC,
then point-to-point ICP), scores the fit one-sidedly (the trimmed mean distance from the view's
points to the cloud's nearest point: missing parts cost nothing) and prints how often each
rule of answering is right, beside the kNN answer (k = 5, distance-weighted) from the same
list. A probe in Python to decide whether the C++ work is worth doing, not a product path.

  build/release/client/cli/shapeid eval --local --quiet --format json --predictions --jobs 2 \\
      --spec dfsd:size=0.15 --augment-views 16 --k 30 --weighting distance \\
      build/independent-views/dales-objects-hpr-fold0-limit0 > build/probe/dales-hpr-0.json
  bench/verification_probe.py --stride 5 build/probe/dales-hpr-*.json
  bench/verification_probe.py --stride 9 --scale-to-candidate build/probe/modelnet10-hpr.json

--scale-to-candidate: ModelNet10's units are each model's own, so the view is first scaled to
0.85 of the candidate's diagonal and ICP fits a similarity. Open3D's RANSAC is not seeded, so
reruns differ by a point or two. Run by Debian's /usr/bin/python3 (python3-open3d).
"""

import argparse
import json

import numpy as np
import open3d as o3d

from independent_views import read_cloud

reg = o3d.pipelines.registration


def prepared(points, voxel):
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    cloud.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=voxel * 3, max_nn=30))
    features = reg.compute_fpfh_feature(
        cloud, o3d.geometry.KDTreeSearchParamHybrid(radius=voxel * 6, max_nn=100))
    return cloud, features


class Clouds:
    """Each file read once, subsampled to at most `n` points (seeded), with its features."""

    def __init__(self):
        self.cache = {}

    def get(self, path, n):
        if (path, n) not in self.cache:
            points = read_cloud(path)
            if len(points) > n:
                points = points[np.random.default_rng(0).choice(len(points), n, replace=False)]
            diagonal = float(np.linalg.norm(points.max(0) - points.min(0)))
            cloud, features = prepared(points, diagonal / 40)
            self.cache[(path, n)] = dict(points=points, cloud=cloud, features=features,
                                         diagonal=diagonal, tree=o3d.geometry.KDTreeFlann(cloud))
        return self.cache[(path, n)]


def fit(view, model, scale_to_candidate):
    """(trimmed one-sided distance, model diagonal, view diagonal) after alignment."""
    voxel = model["diagonal"] / 40
    scale = 0.85 * model["diagonal"] / view["diagonal"] if scale_to_candidate else 1.0
    if scale_to_candidate:
        cloud, features = prepared(view["points"] * scale, voxel)
    else:
        cloud, features = view["cloud"], view["features"]
    tolerance = 2 * voxel
    coarse = reg.registration_ransac_based_on_feature_matching(
        cloud, model["cloud"], features, model["features"], True, tolerance,
        reg.TransformationEstimationPointToPoint(False), 3,
        [reg.CorrespondenceCheckerBasedOnEdgeLength(0.9),
         reg.CorrespondenceCheckerBasedOnDistance(tolerance)],
        reg.RANSACConvergenceCriteria(20000, 0.999))
    fine = reg.registration_icp(cloud, model["cloud"], tolerance, coarse.transformation,
                                reg.TransformationEstimationPointToPoint(scale_to_candidate))
    moved = np.asarray(cloud.points) @ fine.transformation[:3, :3].T + fine.transformation[:3, 3]
    distances = np.sort([np.sqrt(model["tree"].search_knn_vector_3d(p, 1)[2][0]) for p in moved])
    return (float(distances[: int(0.8 * len(distances))].mean()), model["diagonal"],
            view["diagonal"] * scale, coverage(moved, model, tolerance))


def coverage(moved, model, tolerance):
    """Of the candidate's points that face the camera, the fraction the view covers.

    The camera is taken to lie beyond the view's centroid as seen from the candidate's (a
    view's points lean toward its camera); a point faces it when its outward normal (oriented
    away from the centroid) points there. No visibility algorithm of the test views is used.
    """
    points = model["points"]
    center = points.mean(0)
    towards = moved.mean(0) - center
    if np.linalg.norm(towards) < 1e-9:
        return 1.0
    towards /= np.linalg.norm(towards)
    normals = np.asarray(model["cloud"].normals)
    outward = np.where(((points - center) * normals).sum(1, keepdims=True) < 0, -normals, normals)
    facing = points[outward @ towards > 0.2]
    if len(facing) == 0:
        return 1.0
    view_tree = o3d.geometry.KDTreeFlann(o3d.geometry.PointCloud(o3d.utility.Vector3dVector(moved)))
    covered = sum(view_tree.search_knn_vector_3d(p, 1)[2][0] <= (2 * tolerance) ** 2
                  for p in facing)
    return covered / len(facing)


def knn_answer(neighbors, k=5):
    votes = {}
    for n in neighbors[:k]:
        votes[n["label"]] = votes.get(n["label"], 0.0) + 1.0 / max(n["distance"], 1e-9)
    return max(votes, key=votes.get)


# Rules of answering from the candidates (file, (fit, model diagonal, view diagonal), label,
# descriptor distance), in shortlist order.
RULES = {
    "kNN (k = 5, distance)": None,
    "best fit / model diagonal": lambda c: min(c, key=lambda x: x[1][0] / x[1][1])[2],
    "best fit (absolute)": lambda c: min(c, key=lambda x: x[1][0])[2],
    "fit x descriptor distance": lambda c: min(c, key=lambda x: x[1][0] * x[3])[2],
    "fit x descriptor distance, first 3": lambda c: min(c[:3], key=lambda x: x[1][0] * x[3])[2],
    "fit / diagonal / coverage": lambda c: min(c, key=lambda x: x[1][0] / x[1][1] / max(x[1][3], 0.05))[2],
    "fit / coverage (absolute)": lambda c: min(c, key=lambda x: x[1][0] / max(x[1][3], 0.05))[2],
    "best coverage": lambda c: max(c, key=lambda x: x[1][3])[2],
    "descriptor distance / coverage": lambda c: min(c, key=lambda x: x[3] / max(x[1][3], 0.05))[2],
    "fit x descriptor / coverage": lambda c: min(c, key=lambda x: x[1][0] * x[3] / max(x[1][3], 0.05))[2],
}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("predictions", nargs="+")
    parser.add_argument("--stride", type=int, default=1, help="every Nth test view")
    parser.add_argument("--shortlist", type=int, default=10, help="neighbors considered")
    parser.add_argument("--scale-to-candidate", action="store_true")
    args = parser.parse_args()
    clouds = Clouds()
    right = {name: 0 for name in RULES}
    views = 0
    for path in args.predictions:
        for i, p in enumerate(json.load(open(path))["predictions"]):
            if i % args.stride:
                continue
            views += 1
            view = clouds.get(p["file"], 512)
            candidates, seen = [], set()
            for n in p["neighbors"][: args.shortlist]:
                if n["file"] not in seen:
                    seen.add(n["file"])
                    model = clouds.get(n["file"], 2048)
                    candidates.append((n["file"], fit(view, model, args.scale_to_candidate),
                                       n["label"], n["distance"]))
            for name, rule in RULES.items():
                answer = knn_answer(p["neighbors"]) if rule is None else rule(candidates)
                right[name] += answer == p["truth"]
    for name, r in right.items():
        print(f"{name:38s} {100 * r / views:5.1f} % ({r} / {views})")


if __name__ == "__main__":
    main()
