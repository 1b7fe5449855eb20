#!/usr/bin/python3
"""The Python client beside the C++ client (issue 24): one shapeid-server started here, a
gallery of --gallery-size synthetic 1,024-point clouds, then for each of --runs rounds
(alternating which client goes first):
  - Classify latency from one thread, --requests calls timed one by one, 1,024-point
    clouds (both clients send them in one ClassifyCloud message), in --blocks blocks with
    the Python client and the C++ one (bench/client_bench.cc, the real shapeid::Client)
    taking turns against the same server;
  - throughput from --threads threads sharing one client for --seconds, both clients;
and what the client does to a 1,000,000-point PointCloud2 (ROS 1 message class when
Debian's python3-sensor-msgs is there) before sending it: its layout checked and a strided
finiteness pass, its data forwarded as it is (the default), and, for comparison, the
conversion to packed float32 (forward_point_cloud2=False). Prints the medians over the
rounds as a markdown table, with the machine, and one JSON line.

    cmake --preset release
    cmake --build --preset release --target shapeid_server client_bench shapeid_python_package
    bench/python_client_bench.py                  # ~1 min
    bench/python_client_bench.py --quick          # a few seconds, for the CI smoke
    bench/python_client_bench.py --conversion-only  # the PointCloud2 figures, no server

The server, both load generators and this script share the machine's cores: on 2 cores the
throughput figures show the client's CPU cost as much as the server's.
"""

import argparse
import concurrent.futures
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import threading
import time
import types

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def surface_cloud(rng, n=1024):
    """A box joined to an ellipsoid, of random proportions (as bench/bench_clouds.h)."""
    box = rng.uniform(0.3, 2.0, 3)
    half = n // 2
    p = rng.uniform(-1, 1, (half, 3)) * box
    face = rng.integers(0, 3, half)
    p[np.arange(half), face] = np.where(rng.random(half) < 0.5, -1, 1) * box[face]
    e = rng.normal(size=(n - half, 3))
    e = e / np.linalg.norm(e, axis=1, keepdims=True) * rng.uniform(0.3, 1.2, 3) + [0, 0, box[2]]
    cloud = np.concatenate([p, e]).astype(np.float32)
    return cloud[rng.permutation(n)]


class Server:
    def __init__(self, binary):
        self.proc = subprocess.Popen([binary, "--listen=127.0.0.1:0", "--data_dir=",
                                      "--log_level=warning"], stdout=subprocess.PIPE,
                                     stderr=subprocess.DEVNULL, stdin=subprocess.DEVNULL)
        line = self.proc.stdout.readline().decode()
        if not line.startswith("listening on "):
            self.proc.kill()
            raise SystemExit("shapeid-server did not start: %r" % line)
        self.address = line.split()[-1]

    def stop(self):
        self.proc.terminate()
        self.proc.wait(timeout=10)


def python_latency(client, queries, warmup, requests):
    for i in range(warmup):
        client.classify("bench", queries[i % len(queries)])
    micros = []
    for i in range(requests):
        start = time.perf_counter()
        client.classify("bench", queries[i % len(queries)])
        micros.append((time.perf_counter() - start) * 1e6)
    return micros


def python_throughput(client, queries, threads, seconds):
    stop = threading.Event()
    counts = [0] * threads

    def work(t):
        i = t
        while not stop.is_set():
            client.classify("bench", queries[i % len(queries)])
            counts[t] += 1
            i += 7

    with concurrent.futures.ThreadPoolExecutor(threads) as pool:
        start = time.perf_counter()
        futures = [pool.submit(work, t) for t in range(threads)]
        time.sleep(seconds)
        stop.set()
        for f in futures:
            f.result()
        elapsed = time.perf_counter() - start
    return sum(counts) / elapsed


def percentile(values, q):  # nearest rank, as bench/percentile.h
    values = sorted(values)
    return values[min(len(values) - 1, int(q * (len(values) - 1) + 0.5))]


