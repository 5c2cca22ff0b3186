"""pytest setup for the Python client: finds the assembled package (BUILD/python, made by the
CMake target forestmap_python) and starts a loopback forestmapd on a temporary SQLite database.

    cmake --build build --target forestmapd forestmap forestmap_python
    python3 -m pytest client/python

FORESTMAP_PYTHON_DIR, FORESTMAPD and FORESTMAP_CLI override the paths under ./build.
"""

import os
import socket
import subprocess
import sys
import time

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
BUILD = os.path.join(ROOT, "build")
PYTHON_DIR = os.environ.get("FORESTMAP_PYTHON_DIR", os.path.join(BUILD, "python"))
FORESTMAPD = os.environ.get("FORESTMAPD", os.path.join(BUILD, "server", "forestmapd"))
CLI = os.environ.get("FORESTMAP_CLI", os.path.join(BUILD, "client", "cli", "forestmap"))
DATA = os.environ.get("FORESTMAP_SHARED_DATA", os.path.join(ROOT, "..", "shared", "data"))

if not os.path.exists(os.path.join(PYTHON_DIR, "forestmap", "v1", "maps_pb2.py")):
    raise RuntimeError(f"no generated stubs in {PYTHON_DIR}: build the CMake target "
                       "forestmap_python (or set FORESTMAP_PYTHON_DIR)")
sys.path.insert(0, PYTHON_DIR)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="session")
def server(tmp_path_factory):
    """Address of a forestmapd on loopback, serving a fresh SQLite database."""
    address = f"127.0.0.1:{_free_port()}"
    db = tmp_path_factory.mktemp("forestmapd") / "maps.db"
    process = subprocess.Popen([FORESTMAPD, "--db", str(db), "--listen", address],
                               stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 10
    while subprocess.run([CLI, "--server", address, "health", "--timeout", "0.5"],
                         capture_output=True).returncode != 0:
        if time.monotonic() > deadline or process.poll() is not None:
            process.kill()
            raise RuntimeError(f"forestmapd did not start: {process.stderr.read().decode()}")
        time.sleep(0.1)
    yield address
    process.terminate()
    process.wait(timeout=15)


@pytest.fixture(scope="session")
def data_dir():
    path = os.path.join(DATA, "sequences", "Wild_V01")
    if not os.path.exists(os.path.join(path, "trees.csv")):
        pytest.skip(f"real data missing under {DATA}")
    return path


@pytest.fixture(scope="session")
def cli():
    return CLI
