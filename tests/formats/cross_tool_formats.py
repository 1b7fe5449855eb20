#!/usr/bin/python3
"""Every format shapeid reads, written by the tools its users have, gives the original's descriptor.

One real cloud (the first ModelNet10 chair test cloud under ../shared/data, or, without the data,
a torus made here, which the output says) is written by Open3D, numpy, PCL's command-line tools
(pcl_converter, pcl_pcd2vtk from Debian's pcl-tools) and, for LAS, which no Debian tool writes,
by a few lines of `struct` from the ASPRS specification. Each file is described by
`shapeid describe --local` and compared with the original binary PCD's descriptor: bit for bit
where the format holds float32 exactly, within the format's precision where it does not
(quantised LAS). A mesh is written as PLY, OFF, OBJ and STL by Open3D and must describe alike
in every mesh format (same triangles, same seeded sampling).

Usage: cross_tool_formats.py SHAPEID_CLI WORK_DIR. Exit 0 when every row matches, 1 otherwise
(each mismatch printed), 77 (ctest's skip) when Open3D or numpy is missing.
"""

import gzip
import json
import os
import shutil
import struct
import subprocess
import sys

try:
    import numpy as np
    import open3d as o3d
except ImportError as e:  # pragma: no cover - the set-up scripts install both
    print(f"SKIP: {e} (tools/install-deps.sh installs python3-open3d and python3-numpy)")
    sys.exit(77)

SPECS = ["rphsd", "dfsd"]
DATA = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "..", "shared", "data")


def real_cloud():
    """A real ModelNet10 cloud as float32 (N, 3), or a made torus when the data is absent."""
    path = os.path.join(DATA, "modelnet10", "chair", "test", "chair_0890.pcd")
    if os.path.exists(path):
        cloud = o3d.io.read_point_cloud(path)
        return np.asarray(cloud.points, dtype=np.float32), path
    print("note: ../shared/data is absent; using a torus made here instead of a real cloud")
    rng = np.random.default_rng(7)
    u, v = rng.uniform(0, 2 * np.pi, (2, 1500))
    xyz = np.stack([(3 + np.cos(v)) * np.cos(u), (3 + np.cos(v)) * np.sin(u), np.sin(v) * 0.7], 1)
    return xyz.astype(np.float32), "torus"


def describe(cli, path, extra=()):
    """{spec: values} for one file, or the CLI's error line."""
    out = {}
    for spec in SPECS:
        run = subprocess.run([cli, "describe", "--local", "--spec", spec, "--format", "json",
                              *extra, path], capture_output=True, text=True)
        if run.returncode != 0:
            return run.stderr.strip() or f"exit {run.returncode}"
        out[spec] = np.array(json.loads(run.stdout)["descriptor"], dtype=np.float64)
    return out


def write_las(path, xyz, scale=1e-5, version=(1, 2), point_format=0):
    """An uncompressed LAS file from the ASPRS specification (public header block + records)."""
    offset = xyz.astype(np.float64).min(axis=0)
    ints = np.round((xyz.astype(np.float64) - offset) / scale).astype(np.int32)
    record = {0: 20, 1: 28, 3: 34, 6: 30}[point_format]
    header_size = 375 if version >= (1, 4) else 227
    h = bytearray(header_size)
    h[0:4] = b"LASF"
    h[24], h[25] = version
    h[26:58] = b"shapeid cross-tool test".ljust(32, b"\0")
    h[58:90] = b"cross_tool_formats.py".ljust(32, b"\0")
    struct.pack_into("<HIIBHI", h, 94, header_size, header_size, 0, point_format, record,
                     0 if point_format >= 6 else len(xyz))
    struct.pack_into("<3d3d", h, 131, scale, scale, scale, *offset)
    hi, lo = xyz.max(axis=0).astype(np.float64), xyz.min(axis=0).astype(np.float64)
    struct.pack_into("<6d", h, 179, hi[0], lo[0], hi[1], lo[1], hi[2], lo[2])
    if header_size >= 375:
        struct.pack_into("<Q", h, 247, len(xyz))
    body = np.zeros((len(xyz), record), dtype=np.uint8)
    body[:, 0:12] = ints.view(np.uint8).reshape(len(xyz), 12)
    with open(path, "wb") as f:
        f.write(bytes(h))
        f.write(body.tobytes())


