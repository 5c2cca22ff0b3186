"""Python client of forestmapd, the ForestMap server (maps of trees, relocalization).

    import forestmap
    client = forestmap.Client("127.0.0.1:50051", token=...)     # or FORESTMAP_SERVER/_TOKEN
    client.create_map("plot", "map.csv")                       # tables by column name
    trees = forestmap.detect("scan.pcd")                       # `forestmap detect`, as an array
    answer = client.relocalize("plot", trees)
    if answer.localized:
        print(answer.map_from_sensor, answer.covariance)       # 4 x 4 and 6 x 6 numpy arrays

Needs grpcio (>= 1.51), protobuf (>= 3.21) and numpy (>= 1.24); Debian 12: python3-grpcio,
python3-protobuf, python3-numpy. The generated gRPC stubs are part of the package
(forestmap.v1).
"""

import importlib

from forestmap._version import __version__


def _require() -> None:
    missing = []
    for module, package in (("grpc", "grpcio>=1.51"), ("google.protobuf", "protobuf>=3.21"),
                            ("numpy", "numpy>=1.24")):
        try:
            importlib.import_module(module)
        except ImportError:
            missing.append(package)
    if missing:
        raise ImportError(
            f"forestmap {__version__} needs {', '.join(missing)}, which this Python "
            "cannot import. On Debian 12: apt install python3-grpcio python3-protobuf "
            "python3-numpy (then, in a virtual environment, create it with "
            "--system-site-packages); elsewhere: pip install " + " ".join(missing))


_require()

# pylint: disable=wrong-import-position
from forestmap import ros  # noqa: E402
from forestmap.aio import AsyncClient  # noqa: E402
from forestmap.answers import (MATCH_DTYPE, Answer, Geodetic, MapInfo, ObserveResult,  # noqa
                               TrackAnswer, Tree)
from forestmap.api import VersionInfo  # noqa: E402
from forestmap.client import Client  # noqa: E402
from forestmap.detect import detect  # noqa: E402
from forestmap.errors import FieldViolation, ForestMapError  # noqa: E402
from forestmap.exports import TREE_DTYPE  # noqa: E402
from forestmap.inputs import read_csv  # noqa: E402
from forestmap.tracking import Frame  # noqa: E402

__all__ = ["Answer", "AsyncClient", "Client", "FieldViolation", "ForestMapError", "Frame",
           "Geodetic", "MATCH_DTYPE", "MapInfo", "ObserveResult", "TREE_DTYPE", "TrackAnswer",
           "Tree", "VersionInfo", "__version__", "detect", "read_csv", "ros"]
