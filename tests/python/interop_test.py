#!/usr/bin/python3
"""Interop test: a Python client, generated from proto/shapeid/v1/shapeid.proto with Debian's
grpc_python_plugin and run by Debian's python3-grpcio, drives a real shapeid-server process.

The proto is the contract; this proves a client in another language can follow it: the health
service, ListDescriptors, gallery management, client-streaming Train / Classify / Describe
with packed little-endian float32 points, and the status codes of the errors.

Usage (ctest runs it so):
  /usr/bin/python3 interop_test.py --server build/server/shapeid-server --stubs build/tests/python_stubs
Only the standard library, grpc and google.protobuf are needed.
"""

import argparse
import math
import os
import queue
import random
import signal
import struct
import subprocess
import sys
import tempfile
import threading
import time
import unittest

ARGS = None          # parsed command line, set in main()
grpc = None          # imported in main() so a missing package gives a clear message
pb = None            # shapeid.v1.shapeid_pb2
pb_grpc = None       # shapeid.v1.shapeid_pb2_grpc

SHAPES = ("box", "sphere", "rod")
CALL_TIMEOUT = 10.0  # seconds, every RPC
FIRST_ASSIGNED_ID = 1 << 63  # core/gallery/gallery.h kFirstAssignedId


# ----------------------------------------------------------------------------------------------
# Points

def shape(kind, seed, n=600):
    """A flat box, a sphere shell or a thin rod, as a list of (x, y, z); as in
    server/gallery_service_test.cc (not the same random numbers: another generator)."""
    rng = random.Random(seed)
    u = lambda: rng.uniform(-1.0, 1.0)
    points = []
    for _ in range(n):
        if kind == 0:
            points.append((2 * u(), 1.5 * u(), 0.1 * u()))
        elif kind == 1:
            x, y, z = rng.gauss(0, 1), rng.gauss(0, 1), rng.gauss(0, 1)
            norm = math.sqrt(x * x + y * y + z * z) or 1.0
            r = (1.0 + 0.01 * u()) / norm
            points.append((x * r, y * r, z * r))
        else:
            points.append((3 * u(), 0.05 * u(), 0.05 * u()))
    return points


def pack(points):
    """PointChunk.xyz: 12 bytes per point, x y z as little-endian IEEE-754 float32."""
    flat = [c for p in points for c in p]
    return struct.pack("<%df" % len(flat), *flat)


def chunks(points, size):
    for i in range(0, len(points), size):
        yield pack(points[i:i + size])


# ----------------------------------------------------------------------------------------------
# Request streams

def train_requests(gallery, samples, chunk=256, empty_chunk=False):
    """TrainHeader, then per sample a SampleHeader and its PointChunks.
    samples: list of (label, sample_id, points)."""
    yield pb.TrainRequest(header=pb.TrainHeader(gallery=gallery))
    for label, sample_id, points in samples:
        yield pb.TrainRequest(sample=pb.SampleHeader(label=label, sample_id=sample_id))
        if empty_chunk:  # the proto allows empty chunks
            yield pb.TrainRequest(points=pb.PointChunk(xyz=b""))
        for data in chunks(points, chunk):
            yield pb.TrainRequest(points=pb.PointChunk(xyz=data))


def classify_requests(gallery, points, k=0, chunk=1000):
    yield pb.ClassifyRequest(header=pb.ClassifyHeader(gallery=gallery, k=k,
                                                      expected_points=len(points)))
    for data in chunks(points, chunk):
        yield pb.ClassifyRequest(points=pb.PointChunk(xyz=data))


def describe_requests(spec, points, chunk):
    yield pb.DescribeRequest(header=pb.DescribeHeader(descriptor_spec=spec))
    for data in chunks(points, chunk):
        yield pb.DescribeRequest(points=pb.PointChunk(xyz=data))


def training_set(per_shape, seed):
    return [(SHAPES[kind], 0, shape(kind, seed + 10 * i + kind))
            for i in range(per_shape) for kind in range(3)]


# ----------------------------------------------------------------------------------------------
# The server process

