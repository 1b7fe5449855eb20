#!/usr/bin/python3
"""Partial test views made by code that shares nothing with shapeid's own view simulator.

Issue 27's evaluation must not flatter the augmentation (core/views: SensorView, ScanSimulator),
so the test views here come from other algorithms, written in Python over numpy and Open3D:

  hpr      Katz et al.'s hidden point removal (Open3D's PointCloud.hidden_point_removal): the
           points of the cloud itself that a camera at the viewpoint sees.
  raycast  a surface rebuilt from the points (Open3D's ball pivoting) and a pinhole camera's
           rays cast on it (Moller-Trumbore in numpy; Debian's Open3D 0.16 RaycastingScene
           answers no hit for any ray): new points where the rays land, not the cloud's own.
  cut      the points on the camera's side of a plane through the centroid (a crude cut).
  occluded hpr's view with something in front: a disc-shaped occluder between the camera and
           the object hides 15-40 % of the visible points; 20-50 % as many points of the
           occluder's surface, close in front of what it hides (a segmentation that could not
           part them), are left in the view, and 1-3 % outliers uniform in the view's box.

Each view: the camera at an elevation drawn in [--min-elevation, --max-elevation] degrees
above the object's horizontal plane (its +z is up in both datasets), any azimuth, 3 bounding
radii away; Gaussian noise with sigma drawn in [--min-noise, --max-noise] of the cloud's bounding-box
diagonal; then at most N points, N drawn in [--min-points, --max-points] (a uniform random
subset); then, with --pose any, a uniformly random 3D rotation. Every draw comes from a
generator seeded by --seed and the file's index, so a rerun writes the same views.

Layout written (what `shapeid eval --local DIR` reads):
  OUT/<label>/train/  symlinks to the clean training clouds (a gallery trained whole)
  OUT/<label>/test/   one view per test cloud, PCD binary float32

  ModelNet10: the official split (<label>/{train,test}/*.pcd).
  DALES (<label>/*.xyz, no split): --fold K of 5 (stratified, seeded by --split-seed), so
  five runs make the 5-fold figure.

Usage:
  bench/independent_views.py --data ../shared/data/modelnet10 --model hpr --out build/views/hpr
  bench/independent_views.py --data ../shared/data/dales-objects --fold 0 --model raycast ...
Run by Debian's /usr/bin/python3 (python3-numpy, python3-open3d; tools/install-deps.sh).
"""

import argparse
import os
import random
import struct
import sys

import numpy as np

try:
    import open3d as o3d
except ImportError:  # pragma: no cover - a clear message instead of a traceback
    sys.exit("independent_views: needs python3-open3d (tools/install-deps.sh) and /usr/bin/python3")


# ----------------------------------------------------------------------------------------------
# Reading and writing clouds


def read_cloud(path):
    if path.endswith(".xyz"):
        return np.loadtxt(path, dtype=np.float64, usecols=(0, 1, 2)).reshape(-1, 3)
    cloud = o3d.io.read_point_cloud(path)
    points = np.asarray(cloud.points, dtype=np.float64)
    if len(points) == 0:
        raise ValueError(f"{path}: no points read")
    return points


def write_pcd(path, points):
    points = np.ascontiguousarray(points, dtype="<f4")
    header = (
        "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n"
        f"WIDTH {len(points)}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {len(points)}\nDATA binary\n"
    )
    with open(path, "wb") as f:
        f.write(header.encode("ascii"))
        f.write(points.tobytes())


# ----------------------------------------------------------------------------------------------
# Visibility models


def camera_position(points, elevation_deg, azimuth_deg):
    center = 0.5 * (points.min(0) + points.max(0))
    radius = np.linalg.norm(points - center, axis=1).max()
    e, a = np.radians(elevation_deg), np.radians(azimuth_deg)
    direction = np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])
    return center, radius, center + 3.0 * radius * direction


def camera_axes(center, eye):
    """The camera's forward (towards the center), right and up unit vectors; +z is world up."""
    forward = (center - eye) / np.linalg.norm(center - eye)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    return forward, right, np.cross(right, forward)


