#!/usr/bin/env python3
"""Generates the package's gRPC stubs from proto/shapeid/v1/shapeid.proto with protoc and
grpc_python_plugin (Debian: protobuf-compiler, protobuf-compiler-grpc): the one place that
does, for the pip build (setup.py) and the CMake build of the tests alike.

    build_stubs.py OUT_DIR [--proto-root DIR]

writes OUT_DIR/shapeid/v1/{__init__,shapeid_pb2,shapeid_pb2_grpc}.py. The proto's package
shapeid.v1 is the Python package shapeid.v1, so the generated code's own absolute import
(`from shapeid.v1 import shapeid_pb2`) resolves inside this package, unchanged.
Only the standard library: it runs before anything is installed.
"""

import argparse
import os
import shutil
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
PROTO = os.path.join("shapeid", "v1", "shapeid.proto")
# The repository's proto/: two levels up from client/python. SHAPEID_PROTO_ROOT overrides.
DEFAULT_PROTO_ROOT = os.path.join(HERE, "..", "..", "proto")


def _tool(env, name, package):
    path = os.environ.get(env) or shutil.which(name)
    if not path:
        raise SystemExit("build_stubs: %s not found (Debian package %s; or set %s). "
                         "tools/install-deps.sh installs it." % (name, package, env))
    return path


def generate(out_dir, proto_root=None):
    """Writes the stubs under out_dir; returns their paths."""
    proto_root = os.path.abspath(proto_root or os.environ.get("SHAPEID_PROTO_ROOT")
                                 or DEFAULT_PROTO_ROOT)
    if not os.path.isfile(os.path.join(proto_root, PROTO)):
        raise SystemExit("build_stubs: no %s under %s: build from a checkout of the shapeid "
                         "repository (client/python needs ../../proto), or set "
                         "SHAPEID_PROTO_ROOT" % (PROTO, proto_root))
    protoc = _tool("PROTOC", "protoc", "protobuf-compiler")
    plugin = _tool("GRPC_PYTHON_PLUGIN", "grpc_python_plugin", "protobuf-compiler-grpc")
    target = os.path.join(out_dir, "shapeid", "v1")
    os.makedirs(target, exist_ok=True)
    subprocess.run([protoc, "-I" + proto_root, "--python_out=" + out_dir,
                    "--grpc_python_out=" + out_dir,
                    "--plugin=protoc-gen-grpc_python=" + plugin, PROTO], check=True)
    init = os.path.join(target, "__init__.py")
    with open(init, "w") as f:
        f.write('"""Generated from proto/shapeid/v1/shapeid.proto by build_stubs.py."""\n')
    return [init, os.path.join(target, "shapeid_pb2.py"),
            os.path.join(target, "shapeid_pb2_grpc.py")]


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("out_dir")
    parser.add_argument("--proto-root", help="directory holding shapeid/v1/shapeid.proto")
    args = parser.parse_args()
    generate(args.out_dir, args.proto_root)


if __name__ == "__main__":
    sys.exit(main())
