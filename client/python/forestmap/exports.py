"""ExportTrees streams gathered chunk by chunk: a list of Trees, or a structured numpy array
(TREE_DTYPE) whose memory is that of the array and one chunk (~5,000 trees) of messages."""

from __future__ import annotations

import math
from typing import List, Sequence

import grpc
import numpy as np

from forestmap.answers import Tree, tree_of
from forestmap.errors import ForestMapError
from forestmap.v1 import geometry_pb2, maps_pb2

# export(as_array=True): unknown numbers are NaN.
TREE_DTYPE = np.dtype([("id", np.int64), ("x", np.float64), ("y", np.float64),
                       ("z", np.float64), ("dbh", np.float64), ("confirmed", np.bool_),
                       ("observations", np.int64), ("position_sigma_m", np.float64),
                       ("dbh_sigma_m", np.float64)])


class Gather:
    """Consumes the responses of one ExportTrees call (`reset` before each try)."""

    def __init__(self, as_array: bool, attributes: Sequence[str] = ()):
        self.as_array = as_array
        self.dtype = np.dtype(TREE_DTYPE.descr + [(a, object) for a in attributes])
        self.attributes = tuple(attributes)
        self.reset()

    def reset(self) -> None:
        self.parts: List = []
        self.version = None
        self.boundary: List = []
        self.attribute_columns: List[str] = []

    def add(self, response: maps_pb2.ExportTreesResponse) -> None:
        if self.version is not None and response.map_version != self.version:
            raise ForestMapError("ExportTrees", grpc.StatusCode.INTERNAL,
                                 f"the server mixed map versions {self.version} and "
                                 f"{response.map_version}")
        self.version = response.map_version
        if response.HasField("boundary"):
            self.boundary = polygons_of(response.boundary)
        if response.attribute_columns:
            self.attribute_columns = list(response.attribute_columns)
        if self.as_array:
            self.parts.append(self._array(response.trees))
        else:
            self.parts += [tree_of(t) for t in response.trees]

    def result(self):
        if not self.as_array:
            return self.parts
        return np.concatenate(self.parts) if self.parts else np.empty(0, self.dtype)

    def _array(self, trees) -> np.ndarray:
        n = len(trees)
        out = np.empty(n, self.dtype)
        nan = math.nan
        out["id"] = np.fromiter((t.id for t in trees), np.int64, n)
        out["x"] = np.fromiter((t.x for t in trees), np.float64, n)
        out["y"] = np.fromiter((t.y for t in trees), np.float64, n)
        for name in ("z", "dbh", "position_sigma_m", "dbh_sigma_m"):
            out[name] = np.fromiter((getattr(t, name) if t.HasField(name) else nan
                                     for t in trees), np.float64, n)
        out["confirmed"] = np.fromiter((t.status != maps_pb2.TREE_STATUS_CANDIDATE
                                        for t in trees), np.bool_, n)
        out["observations"] = np.fromiter((t.observations for t in trees), np.int64, n)
        for name in self.attributes:
            out[name] = [t.attributes[name] if name in t.attributes else None for t in trees]
        return out


def box_message(box) -> geometry_pb2.Box2:
    """(min_x, min_y, max_x, max_y), map frame, m."""
    values = [float(v) for v in box]
    if len(values) != 4 or not all(math.isfinite(v) for v in values):
        raise ValueError(f"box: want 4 finite numbers (min_x, min_y, max_x, max_y), got "
                         f"{box!r}")
    return geometry_pb2.Box2(min_x=values[0], min_y=values[1], max_x=values[2], max_y=values[3])


__all__ = ["Gather", "TREE_DTYPE", "Tree", "box_message"]


def boundary_message(polygons) -> geometry_pb2.SurveyBoundary:
    """A survey boundary from polygons, each an outer ring (a sequence of (x, y), m, map frame)
    or an (outer, holes) pair; rings need not repeat their first vertex."""
    def ring(points) -> geometry_pb2.Ring:
        xy = np.asarray(points, dtype=np.float64)
        if xy.ndim != 2 or xy.shape[1] != 2 or len(xy) < 3 or not np.isfinite(xy).all():
            raise ValueError("boundary: a ring is 3 or more finite (x, y) points")
        if (xy[0] == xy[-1]).all():
            xy = xy[:-1]
        return geometry_pb2.Ring(vertices=[geometry_pb2.Vector2(x=x, y=y) for x, y in xy])

    message = geometry_pb2.SurveyBoundary()
    for polygon in polygons:
        is_pair = (isinstance(polygon, tuple) and len(polygon) == 2
                   and np.asarray(polygon[0], dtype=object).ndim == 2)
        outer, holes = polygon if is_pair else (polygon, ())
        message.polygons.add(outer=ring(outer), holes=[ring(h) for h in holes])
    return message


def polygons_of(boundary: geometry_pb2.SurveyBoundary) -> List:
    """[(outer, [holes...])] with every ring an (n, 2) array of x, y (m, map frame)."""
    def ring(r):
        return np.array([(v.x, v.y) for v in r.vertices], dtype=np.float64).reshape(-1, 2)
    return [(ring(p.outer), [ring(h) for h in p.holes]) for p in boundary.polygons]