def view_hpr(points, elevation, azimuth, rng):
    del rng
    _, _, eye = camera_position(points, elevation, azimuth)
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    diameter = np.linalg.norm(points.max(0) - points.min(0))
    _, visible = cloud.hidden_point_removal(eye, diameter * 100)
    return points[np.asarray(visible, dtype=np.int64)]


def rebuilt_surface(points):
    """Triangles (T x 3 x 3) of a ball-pivoting surface over the points."""
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    cloud.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(12))
    spacing = float(np.mean(np.asarray(cloud.compute_nearest_neighbor_distance())))
    radii = o3d.utility.DoubleVector([1.5 * spacing, 3 * spacing, 6 * spacing])
    mesh = o3d.geometry.TriangleMesh.create_from_point_cloud_ball_pivoting(cloud, radii)
    vertices = np.asarray(mesh.vertices)
    return vertices[np.asarray(mesh.triangles)]


def first_hits(origin, directions, triangles):
    """Moller-Trumbore: the distance along each ray to the nearest triangle, inf for none."""
    v0, e1, e2 = triangles[:, 0], triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0]
    best = np.full(len(directions), np.inf)
    t_vec = origin - v0  # (T, 3): the same origin for every ray
    rays = max(1, 4_000_000 // len(triangles))  # bounds the (R, T, 3) arrays at ~100 MB
    for start in range(0, len(directions), rays):
        d = directions[start:start + rays]  # (R, 3)
        p = np.cross(d[:, None, :], e2[None, :, :])  # (R, T, 3)
        det = np.einsum("rtk,tk->rt", p, e1)
        ok = np.abs(det) > 1e-12
        inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        u = np.einsum("rtk,tk->rt", p, t_vec) * inv
        q = np.cross(t_vec, e1)  # (T, 3)
        v = np.einsum("rk,tk->rt", d, q) * inv
        t = np.einsum("tk,tk->t", q, e2)[None, :] * inv
        hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 1e-9)
        t = np.where(hit, t, np.inf)
        best[start:start + rays] = t.min(axis=1)
    return best


def view_raycast(points, elevation, azimuth, rng, pixels=72):
    center, radius, eye = camera_position(points, elevation, azimuth)
    triangles = rebuilt_surface(points)
    if len(triangles) == 0:
        return view_hpr(points, elevation, azimuth, rng)
    forward, right, up = camera_axes(center, eye)
    half = np.arctan(1.1 * radius / (3.0 * radius))  # the bounding sphere fills the image
    # Jittered pixel centers: a sensor's samples are not a lattice aligned with anything.
    grid = (np.arange(pixels) + 0.5) / pixels * 2 - 1
    u, v = np.meshgrid(grid, grid)
    u = (u + rng.uniform(-0.5, 0.5, u.shape) * 2 / pixels) * np.tan(half)
    v = (v + rng.uniform(-0.5, 0.5, v.shape) * 2 / pixels) * np.tan(half)
    directions = forward + u[..., None] * right + v[..., None] * up
    directions = (directions / np.linalg.norm(directions, axis=-1, keepdims=True)).reshape(-1, 3)
    t = first_hits(eye, directions, triangles)
    hit = np.isfinite(t)
    return eye + directions[hit] * t[hit, None]


def view_cut(points, elevation, azimuth, rng):
    del rng
    center, _, eye = camera_position(points, elevation, azimuth)
    toward = (eye - center) / np.linalg.norm(eye - center)
    return points[(points - points.mean(0)) @ toward >= 0]


def view_occluded(points, elevation, azimuth, rng):
    view = view_hpr(points, elevation, azimuth, rng)
    center, radius, eye = camera_position(points, elevation, azimuth)
    forward, right, up = camera_axes(center, eye)
    relative = view - eye
    depth = relative @ forward
    image = np.stack([relative @ right, relative @ up], axis=1) / depth[:, None]
    # The occluder's center: a random visible point's image; its radius covers the wanted share.
    middle = image[rng.integers(len(image))]
    distance = np.linalg.norm(image - middle, axis=1)
    radius = np.quantile(distance, rng.uniform(0.15, 0.40))
    hidden = distance < radius
    kept = view[~hidden]
    # Points on the occluder: a flat disc 5-15 % of the object's radius in front of the
    # nearest point it hides.
    count = int(hidden.sum() * rng.uniform(0.2, 0.5))
    angle = rng.uniform(0, 2 * np.pi, count)
    r = radius * np.sqrt(rng.uniform(0, 1, count))
    u = middle[0] + r * np.cos(angle)
    v = middle[1] + r * np.sin(angle)
    d = depth[hidden].min() - rng.uniform(0.05, 0.15) * radius if hidden.any() else depth.min()
    occluder = eye + d * (forward + u[:, None] * right + v[:, None] * up)
    low, high = view.min(0), view.max(0)
    outliers = rng.uniform(low, high, size=(int(len(view) * rng.uniform(0.01, 0.03)), 3))
    return np.concatenate([kept, occluder, outliers])