class ServerProcess:
    """shapeid-server --listen=127.0.0.1:0, its address read from `listening on HOST:PORT`."""

    def __init__(self, binary, start_timeout=15.0):
        self.stderr = tempfile.TemporaryFile()
        # A data directory of its own, removed with the process object (TemporaryDirectory).
        self.data_dir = tempfile.TemporaryDirectory(prefix="shapeid_interop_")
        self.proc = subprocess.Popen([binary, "--listen=127.0.0.1:0",
                                      "--data_dir=" + self.data_dir.name], stdout=subprocess.PIPE,
                                     stderr=self.stderr, stdin=subprocess.DEVNULL)
        lines = queue.Queue()
        threading.Thread(target=self._pump, args=(lines,), daemon=True).start()
        deadline = time.monotonic() + start_timeout
        self.address = None
        while self.address is None:
            remaining = deadline - time.monotonic()
            try:
                line = lines.get(timeout=max(remaining, 0.01))
            except queue.Empty:
                self.kill()
                raise RuntimeError("shapeid-server printed no 'listening on' line in %.0f s; "
                                   "stderr: %s" % (start_timeout, self.stderr_text()))
            if line is None:
                code = self.proc.wait()
                raise RuntimeError("shapeid-server exited with %d before listening; stderr: %s"
                                   % (code, self.stderr_text()))
            if line.startswith("listening on "):
                self.address = line[len("listening on "):].strip()

    def _pump(self, lines):
        for raw in self.proc.stdout:
            lines.put(raw.decode("utf-8", "replace"))
        lines.put(None)

    def stderr_text(self):
        self.stderr.seek(0)
        return self.stderr.read().decode("utf-8", "replace").strip()

    def terminate(self, timeout=5.0):
        """SIGTERM; returns the exit code, or None if the server did not exit in time (then
        it is killed)."""
        if self.proc.poll() is not None:
            return self.proc.returncode
        self.proc.send_signal(signal.SIGTERM)
        try:
            return self.proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.kill()
            return None

    def kill(self):
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()


# ----------------------------------------------------------------------------------------------
# Tests