def main():
    if len(sys.argv) != 3:
        print(__doc__)
        return 2
    cli, work = sys.argv[1], sys.argv[2]
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    xyz, source = real_cloud()
    print(f"cloud: {source}, {len(xyz)} points")
    p = lambda name: os.path.join(work, name)

    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(xyz.astype(np.float64)))
    cloud.estimate_normals()
    cloud.colors = o3d.utility.Vector3dVector(np.tile([[0.2, 0.4, 0.6]], (len(xyz), 1)))
    o3d.io.write_point_cloud(p("original.pcd"), cloud, write_ascii=False)
    reference = describe(cli, p("original.pcd"))
    if isinstance(reference, str):
        print(f"FAIL: the original does not describe: {reference}")
        return 1

    # Binary float32 formats must give the same bits; text and quantised formats (a float
    # printed with 10 decimals, or OBJ's 6 significant digits; LAS's integer steps) may move a
    # coordinate by its last digit, which moves a descriptor value by about as much.
    exact, close = [], []  # (name, path, extra flags)
    for ext in ["xyz", "xyzn", "xyzrgb", "pts"]:
        o3d.io.write_point_cloud(p(f"open3d.{ext}"), cloud)
        close.append((f"Open3D .{ext}", p(f"open3d.{ext}"), []))
    o3d.io.write_point_cloud(p("open3d_binary.ply"), cloud, write_ascii=False)
    exact.append(("Open3D .ply binary", p("open3d_binary.ply"), []))
    o3d.io.write_point_cloud(p("open3d_ascii.ply"), cloud, write_ascii=True)
    close.append(("Open3D .ply ascii", p("open3d_ascii.ply"), []))
    o3d.io.write_point_cloud(p("open3d_compressed.pcd"), cloud, compressed=True)
    exact.append(("Open3D .pcd binary_compressed", p("open3d_compressed.pcd"), []))

    # numpy: what Python users hold.
    np.save(p("numpy_f4.npy"), xyz)
    np.save(p("numpy_f8.npy"), xyz.astype(np.float64))
    np.save(p("numpy_fortran.npy"), np.asfortranarray(xyz))
    np.save(p("numpy_with_normals.npy"), np.hstack([xyz, np.asarray(cloud.normals, np.float32)]))
    structured = np.zeros(len(xyz), dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"),
                                           ("intensity", "<f4"), ("ring", "<u2")])
    structured["x"], structured["y"], structured["z"] = xyz.T
    np.save(p("numpy_structured.npy"), structured)
    np.savez(p("numpy_savez.npz"), points=xyz, labels=np.arange(len(xyz)))
    np.savez_compressed(p("numpy_compressed.npz"), xyz)
    for name in ["f4.npy", "f8.npy", "fortran.npy", "with_normals.npy", "structured.npy",
                 "savez.npz", "compressed.npz"]:
        exact.append((f"numpy {name}", p(f"numpy_{name}"), []))

    # PCL's tools, from the PCD PCL itself would write (pcl_converter reads it back first).
    pcl = shutil.which("pcl_converter") is not None and shutil.which("pcl_pcd2vtk") is not None
    if pcl:
        subprocess.run(["pcl_pcd2vtk", p("original.pcd"), p("pcl_pcd2vtk.vtk")], check=True,
                       capture_output=True)
        close.append(("PCL pcl_pcd2vtk .vtk (ascii)", p("pcl_pcd2vtk.vtk"), []))
        for ext, fmt in [("pcd", "binary"), ("ply", "binary"), ("vtk", "binary"),
                         ("obj", "ascii")]:
            out = p(f"pcl_converter_{fmt}.{ext}")
            subprocess.run(["pcl_converter", "-f", fmt, p("original.pcd"), out], check=True,
                           capture_output=True)
            # OBJ is text with 6 significant digits: close, not exact.
            (close if ext == "obj" else exact).append((f"PCL pcl_converter .{ext} {fmt}", out, []))
    else:
        print("FAIL: pcl_converter / pcl_pcd2vtk missing (tools/install-deps.sh installs pcl-tools)")
        return 1

    # gzip of any format, by name and piped through standard input.
    for src in ["original.pcd", "open3d.xyz", "numpy_f4.npy"]:
        with open(p(src), "rb") as f, gzip.open(p(src + ".gz"), "wb") as g:
            g.write(f.read())
        (close if src.endswith(".xyz") else exact).append((f"gzip {src}.gz", p(src + ".gz"), []))
    exact.append(("standard input, pcd", "-", ["--input-format", "pcd", "<", p("original.pcd")]))

    # LAS by hand (no Debian tool writes it): 1 um and 10 um quantisation.
    write_las(p("hand_1_2.las"), xyz, scale=1e-6, version=(1, 2), point_format=1)
    write_las(p("hand_1_4.las"), xyz, scale=1e-5, version=(1, 4), point_format=6)
    close += [("LAS 1.2 format 1, scale 1e-6", p("hand_1_2.las"), []),
              ("LAS 1.4 format 6, scale 1e-5", p("hand_1_4.las"), [])]

    failures = 0

    def check(name, path, extra, tolerance, against=reference):
        nonlocal failures
        if path == "-":
            got = {}
            for spec in SPECS:
                with open(extra[-1], "rb") as f:
                    run = subprocess.run([cli, "describe", "--local", "--spec", spec, "--format",
                                          "json", *extra[:-2], "-"], stdin=f,
                                         capture_output=True, text=True)
                if run.returncode != 0:
                    got = run.stderr.strip()
                    break
                got[spec] = np.array(json.loads(run.stdout)["descriptor"])
        else:
            got = describe(cli, path, extra)
        if isinstance(got, str):
            print(f"FAIL  {name}: {got}")
            failures += 1
            return
        worst = max(float(np.abs(got[s] - against[s]).max() / max(1e-12, np.abs(against[s]).max()))
                    for s in SPECS)
        ok = worst == 0 if tolerance == 0 else worst <= tolerance
        print(f"{'ok   ' if ok else 'FAIL '} {name}: largest difference {worst:.2e} of the "
              f"largest value{' (exact required)' if tolerance == 0 else f' (<= {tolerance})'}")
        failures += not ok

    for name, path, extra in exact:
        check(name, path, extra, 0)
    for name, path, extra in close:
        check(name, path, extra, 1e-3)

    # Meshes: one Open3D mesh in every mesh format samples to the same cloud.
    mesh = o3d.geometry.TriangleMesh.create_torus(torus_radius=1.0, tube_radius=0.3,
                                                 radial_resolution=24, tubular_resolution=12)
    mesh.compute_triangle_normals()
    for ext in ["ply", "off", "obj", "stl"]:
        o3d.io.write_triangle_mesh(p(f"mesh.{ext}"), mesh, write_ascii=ext in ("off", "obj"))
    # Open3D writes binary STL only; the ascii kind by hand, as CAD exporters write it.
    vertices, triangles = np.asarray(mesh.vertices), np.asarray(mesh.triangles)
    with open(p("mesh_ascii.stl"), "w") as f:
        f.write("solid torus\n")
        for t, n in zip(triangles, np.asarray(mesh.triangle_normals)):
            f.write(f"  facet normal {n[0]:e} {n[1]:e} {n[2]:e}\n    outer loop\n")
            for v in vertices[t].astype(np.float32):
                f.write(f"      vertex {v[0]:.9e} {v[1]:.9e} {v[2]:.9e}\n")
            f.write("    endloop\n  endfacet\n")
        f.write("endsolid torus\n")
    mesh_reference = describe(cli, p("mesh.ply"))
    if isinstance(mesh_reference, str):
        print(f"FAIL  Open3D mesh .ply: {mesh_reference}")
        return 1
    for ext in ["off", "obj", "stl"]:
        check(f"Open3D mesh .{ext} (sampled)", p(f"mesh.{ext}"), [], 1e-3, mesh_reference)
    check("Open3D mesh .stl ascii (sampled)", p("mesh_ascii.stl"), [], 1e-3, mesh_reference)
    if pcl:
        subprocess.run(["pcl_converter", "-f", "binary", p("mesh.ply"), p("pcl_mesh.vtk")],
                       check=True, capture_output=True)
        check("PCL pcl_converter mesh .vtk (sampled)", p("pcl_mesh.vtk"), [], 1e-3,
              mesh_reference)

    print(f"{failures} of {len(exact) + len(close) + 5} rows differ" if failures
          else "every format matches")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