MODELS = {"hpr": view_hpr, "raycast": view_raycast, "cut": view_cut, "occluded": view_occluded}


def random_rotation(rng):
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q *= np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return q


def make_view(points, args, rng):
    elevation = rng.uniform(args.min_elevation, args.max_elevation)
    azimuth = rng.uniform(0, 360)
    view = MODELS[args.model](points, elevation, azimuth, rng)
    if len(view) < 3:  # a degenerate cut: the whole cloud rather than nothing
        view = points
    diagonal = np.linalg.norm(points.max(0) - points.min(0))
    view = view + rng.normal(size=view.shape) * rng.uniform(args.min_noise, args.max_noise) * diagonal
    wanted = int(rng.integers(args.min_points, args.max_points + 1))
    if len(view) > wanted:
        view = view[rng.choice(len(view), wanted, replace=False)]
    if args.pose == "any":
        center = view.mean(0)
        view = (view - center) @ random_rotation(rng).T + center
    return view


# ----------------------------------------------------------------------------------------------
# Datasets


def modelnet_split(root):
    for label in sorted(os.listdir(root)):
        for part in ("train", "test"):
            folder = os.path.join(root, label, part)
            for name in sorted(os.listdir(folder)):
                yield label, part, os.path.join(folder, name)


def dales_split(root, fold, folds, seed):
    for label in sorted(os.listdir(root)):
        files = sorted(os.listdir(os.path.join(root, label)))
        order = list(range(len(files)))
        random.Random(f"{seed}/{label}").shuffle(order)
        for rank, index in enumerate(order):
            part = "test" if rank % folds == fold else "train"
            yield label, part, os.path.join(root, label, files[index])


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--data", required=True, help="ModelNet10 or DALES Objects folder")
    parser.add_argument("--out", required=True)
    parser.add_argument("--model", choices=sorted(MODELS), required=True)
    parser.add_argument("--fold", type=int, help="DALES: the test fold, 0-4")
    parser.add_argument("--split-seed", type=int, default=1)
    parser.add_argument("--seed", type=int, default=27)
    parser.add_argument("--min-elevation", type=float, default=0)
    parser.add_argument("--max-elevation", type=float, default=60)
    parser.add_argument("--min-noise", type=float, default=0.0)
    parser.add_argument("--max-noise", type=float, default=0.03)
    parser.add_argument("--min-points", type=int, default=150)
    parser.add_argument("--max-points", type=int, default=1000)
    parser.add_argument("--pose", choices=("any", "upright"), default="any")
    parser.add_argument("--limit", type=int, default=0, help="at most this many test views per label")
    args = parser.parse_args()

    dales = args.fold is not None
    items = dales_split(args.data, args.fold, 5, args.split_seed) if dales else modelnet_split(args.data)
    written = {}
    for index, (label, part, path) in enumerate(items):
        folder = os.path.join(args.out, label, part)
        os.makedirs(folder, exist_ok=True)
        name = os.path.splitext(os.path.basename(path))[0]
        if part == "train":
            link = os.path.join(folder, os.path.basename(path))
            if not os.path.lexists(link):
                os.symlink(os.path.abspath(path), link)
            continue
        if args.limit and written.get(label, 0) >= args.limit:
            continue
        rng = np.random.default_rng([args.seed, index])
        view = make_view(read_cloud(path), args, rng)
        write_pcd(os.path.join(folder, name + ".pcd"), view)
        written[label] = written.get(label, 0) + 1
    print(f"independent_views: {sum(written.values())} {args.model} views in {args.out}")


if __name__ == "__main__":
    main()