class InteropTest(unittest.TestCase):
    """Each test gets its own server; tearDown stops it with SIGTERM and checks exit 0."""

    def setUp(self):
        self.server = ServerProcess(ARGS.server)
        self.addCleanup(self.server.kill)  # runs even if setUp or the test fails
        self.channel = grpc.insecure_channel(self.server.address)
        self.addCleanup(self.channel.close)
        grpc.channel_ready_future(self.channel).result(timeout=CALL_TIMEOUT)
        self.stub = pb_grpc.ShapeIdStub(self.channel)

    def tearDown(self):
        self.channel.close()
        code = self.server.terminate(timeout=5.0)
        self.assertIsNotNone(code, "shapeid-server did not exit within 5 s of SIGTERM")
        self.assertEqual(code, 0, "shapeid-server exit code after SIGTERM; stderr: %s"
                         % self.server.stderr_text())

    # Helpers ---------------------------------------------------------------------------------

    def assertRpcError(self, code, call, *args, **kwargs):
        """Runs call(*args) expecting a gRPC error with `code`; returns its details string."""
        kwargs.setdefault("timeout", CALL_TIMEOUT)
        with self.assertRaises(grpc.RpcError) as caught:
            call(*args, **kwargs)
        self.assertEqual(caught.exception.code(), code, caught.exception.details())
        return caught.exception.details() or ""

    def create(self, name, spec=""):
        return self.stub.CreateGallery(pb.CreateGalleryRequest(name=name, descriptor_spec=spec),
                                       timeout=CALL_TIMEOUT)

    def get(self, name):
        return self.stub.GetGallery(pb.GetGalleryRequest(name=name), timeout=CALL_TIMEOUT)

    def train(self, gallery, samples, **kwargs):
        return self.stub.Train(train_requests(gallery, samples, **kwargs), timeout=CALL_TIMEOUT)

    def classify(self, gallery, points, k=0):
        return self.stub.Classify(classify_requests(gallery, points, k), timeout=CALL_TIMEOUT)

    # 1. Health ---------------------------------------------------------------------------------

    def test_health_check_serving(self):
        try:
            from grpc_health.v1 import health_pb2, health_pb2_grpc  # not in Debian's python3-grpcio
        except ImportError:
            # Generic call: HealthCheckRequest{service: ""} serialises to no bytes; the answer
            # HealthCheckResponse{status: SERVING (1)} to field 1 varint 1.
            check = self.channel.unary_unary("/grpc.health.v1.Health/Check",
                                              request_serializer=lambda _: b"",
                                              response_deserializer=lambda b: b)
            self.assertEqual(check(None, timeout=CALL_TIMEOUT), b"\x08\x01")
        else:
            reply = health_pb2_grpc.HealthStub(self.channel).Check(
                health_pb2.HealthCheckRequest(service=""), timeout=CALL_TIMEOUT)
            self.assertEqual(reply.status, health_pb2.HealthCheckResponse.SERVING)

    # 2. ListDescriptors ------------------------------------------------------------------------

    def test_list_descriptors_has_every_kind_with_defaults(self):
        reply = self.stub.ListDescriptors(pb.ListDescriptorsRequest(), timeout=CALL_TIMEOUT)
        kinds = {d.kind: d for d in reply.descriptors}
        self.assertEqual(set(kinds), {"rphsd", "comsd", "cnsd", "dfsd"})
        self.assertEqual(kinds["rphsd"].default_spec, "rphsd:refs=cubic27,bins=100,variant=complete")
        self.assertEqual(kinds["rphsd"].default_dimension, 81)
        self.assertEqual(kinds["dfsd"].default_spec,
                         "dfsd:grid=12,order=8,frame=box,fields=both,size=0")
        self.assertEqual(kinds["dfsd"].default_dimension, 240)
        self.assertEqual(kinds["comsd"].default_spec, "comsd:grid=50")
        self.assertEqual(kinds["comsd"].default_dimension, 91)
        self.assertEqual(kinds["cnsd"].default_spec,
                         "cnsd:t_start=0.05,t_end=0.95,t_step=0.05,max_points=8000,"
                         "downsample=voxel,seed=0")
        self.assertEqual(kinds["cnsd"].default_dimension, 38)
        for d in reply.descriptors:
            self.assertTrue(d.summary, d.kind)
            # The default spec is "kind:name=default,..." in parameter order, less dfsd's
            # up, which a canonical spec writes only when it is not z.
            expected = ",".join("%s=%s" % (p.name, p.default_value) for p in d.parameters
                                if (d.kind, p.name) != ("dfsd", "up"))
            self.assertEqual(d.default_spec, "%s:%s" % (d.kind, expected))
            for p in d.parameters:
                self.assertTrue(p.help, "%s.%s has no help" % (d.kind, p.name))

    # 3, 4 and 6. Train, Classify, GetGallery, DeleteGallery -------------------------------------

    def test_train_classify_get_delete(self):
        created = self.create("shapes", "rphsd:refs=cubic27,bins=30")
        self.assertEqual(created.name, "shapes")
        self.assertEqual(created.descriptor_spec, "rphsd:refs=cubic27,bins=30,variant=complete")
        self.assertEqual(created.dimension, 81)
        self.assertEqual(created.knn.k, 1)
        self.assertEqual(created.knn.weighting, pb.VOTE_WEIGHTING_UNIFORM)
        self.assertEqual(created.knn.scaling, pb.FEATURE_SCALING_NONE)
        self.assertEqual(created.sample_count, 0)
        self.assertGreater(created.create_time.seconds, 0)

        samples = training_set(4, 100)   # 12 samples: box, sphere, rod, box, ...
        samples[0] = (samples[0][0], 42, samples[0][2])  # a client-chosen id among assigned ones
        trained = self.train("shapes", samples, chunk=256, empty_chunk=True)
        self.assertEqual(len(trained.sample_ids), 12)
        self.assertEqual(trained.sample_ids[0], 42)
        assigned = list(trained.sample_ids[1:])
        self.assertTrue(all(i >= FIRST_ASSIGNED_ID for i in assigned), assigned)  # uint64 > 2^63
        self.assertEqual(len(set(trained.sample_ids)), 12)
        self.assertEqual(trained.gallery_sample_count, 12)
        self.assertGreater(trained.gallery_version, created.version)
        self.assertTrue(trained.HasField("describe_time"))

        gallery = self.get("shapes")
        self.assertEqual(gallery.sample_count, 12)
        self.assertEqual(gallery.version, trained.gallery_version)
        self.assertEqual([(c.label, c.count) for c in gallery.label_counts],
                         [("box", 4), ("rod", 4), ("sphere", 4)])  # sorted by label
        listed = self.stub.ListGalleries(pb.ListGalleriesRequest(), timeout=CALL_TIMEOUT)
        self.assertEqual([g.name for g in listed.galleries], ["shapes"])

        label_of = {i: label for i, (label, _, _) in zip(trained.sample_ids, samples)}
        for kind in range(3):
            points = shape(kind, 999 + kind, 2000)
            answer = self.classify("shapes", points, k=3)
            self.assertEqual(answer.label, SHAPES[kind])
            self.assertFalse(answer.unknown)
            self.assertEqual(answer.num_points, 2000)
            self.assertEqual(len(answer.neighbors), 3)
            distances = [n.distance for n in answer.neighbors]
            self.assertEqual(distances, sorted(distances))  # nearest first
            for n in answer.neighbors:
                self.assertIn(n.sample_id, label_of)
                self.assertEqual(n.label, label_of[n.sample_id])
            weights = [v.weight for v in answer.votes]
            self.assertEqual(weights, sorted(weights, reverse=True))  # most weight first
            self.assertEqual(answer.votes[0].label, answer.label)
            self.assertAlmostEqual(sum(weights), 3.0)  # uniform: 1 per neighbour
            # The one-message call answers the same, neighbour for neighbour.
            one = self.stub.ClassifyCloud(
                pb.ClassifyCloudRequest(
                    header=pb.ClassifyHeader(gallery="shapes", k=3, expected_points=len(points)),
                    points=pb.PointChunk(xyz=pack(points))),
                timeout=CALL_TIMEOUT)
            self.assertEqual(one.label, answer.label)
            self.assertEqual([(n.sample_id, n.distance) for n in one.neighbors],
                             [(n.sample_id, n.distance) for n in answer.neighbors])
            self.assertGreater(answer.confidence, 0.0)
            self.assertLessEqual(answer.confidence, 1.0)
            self.assertAlmostEqual(answer.confidence, weights[0] / sum(weights))
            self.assertTrue(answer.HasField("describe_time"))
            self.assertTrue(answer.HasField("search_time"))

        deleted = self.stub.DeleteGallery(pb.DeleteGalleryRequest(name="shapes"),
                                          timeout=CALL_TIMEOUT)
        self.assertEqual(deleted.samples_deleted, 12)
        self.assertRpcError(grpc.StatusCode.NOT_FOUND, self.stub.GetGallery,
                            pb.GetGalleryRequest(name="shapes"))
        listed = self.stub.ListGalleries(pb.ListGalleriesRequest(), timeout=CALL_TIMEOUT)
        self.assertEqual(len(listed.galleries), 0)

    def test_describe_is_independent_of_chunking(self):
        points = shape(1, 5, 1000)
        first = self.stub.Describe(describe_requests("rphsd:bins=30", points, 7),
                                   timeout=CALL_TIMEOUT)
        second = self.stub.Describe(describe_requests("rphsd:bins=30", points, 1000),
                                    timeout=CALL_TIMEOUT)
        self.assertEqual(first.descriptor_spec, "rphsd:refs=cubic27,bins=30,variant=complete")
        self.assertEqual(first.num_points, 1000)
        self.assertEqual(len(first.values), 81)
        self.assertEqual(list(first.values), list(second.values))
        self.assertTrue(all(math.isfinite(v) for v in first.values))

    # 5. Errors keep their codes across languages -----------------------------------------------

    def test_error_codes(self):
        self.create("g", "rphsd:bins=30")
        self.assertRpcError(grpc.StatusCode.ALREADY_EXISTS, self.stub.CreateGallery,
                            pb.CreateGalleryRequest(name="g"))
        details = self.assertRpcError(grpc.StatusCode.INVALID_ARGUMENT, self.stub.CreateGallery,
                                      pb.CreateGalleryRequest(name="no spaces"))
        self.assertIn("[A-Za-z0-9]", details)

        details = self.assertRpcError(grpc.StatusCode.NOT_FOUND, self.stub.GetGallery,
                                      pb.GetGalleryRequest(name="nope"))
        self.assertIn("nope", details)
        self.assertRpcError(grpc.StatusCode.NOT_FOUND, self.stub.Train,
                            train_requests("nope", training_set(1, 1)))
        self.assertRpcError(grpc.StatusCode.NOT_FOUND, self.stub.Classify,
                            classify_requests("nope", shape(0, 1)))
        self.assertRpcError(grpc.StatusCode.NOT_FOUND, self.stub.DeleteGallery,
                            pb.DeleteGalleryRequest(name="nope"))

        details = self.assertRpcError(grpc.StatusCode.FAILED_PRECONDITION, self.stub.Classify,
                                      classify_requests("g", shape(0, 1)))
        self.assertIn("has no samples", details)

        trained = self.train("g", training_set(1, 2))
        self.assertEqual(trained.gallery_sample_count, 3)
        version = self.get("g").version

        # A NaN in sample 3 (counting from 0 in the stream), point 17: the whole stream fails.
        samples = training_set(2, 7)
        label, sample_id, points = samples[3]
        points = list(points)
        points[17] = (points[17][0], float("nan"), points[17][2])
        samples[3] = (label, sample_id, points)
        details = self.assertRpcError(grpc.StatusCode.INVALID_ARGUMENT, self.stub.Train,
                                      train_requests("g", samples))
        self.assertIn("sample 3", details)
        self.assertIn("point 17", details)
        after = self.get("g")
        self.assertEqual(after.sample_count, 3)  # all-or-nothing
        self.assertEqual(after.version, version)

        # A chunk whose length is not a multiple of 12, and points before the header.
        bad_chunk = iter([pb.ClassifyRequest(header=pb.ClassifyHeader(gallery="g")),
                          pb.ClassifyRequest(points=pb.PointChunk(xyz=b"\0" * 13))])
        self.assertRpcError(grpc.StatusCode.INVALID_ARGUMENT, self.stub.Classify, bad_chunk)
        headless = iter([pb.ClassifyRequest(points=pb.PointChunk(xyz=b"\0" * 12))])
        details = self.assertRpcError(grpc.StatusCode.INVALID_ARGUMENT, self.stub.Classify,
                                      headless)
        self.assertIn("first message must be a ClassifyHeader", details)
        details = self.assertRpcError(grpc.StatusCode.INVALID_ARGUMENT, self.stub.Classify,
                                      classify_requests("g", [(0, 0, 0), (1, 1, 1)]))
        self.assertIn("cloud has 2 points", details)
        self.assertEqual(self.get("g").sample_count, 3)  # unchanged by every error above


