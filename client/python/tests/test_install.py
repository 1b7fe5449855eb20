"""The install as a user does it: the README's command in a fresh venv over Debian's packages,
from a copy of the repository's client/python and proto/ only, then the README's example as
written (its address replaced by a test server's) and the stubs imported from the install."""

import os
import re
import shutil
import subprocess
import sys

from conftest import ServerProcess

SOURCE = os.environ.get("SHAPEID_SOURCE_DIR", "")
INSTALL = "python3 -m pip install --no-build-isolation --no-deps --no-index client/python"


def readme_section():
    with open(os.path.join(SOURCE, "README.md")) as f:
        text = f.read()
    start = text.index("## Use the Python client")
    return text[start:text.index("\n## ", start + 1)]


def test_readme_install_and_example_work_as_written(tmp_path):
    section = readme_section()
    assert INSTALL in section, "the README's install command changed: change this test too"
    example = re.search(r"```python\n(.*?)```", section, re.S).group(1)

    clone = tmp_path / "clone"
    shutil.copytree(os.path.join(SOURCE, "proto"), clone / "proto")
    shutil.copytree(os.path.join(SOURCE, "client", "python"), clone / "client" / "python",
                    ignore=shutil.ignore_patterns("build", "*.egg-info", "__pycache__"))
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--system-site-packages", str(venv)],
                   check=True)
    try:
        check_venv(venv, clone, example, tmp_path)
    finally:
        # Now, with rm: pytest would delete the venv's 1,700 files file by file in a later
        # run's clean-up of old temporary directories (seconds on this machine's disk).
        subprocess.run(["rm", "-rf", str(venv), str(clone)], check=True)


def check_venv(venv, clone, example, tmp_path):
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTHON")}
    env["PATH"] = "%s:%s" % (venv / "bin", env.get("PATH", ""))
    installed = subprocess.run(INSTALL.split(), cwd=clone, env=env, capture_output=True,
                               text=True)
    assert installed.returncode == 0, installed.stdout + installed.stderr

    server = ServerProcess()
    try:
        script = tmp_path / "example.py"
        script.write_text(example.replace("127.0.0.1:50051", server.address))
        run = subprocess.run(["python3", str(script)], cwd=tmp_path, env=env,
                             capture_output=True, text=True, timeout=60)
        assert run.returncode == 0, run.stderr
        assert run.stdout == "ball\n"
    finally:
        assert server.stop() == 0
    where = subprocess.run(
        ["python3", "-c", "import shapeid, shapeid.v1.shapeid_pb2_grpc as g; "
                          "print(shapeid.__file__); print(g.__file__)"],
        cwd=tmp_path, env=env, capture_output=True, text=True, check=True).stdout.split()
    assert all(path.startswith(str(venv)) for path in where), where
