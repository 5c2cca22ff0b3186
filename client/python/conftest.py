"""pytest setup for the Python client: finds the assembled package (BUILD/python, made by the
CMake target forestmap_python) and starts a loopback forestmapd on a temporary SQLite database.

    cmake --build build --target forestmapd forestmap forestmap_python
    python3 -m pytest client/python

FORESTMAP_PYTHON_DIR, FORESTMAPD and FORESTMAP_CLI override the paths under ./build. With
FORESTMAP_INSTALLED=1 the tests use the `forestmap` package the interpreter has installed (the
wheel in a virtual environment, tests/run_in_venv.py) and check that they do.
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

if os.environ.get("FORESTMAP_INSTALLED") == "1":
    import forestmap  # noqa: E402

    if not forestmap.__file__.startswith(sys.prefix) or sys.prefix == sys.base_prefix:
        raise RuntimeError(f"FORESTMAP_INSTALLED=1, but forestmap comes from {forestmap.__file__},"
                           f" not from the virtual environment {sys.prefix}")
else:
    if not os.path.exists(os.path.join(PYTHON_DIR, "forestmap", "v1", "maps_pb2.py")):
        raise RuntimeError(f"no generated stubs in {PYTHON_DIR}: build the CMake target "
                           "forestmap_python (or set FORESTMAP_PYTHON_DIR)")
    sys.path.insert(0, PYTHON_DIR)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _listening(port: int) -> bool:
    with socket.socket() as s:
        return s.connect_ex(("127.0.0.1", port)) == 0


def start_forestmapd(db, *args):
    """A forestmapd on a free loopback port serving `db` (more flags in args): (process,
    address), once it accepts connections."""
    port = _free_port()
    address = f"127.0.0.1:{port}"
    process = subprocess.Popen([FORESTMAPD, "--db", str(db), "--listen", address, *args],
                               stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 10
    while not _listening(port):
        if time.monotonic() > deadline or process.poll() is not None:
            process.kill()
            raise RuntimeError(f"forestmapd did not start: {process.stderr.read().decode()}")
        time.sleep(0.1)
    return process, address


def stop(process):
    process.terminate()
    process.wait(timeout=15)


@pytest.fixture(scope="session")
def server(tmp_path_factory):
    """Address of a forestmapd on loopback, serving a fresh SQLite database."""
    process, address = start_forestmapd(tmp_path_factory.mktemp("forestmapd") / "maps.db")
    yield address
    stop(process)


@pytest.fixture(scope="session")
def data_dir():
    path = os.path.join(DATA, "sequences", "Wild_V01")
    if not os.path.exists(os.path.join(path, "trees.csv")):
        pytest.skip(f"real data missing under {DATA}")
    return path


@pytest.fixture(scope="session")
def cli():
    return CLI


@pytest.fixture(scope="session")
def data_root():
    if not os.path.exists(os.path.join(DATA, "sequences", "Wild_V02", "trees.csv")):
        pytest.skip(f"real data missing under {DATA}")
    return DATA