def point_cloud2(n, layout):
    """A 1-row PointCloud2 of n points: "xyzi32" is an Ouster-like 32-byte point (x y z at 0,
    intensity, ring, padding), "xyz64" float64 x y z with intensity, 32 bytes."""
    rng = np.random.default_rng(1)
    if layout == "xyzi32":
        fields = [("x", 0, 7), ("y", 4, 7), ("z", 8, 7), ("intensity", 16, 7)]
        dtype = np.dtype({"names": ["x", "y", "z", "intensity", "ring"],
                          "formats": ["<f4", "<f4", "<f4", "<f4", "<u2"],
                          "offsets": [0, 4, 8, 16, 20], "itemsize": 32})
    else:
        fields = [("x", 0, 8), ("y", 8, 8), ("z", 16, 8), ("intensity", 24, 7)]
        dtype = np.dtype({"names": ["x", "y", "z", "intensity"],
                          "formats": ["<f8", "<f8", "<f8", "<f4"],
                          "offsets": [0, 8, 16, 24], "itemsize": 32})
    records = np.zeros(n, dtype)
    for name in "xyz":
        records[name] = rng.uniform(-50, 50, n)
    data = records.tobytes()
    try:
        from sensor_msgs.msg import PointCloud2, PointField
        return PointCloud2(height=1, width=n, is_bigendian=False, point_step=32,
                           row_step=32 * n, data=data, is_dense=True,
                           fields=[PointField(name=f, offset=o, datatype=d, count=1)
                                   for f, o, d in fields]), "sensor_msgs (ROS 1)"
    except ImportError:
        return types.SimpleNamespace(
            height=1, width=n, is_bigendian=False, point_step=32, row_step=32 * n, data=data,
            fields=[types.SimpleNamespace(name=f, offset=o, datatype=d, count=1)
                    for f, o, d in fields]), "a ROS 2-style object"


def conversion_ms(shapeid, n, layout, repeats, forward=True):
    message, kind = point_cloud2(n, layout)
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        encoded = shapeid.encode(message, forward_point_cloud2=forward)
        times.append((time.perf_counter() - start) * 1e3)
    assert encoded.num_points == n
    assert (encoded.layout == shapeid.clouds.PACKED_XYZ32) != forward
    return statistics.median(times), kind


def conversion_figures(shapeid, repeats):
    """{name: median ms} for 1,000,000 points: forwarded (layout + check) and converted."""
    out = {}
    for layout, name in (("xyzi32", "f32"), ("xyz64", "f64")):
        out["check_ms_" + name], kind = conversion_ms(shapeid, 1_000_000, layout, repeats)
        out["conversion_ms_" + name], _ = conversion_ms(shapeid, 1_000_000, layout, repeats,
                                                        forward=False)
    return out, kind


