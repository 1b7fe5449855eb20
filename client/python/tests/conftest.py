"""Fixtures of the Python package's tests: real shapeid-server processes and test clouds.

ctest (client/python/CMakeLists.txt) sets SHAPEID_SERVER, SHAPEID_CLI, SHAPEID_SOURCE_DIR and
PYTHONPATH (the package as built into the build tree). By hand, from the repository root:

    PYTHONPATH=build/ci/client/python/package SHAPEID_SERVER=build/ci/server/shapeid-server \
      SHAPEID_SOURCE_DIR=$PWD /usr/bin/python3 -m pytest client/python/tests
"""

import hashlib
import os
import queue
import re
import signal
import subprocess
import tempfile
import threading
import time

import numpy as np
import pytest

try:
    import shapeid
except ImportError as e:  # say what to do rather than a bare traceback
    raise SystemExit("tests: cannot import the shapeid package (%s): run them through ctest, "
                     "or put the built package on PYTHONPATH (see conftest.py)" % e)


def _required_env(name):
    value = os.environ.get(name)
    if not value:
        pytest.exit("tests: %s is not set; run them through ctest (see conftest.py)" % name,
                    returncode=2)
    return value


class ServerProcess:
    """shapeid-server --listen=127.0.0.1:0 with a data directory of its own; `address` is
    read from its "listening on HOST:PORT" line."""

    def __init__(self, *flags, env=None, start_timeout=15.0):
        binary = _required_env("SHAPEID_SERVER")
        self.data_dir = tempfile.TemporaryDirectory(prefix="shapeid_pytest_")
        self.stderr = tempfile.TemporaryFile()
        self.proc = subprocess.Popen(
            [binary, "--listen=127.0.0.1:0", "--data_dir=" + self.data_dir.name, *flags],
            stdout=subprocess.PIPE, stderr=self.stderr, stdin=subprocess.DEVNULL,
            env=dict(os.environ, **(env or {})))
        lines = queue.Queue()
        threading.Thread(target=self._pump, args=(lines,), daemon=True).start()
        deadline = time.monotonic() + start_timeout
        self.address = None
        while self.address is None:
            try:
                line = lines.get(timeout=max(deadline - time.monotonic(), 0.01))
            except queue.Empty:
                self.stop()
                raise RuntimeError("shapeid-server printed no 'listening on' line in %.0f s: %s"
                                   % (start_timeout, self.stderr_text()))
            if line is None:
                raise RuntimeError("shapeid-server exited with %s before listening: %s"
                                   % (self.proc.wait(), self.stderr_text()))
            if line.startswith("listening on "):
                self.address = line[len("listening on "):].strip()

    def _pump(self, lines):
        for raw in self.proc.stdout:
            lines.put(raw.decode("utf-8", "replace"))
        lines.put(None)

    def stderr_text(self):
        self.stderr.seek(0)
        return self.stderr.read().decode("utf-8", "replace").strip()

    def stop(self):
        """SIGTERM, then the exit code (a kill after 5 s: None)."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
                return None
        self.data_dir.cleanup()
        return self.proc.returncode


@pytest.fixture(scope="session")
def server():
    """One plain server for the whole run (tests use galleries of their own names)."""
    process = ServerProcess()
    yield process
    code = process.stop()
    assert code == 0, "shapeid-server exit code %s after SIGTERM: %s" % (
        code, process.stderr_text())


@pytest.fixture(scope="session")
def client(server):
    with shapeid.Client(server.address) as c:
        yield c


@pytest.fixture
def gallery(request, client):
    """A fresh gallery named after the test (default spec), deleted afterwards."""
    name = re.sub(r"[^A-Za-z0-9_.-]", "-", request.node.name)[:100]
    client.create_gallery(name)
    yield name
    try:
        client.delete_gallery(name)
    except shapeid.NotFoundError:
        pass


def sha256(text):
    return hashlib.sha256(text.encode()).hexdigest()


# ---------------------------------------------------------------------------------------------
# Clouds

SHAPES = ("plate", "ball", "rod")


def shape(kind, seed, n=1024):
    """A flat box, a sphere shell or a thin rod as an (n, 3) float32 array."""
    rng = np.random.default_rng(seed)
    if kind == 0:
        points = rng.uniform(-1, 1, (n, 3)) * [2.0, 1.5, 0.1]
    elif kind == 1:
        points = rng.normal(size=(n, 3))
        points *= (1 + 0.01 * rng.uniform(-1, 1, (n, 1))) / np.linalg.norm(points, axis=1,
                                                                          keepdims=True)
    else:
        points = rng.uniform(-1, 1, (n, 3)) * [3.0, 0.05, 0.05]
    return points.astype(np.float32)


@pytest.fixture(scope="session")
def trained(client):
    """A gallery "shapes" of 4 plates, balls and rods, trained once."""
    clouds = [shape(kind, 100 + 10 * i + kind) for i in range(4) for kind in range(3)]
    labels = [SHAPES[kind] for _ in range(4) for kind in range(3)]
    client.create_gallery("shapes")
    result = client.train("shapes", clouds, labels)
    return {"name": "shapes", "labels": labels, "ids": result.sample_ids}