# ----------------------------------------------------------------------------------------------

def main():
    global ARGS, grpc, pb, pb_grpc
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--server", required=True, help="path of the shapeid-server binary")
    parser.add_argument("--stubs", required=True,
                        help="directory holding shapeid/v1/shapeid_pb2{,_grpc}.py")
    ARGS, rest = parser.parse_known_args()

    try:
        import grpc as grpc_module
        import google.protobuf  # noqa: F401
    except ImportError as e:
        sys.exit("interop_test: %s under %s. Install Debian's python3-grpcio and python3-protobuf "
                 "(tools/install-deps.sh) and run this with /usr/bin/python3." % (e, sys.executable))
    grpc = grpc_module
    generated = os.path.join(ARGS.stubs, "shapeid", "v1", "shapeid_pb2_grpc.py")
    if not os.path.isfile(generated):
        sys.exit("interop_test: no generated stubs at %s. They are made at build time by "
                 "grpc_python_plugin (package protobuf-compiler-grpc); if CMake did not find it, "
                 "run tools/install-deps.sh, re-run cmake and build." % generated)
    if not os.access(ARGS.server, os.X_OK):
        sys.exit("interop_test: server binary %s is missing or not executable" % ARGS.server)
    sys.path.insert(0, os.path.abspath(ARGS.stubs))
    from shapeid.v1 import shapeid_pb2, shapeid_pb2_grpc  # noqa: E402 (path set above)
    pb, pb_grpc = shapeid_pb2, shapeid_pb2_grpc

    started = time.monotonic()
    suite = unittest.defaultTestLoader.loadTestsFromTestCase(InteropTest)
    if rest:  # test names, as unittest accepts them: e.g. InteropTest.test_error_codes
        suite = unittest.defaultTestLoader.loadTestsFromNames(rest, sys.modules[__name__])
    result = unittest.TextTestRunner(verbosity=2).run(suite)
    import google.protobuf as protobuf_module
    print("python interop: %d tests, %d failures, %d errors in %.1f s (python %s, grpcio %s, "
          "protobuf %s)" % (result.testsRun, len(result.failures), len(result.errors),
                            time.monotonic() - started, sys.version.split()[0],
                            grpc.__version__, protobuf_module.__version__))
    sys.exit(0 if result.wasSuccessful() else 1)


if __name__ == "__main__":
    main()
