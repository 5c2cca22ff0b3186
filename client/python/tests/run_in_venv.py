#!/usr/bin/env python3
"""The packaging check (CTest python_wheel): builds the wheel from the assembled package
(FORESTMAP_PYTHON_DIR) offline, checks that it holds the generated stubs, installs it into a
fresh virtual environment (--system-site-packages: Debian's grpcio, protobuf, numpy, pytest)
and runs the client's tests there against the installed package. Also checks that `import
forestmap` on a Python without grpcio says what to install. Run with Debian's python3."""

import glob
import os
import shutil
import subprocess
import sys
import tempfile
import zipfile

HERE = os.path.dirname(os.path.abspath(__file__))
IN_WHEEL = ["forestmap/__init__.py", "forestmap/_version.py", "forestmap/v1/maps_pb2.py",
            "forestmap/v1/forestmap_service_pb2_grpc.py",
            "forestmap/_googleapis/google/rpc/error_details_pb2.py"]


def run(*command, **kwargs):
    print("+", " ".join(command), flush=True)
    return subprocess.run(command, check=True, **kwargs)


def main() -> int:
    package = os.environ["FORESTMAP_PYTHON_DIR"]
    with tempfile.TemporaryDirectory(prefix="forestmap-wheel-") as tmp:
        source, dist, venv = (os.path.join(tmp, d) for d in ("src", "dist", "venv"))
        shutil.copytree(package, source, ignore=shutil.ignore_patterns(
            "__pycache__", "build", "*.egg-info"))
        run(sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation",
            "--no-index", "-w", dist, source)
        wheel, = glob.glob(os.path.join(dist, "forestmap-*.whl"))
        names = set(zipfile.ZipFile(wheel).namelist())
        missing = [n for n in IN_WHEEL if n not in names]
        if missing:
            print(f"{wheel} lacks {missing}", file=sys.stderr)
            return 1
        run(sys.executable, "-m", "venv", "--system-site-packages", "--without-pip", venv)
        python = os.path.join(venv, "bin", "python")
        run(python, "-m", "pip", "install", "--no-deps", "--no-index", wheel)
        site = run(python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])",
                   capture_output=True, text=True).stdout.strip()
        # A Python without grpcio (nor numpy): -S leaves Debian's packages out.
        bare = subprocess.run([sys.executable, "-S", "-c",
                               f"import sys; sys.path.insert(0, {site!r}); import forestmap"],
                              capture_output=True, text=True)
        if bare.returncode == 0 or "apt install python3-grpcio" not in bare.stderr:
            print(f"import forestmap without grpcio: {bare.stderr}", file=sys.stderr)
            return 1
        env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH",
                                                                "FORESTMAP_PYTHON_DIR")}
        env["FORESTMAP_INSTALLED"] = "1"
        # --import-mode=append: the installed package, not the source tree beside the tests.
        return subprocess.run([python, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                               "--import-mode=append", os.path.dirname(HERE)], cwd=tmp,
                              env=env).returncode


if __name__ == "__main__":
    sys.exit(main())
