"""Builds the shapeid Python package; its stubs are generated from ../../proto at build time
(build_stubs.py). Install, offline, over Debian's python3-grpcio, python3-protobuf and
python3-numpy (docs/python.md):

    python3 -m pip install --no-build-isolation --no-deps client/python
"""

import os
import sys

from setuptools import setup
from setuptools.command.build_py import build_py

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import build_stubs  # noqa: E402 (beside this file)


class BuildPyWithStubs(build_py):
    """build_py, then the generated stubs into the same build directory (never the source
    tree), so that the wheel carries shapeid/v1/."""

    def run(self):
        super().run()
        if not self.dry_run:
            build_stubs.generate(self.build_lib)


setup(
    name="shapeid",
    version="0.1.0",
    description="Client of a shapeid server: 3D object recognition from point clouds",
    packages=["shapeid"],
    python_requires=">=3.10",
    # Debian's python3-grpcio, python3-protobuf and python3-numpy provide these; --no-deps
    # keeps pip from looking for them elsewhere.
    install_requires=["grpcio", "protobuf", "numpy"],
    cmdclass={"build_py": BuildPyWithStubs},
)