def print_conversion(figures, kind, repeats):
    print("PointCloud2 of 1,000,000 points (%s), median of %d: forwarded (layout + "
          "finiteness check) %.1f ms float32 x y z in a 32-byte point, %.1f ms float64 x y z; "
          "converted to packed float32 instead: %.1f ms, %.1f ms"
          % (kind, repeats, figures["check_ms_f32"], figures["check_ms_f64"],
             figures["conversion_ms_f32"], figures["conversion_ms_f64"]))


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--server-binary",
                        default=os.path.join(ROOT, "build/release/server/shapeid-server"))
    parser.add_argument("--cpp-bench", default=os.path.join(ROOT, "build/release/bench/client_bench"))
    parser.add_argument("--gallery-size", type=int, default=4000)
    parser.add_argument("--queries", type=int, default=64, help="distinct query clouds, cycled")
    parser.add_argument("--warmup", type=int, default=50, help="calls before each block")
    parser.add_argument("--requests", type=int, default=2000,
                        help="single-thread calls timed per client and round")
    parser.add_argument("--blocks", type=int, default=4,
                        help="blocks the single-thread calls are split in, clients alternating")
    parser.add_argument("--threads", type=int, default=16)
    parser.add_argument("--seconds", type=float, default=3.0)
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--quick", action="store_true", help="tiny numbers for a CI smoke")
    parser.add_argument("--conversion-only", action="store_true",
                        help="only the PointCloud2 figures (no server, no C++ client)")
    args = parser.parse_args()
    repeats = 3 if args.quick else 20
    if args.conversion_only:
        sys.path.append(os.path.join(ROOT, "build/release/client/python/package"))
        import shapeid
        figures, kind = conversion_figures(shapeid, repeats)
        print_conversion(figures, kind, repeats)
        print("JSON " + json.dumps(figures))
        return 0
    if args.quick:
        args.gallery_size, args.warmup, args.requests, args.blocks = 100, 10, 100, 2
        args.seconds, args.runs = 0.3, 1
    for path in (args.server_binary, args.cpp_bench):
        if not os.access(path, os.X_OK):
            raise SystemExit("python_client_bench: %s is not built (cmake --build --preset "
                             "release --target shapeid_server client_bench)" % path)
    # The package as the release build makes it, unless PYTHONPATH or an install has one.
    sys.path.append(os.path.join(ROOT, "build/release/client/python/package"))
    import shapeid
    print("shapeid package: %s" % os.path.dirname(shapeid.__file__))

    load_before = open("/proc/loadavg").read().split()[:3]
    rng = np.random.default_rng(7)
    server = Server(args.server_binary)
    try:
        client = shapeid.Client(server.address)
        client.create_gallery("bench")
        for start in range(0, args.gallery_size, 500):
            batch = [surface_cloud(rng) for _ in range(min(500, args.gallery_size - start))]
            client.train("bench", batch, ["class%d" % (i % 10) for i in range(len(batch))])
        queries = [surface_cloud(rng) for _ in range(args.queries)]
        with tempfile.NamedTemporaryFile(suffix=".f32") as f:
            f.write(b"".join(q.tobytes() for q in queries))
            f.flush()
            rounds = []
            for r in range(args.runs):
                py_micros, cpp_micros, figures = [], [], {}

                def cpp_bench(requests, warmup, seconds):
                    out = subprocess.run(
                        [args.cpp_bench, "--server", server.address, "--gallery", "bench",
                         "--clouds", f.name, "--warmup", str(warmup), "--requests",
                         str(requests), "--threads", str(args.threads), "--seconds",
                         str(seconds), "--latencies"],
                        check=True, capture_output=True, text=True).stdout
                    return json.loads(out.strip().splitlines()[-1])

                # Latency in blocks, the two clients taking turns, so that both see the same
                # machine (other work on it comes and goes).
                per_block = max(1, args.requests // args.blocks)
                for block in range(args.blocks):
                    turns = ("py", "cpp") if (r + block) % 2 == 0 else ("cpp", "py")
                    for side in turns:
                        if side == "py":
                            py_micros += python_latency(client, queries, args.warmup, per_block)
                        else:
                            cpp_micros += cpp_bench(per_block, args.warmup, 0)["latencies_us"]
                figures["py_p50"], figures["py_p99"] = (percentile(py_micros, 0.5),
                                                       percentile(py_micros, 0.99))
                figures["cpp_p50"], figures["cpp_p99"] = (percentile(cpp_micros, 0.5),
                                                         percentile(cpp_micros, 0.99))
                for side in (("py", "cpp") if r % 2 == 0 else ("cpp", "py")):
                    if side == "py":
                        figures["py_rate"] = python_throughput(client, queries, args.threads,
                                                               args.seconds)
                    else:
                        figures["cpp_rate"] = cpp_bench(1, 0, args.seconds)["per_second"]
                rounds.append(figures)
                print("round %d: %s" % (r + 1, ", ".join("%s %.0f" % kv for kv in
                                                         sorted(figures.items()))), flush=True)
        client.close()
    finally:
        server.stop()
    conversion, kind = conversion_figures(shapeid, repeats)

    med = {k: statistics.median(r[k] for r in rounds) for k in rounds[0]}
    # Each round's ratio, then their median: within a round the clients take turns, so its
    # ratio compares like with like even when the machine's other load changes.
    ratio = {k: statistics.median(r["py_" + k] / r["cpp_" + k] for r in rounds)
             for k in ("p50", "p99", "rate")}
    cpu = next((line.split(":", 1)[1].strip() for line in open("/proc/cpuinfo")
                if line.startswith("model name")), "unknown")
    print()
    print("machine: %d cores (nproc), %s; load average before %s, after %s; python %s, "
          "grpcio %s" % (os.cpu_count(), cpu, " ".join(load_before),
                         " ".join(open("/proc/loadavg").read().split()[:3]),
                         platform.python_version(), __import__("grpc").__version__))
    print("gallery: %d synthetic 1,024-point clouds (dfsd), %d distinct queries; medians of %d "
          "rounds" % (args.gallery_size, args.queries, len(rounds)))
    print()
    print("| Classify, 1,024 points | Python client | C++ client | Python / C++ (median of the rounds' ratios) |")
    print("|---|---|---|---|")
    print("| p50, one thread | %.0f us | %.0f us | %.2f |" % (med["py_p50"], med["cpp_p50"],
                                                              ratio["p50"]))
    print("| p99, one thread | %.0f us | %.0f us | %.2f |" % (med["py_p99"], med["cpp_p99"],
                                                              ratio["p99"]))
    print("| %d threads, one client | %.0f / s | %.0f / s | %.2f |" % (
        args.threads, med["py_rate"], med["cpp_rate"], ratio["rate"]))
    print()
    print_conversion(conversion, kind, repeats)
    print("JSON " + json.dumps(dict(med, ratio_p50=ratio["p50"], ratio_p99=ratio["p99"],
                                    ratio_rate=ratio["rate"], runs=len(rounds), **conversion)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
