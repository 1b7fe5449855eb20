#!/usr/bin/python3
"""The eval report renders in a real browser, pictures included.

Writes a tiny labeled dataset (box, sphere and rod clouds as XYZ text; one sphere filed under
box/test/, a deliberate misclassification), runs `shapeid eval --local ... --report`, checks
that the error names the training file it matched, then opens the report in Debian's headless
Chromium and checks the screenshot's pixels: the page is not blank, its text is drawn, and
both pictures (the misread scan and its nearest training sample, three views each) were
decoded and painted side by side in their colors.

Usage: report_browser_test.py SHAPEID_CLI WORK_DIR. Exit 0 when it renders, 1 otherwise (what
failed is printed). Without Chromium, Pillow or numpy: exit 77 (ctest's skip), except under CI
(CI or SHAPEID_REQUIRE_BROWSER=1 in the environment), where it is a failure;
tools/install-deps.sh installs all three.
"""

import json
import math
import os
import random
import shutil
import subprocess
import sys
import time

REQUIRED = os.environ.get("SHAPEID_REQUIRE_BROWSER") == "1" or bool(os.environ.get("CI"))


def missing(what):
    print(f"{'FAIL' if REQUIRED else 'SKIP'}: {what} (tools/install-deps.sh installs it)")
    sys.exit(1 if REQUIRED else 77)


try:
    import numpy as np
    from PIL import Image
except ImportError as e:
    missing(f"{e.name} is missing (python3-numpy, python3-pil)")

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
if CHROMIUM is None:
    missing("chromium is not installed")

# The picture colors of client/cli/cloud_picture.cc: 24 shades from navy to pale blue.
NEAR, FAR, SHADES = (17, 45, 110), (165, 196, 236), 24
PALETTE = {
    tuple(n + (f - n) * s // (SHADES - 1) for n, f in zip(NEAR, FAR)) for s in range(SHADES)
}


def shape(kind, rng, n=300):
    """As core/testing/test_clouds.h: 0 a flat 4 x 3 box, 1 a unit sphere shell, 2 a rod."""
    points = []
    for _ in range(n):
        if kind == 1:
            x, y, z = rng.gauss(0, 1), rng.gauss(0, 1), rng.gauss(0, 1)
            r = math.sqrt(x * x + y * y + z * z) or 1.0
            points.append((x / r, y / r, z / r))
        else:
            size = (2, 1.5, 0.1) if kind == 0 else (3, 0.05, 0.05)
            points.append(tuple(s * rng.uniform(-1, 1) for s in size))
    return points


def write_xyz(path, points):
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "w") as f:
        f.writelines(f"{x:.6f} {y:.6f} {z:.6f}\n" for x, y, z in points)


def fail(message):
    print(f"FAIL: {message}")
    sys.exit(1)


def main():
    cli, work = sys.argv[1], os.path.abspath(sys.argv[2])
    shutil.rmtree(work, ignore_errors=True)
    data = os.path.join(work, "data")
    rng = random.Random(28)
    for kind, label in enumerate(["box", "sphere", "rod"]):
        for i in range(6):
            part = "train" if i < 4 else "test"
            write_xyz(os.path.join(data, label, part, f"{i}.xyz"), shape(kind, rng))
    write_xyz(os.path.join(data, "box", "test", "misfiled.xyz"), shape(1, rng))

    report = os.path.join(work, "report.html")
    started = time.monotonic()
    run = subprocess.run([cli, "--quiet", "eval", "--local", "--spec", "rphsd", data, "--report",
                          report, "--format", "json", "--predictions"],
                         capture_output=True, text=True, check=False)
    if run.returncode != 0:
        fail(f"shapeid eval exited {run.returncode}: {run.stderr}")
    result = json.loads(run.stdout)
    errors = [p for p in result["predictions"] if p["truth"] != p["predicted"]]
    if [e["file"] for e in errors] != [os.path.join(data, "box", "test", "misfiled.xyz")]:
        fail(f"expected the one misfiled sphere as the only error, got {errors}")
    matched = errors[0]["neighbors"][0]["file"]
    if not matched.startswith(os.path.join(data, "sphere", "train", "")):
        fail(f"the error's nearest training file is {matched}, not a sphere")
    page = open(report, encoding="utf-8").read()
    if f'<td class="path">{matched}</td><td>sphere</td>' not in page:
        fail(f"the report's error row does not name {matched}")
    eval_seconds = time.monotonic() - started

    # A window taller than the page: the whole report in one screenshot.
    shot = os.path.join(work, "shot.png")
    started = time.monotonic()
    chromium = subprocess.run(
        [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
         "--force-device-scale-factor=1", "--window-size=1000,2400",
         f"--user-data-dir={os.path.join(work, 'profile')}", f"--screenshot={shot}",
         f"file://{report}"],
        capture_output=True, text=True, timeout=60, check=False)
    browser_seconds = time.monotonic() - started
    if chromium.returncode != 0 or not os.path.exists(shot):
        fail(f"chromium exited {chromium.returncode}: {chromium.stderr[-2000:]}")

    pixels = np.asarray(Image.open(shot).convert("RGB")).astype(np.int32)
    height, width, _ = pixels.shape
    if (width, height) != (1000, 2400):
        fail(f"the screenshot is {width} x {height}, not the window's 1000 x 2400")
    background = np.all(pixels == (246, 247, 249), axis=2) | np.all(pixels == 255, axis=2)
    if background.all():
        fail("the screenshot is blank")
    dark = int(np.all(pixels < 100, axis=2).sum())  # text
    if dark < 2000:
        fail(f"only {dark} dark pixels: the page's text was not drawn")
    code = (pixels[:, :, 0] << 16) | (pixels[:, :, 1] << 8) | pixels[:, :, 2]
    palette = np.isin(code, [(r << 16) | (g << 8) | b for r, g, b in PALETTE])
    # A picture's view is a run of columns holding its colors (a few stray pixels of
    # anti-aliased text aside); views are at least 10 columns apart.
    columns = np.nonzero(palette.sum(axis=0) >= 3)[0]
    views = 0 if columns.size == 0 else 1 + int((np.diff(columns) > 8).sum())
    if views != 6:
        fail(f"expected 6 views (3 of the test cloud, 3 of its training sample), saw {views}")
    rows = np.nonzero(palette.sum(axis=1) >= 3)[0]
    if rows.size == 0 or rows.max() - rows.min() > 140:
        fail("the two pictures are not side by side")
    print(f"OK: the report ({len(page)} bytes) renders: {views} views of 2 clouds, "
          f"{int(palette.sum())} picture pixels, {dark} text pixels; eval {eval_seconds:.1f} s, "
          f"chromium {browser_seconds:.1f} s")


if __name__ == "__main__":
    main()
