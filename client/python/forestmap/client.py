"""A thin, typed wrapper over the generated gRPC stubs of forestmap.v1 (see proto/)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Dict, Iterable, Iterator, List, Optional, Sequence, Tuple, Union

import grpc
import numpy as np
from google.rpc import error_details_pb2, status_pb2

from forestmap.v1 import (forestmap_service_pb2_grpc, geometry_pb2, maps_pb2, observations_pb2,
                          relocalization_pb2, tracking_pb2)

ArrayLike = Union[np.ndarray, Sequence[Sequence[float]]]


@dataclass
class FieldViolation:
    """One bad field of a request (google.rpc.BadRequest): its path and what is wrong."""
    field: str        # e.g. "trees[12].position.x"
    description: str


def _violations(error: grpc.RpcError) -> List[FieldViolation]:
    """The google.rpc.BadRequest field violations in the status details of `error`, if any."""
    metadata = error.trailing_metadata() if hasattr(error, "trailing_metadata") else None
    out = []
    for key, value in metadata or ():
        if key != "grpc-status-details-bin":
            continue
        status = status_pb2.Status()
        status.ParseFromString(value)
        for detail in status.details:
            bad_request = error_details_pb2.BadRequest()
            if detail.Unpack(bad_request):
                out += [FieldViolation(v.field, v.description)
                        for v in bad_request.field_violations]
    return out


class ForestMapError(Exception):
    """Every failed call: `code` is the grpc.StatusCode, `details` the server's message, and
    `violations` the bad fields the server named in its error details (INVALID_ARGUMENT)."""

    def __init__(self, call: str, code: grpc.StatusCode, details: str,
                 violations: Sequence[FieldViolation] = ()):
        fields = ", ".join(v.field for v in violations)
        shown = f" ({'fields' if len(violations) > 1 else 'field'}: {fields})" if fields else ""
        super().__init__(f"{call}: {code.name}: {details}{shown}")
        self.call = call
        self.code = code
        self.details = details
        self.violations = list(violations)

    @classmethod
    def of(cls, call: str, error: grpc.RpcError) -> "ForestMapError":
        return cls(call, error.code(), error.details(), _violations(error))


def _label(enum, value: int) -> str:
    """An enum value's name without its enum's prefix: "LOCALIZED" for STATUS_LOCALIZED."""
    prefix = enum.Name(0)[:-len("UNSPECIFIED")]  # value 0 is <PREFIX>_UNSPECIFIED (buf lint)
    name = enum.Name(value)
    return name[len(prefix):] if name.startswith(prefix) else name


@dataclass
class Tree:
    """A map tree (m, map frame). Unknown z / dbh are None."""
    x: float
    y: float
    z: Optional[float] = None
    dbh: Optional[float] = None
    id: Optional[int] = None
    # Survey columns; None is an unknown value (NA): the column is kept, as a null field.
    attributes: Dict[str, Optional[str]] = field(default_factory=dict)
    confirmed: bool = True    # False: a candidate of a shared map
    observations: int = 0     # observations merged into the tree


@dataclass
class MapInfo:
    name: str
    description: str
    crs: str
    version: int
    tree_count: int
    extent: Optional[Tuple[float, float, float, float]]  # min_x, min_y, max_x, max_y (m)


@dataclass
class Answer:
    """A relocalization: status "LOCALIZED", "AMBIGUOUS" or "NOT_FOUND"; the pose when localized."""
    status: str
    map_from_sensor: Optional[np.ndarray]  # 4 x 4 homogeneous transform, when LOCALIZED
    x: Optional[float]
    y: Optional[float]
    z: Optional[float]
    quaternion: Optional[Tuple[float, float, float, float]]  # qx, qy, qz, qw
    yaw_deg: Optional[float]
    inliers: int
    rmse_m: float
    confidence: float
    server_ms: float
    map_version: int
    detail: str
    # Why not localized ("NOT_SIGNIFICANT", "OUTSIDE_COVERAGE", ...; "NONE" when localized).
    reason: str
    # Under the answer's pose: the share of the nearby trees inside what the map covers, and
    # how many they are (the only evidence for or against the pose).
    coverage_share: float
    trees_in_coverage: int

    @property
    def localized(self) -> bool:
        return self.status == "LOCALIZED"


@dataclass
class TrackAnswer:
    frame_id: int
    state: str   # "TRACKING", "RECOVERED" or "LOST"
    method: str  # "LOCAL", "PRIOR" or "GLOBAL"
    frames_lost: int
    answer: Answer


@dataclass
class ObserveResult:
    map_version: int
    merged: int   # frames merged
    skipped: int  # frames not merged (see details)
    details: List[str]


def _rows(trees: ArrayLike, what: str) -> np.ndarray:
    array = np.asarray(trees, dtype=np.float64)
    if array.ndim != 2 or array.shape[1] < 2:
        raise ValueError(f"{what}: want an N x k array (k >= 2: x, y[, z, dbh]), got shape "
                         f"{array.shape}")
    return array


def _detected(trees: ArrayLike) -> List[relocalization_pb2.DetectedTree]:
    """Rows x, y, z[, dbh[, axis_x, axis_y, axis_z[, score]]] (sensor frame, m); NaN = unknown."""
    array = _rows(trees, "trees")
    out = []
    for row in array:
        tree = relocalization_pb2.DetectedTree()
        tree.position.x, tree.position.y = float(row[0]), float(row[1])
        tree.position.z = float(row[2]) if array.shape[1] > 2 else 0.0
        if array.shape[1] > 3 and not math.isnan(row[3]):
            tree.dbh = float(row[3])
        if array.shape[1] > 6:
            axis = row[4:7]
            if not np.isnan(axis).any() and float(np.dot(axis, axis)) > 0.25:
                tree.axis.x, tree.axis.y, tree.axis.z = (float(v) for v in axis)
        if array.shape[1] > 7 and not math.isnan(row[7]):
            tree.score = float(row[7])
        out.append(tree)
    return out


def _map_trees(trees: Union[ArrayLike, Iterable[Tree]]) -> List[maps_pb2.Tree]:
    if isinstance(trees, np.ndarray) or (isinstance(trees, (list, tuple)) and trees
                                         and not isinstance(trees[0], Tree)):
        array = _rows(trees, "trees")
        trees = [Tree(x=r[0], y=r[1], z=r[2] if array.shape[1] > 2 else None,
                      dbh=r[3] if array.shape[1] > 3 else None) for r in array]
    out = []
    for tree in trees:
        message = maps_pb2.Tree(
            x=float(tree.x), y=float(tree.y),
            attributes={k: v for k, v in tree.attributes.items() if v is not None},
            null_attributes=sorted(k for k, v in tree.attributes.items() if v is None))
        if tree.id is not None:
            message.id = int(tree.id)
        if tree.z is not None and not math.isnan(tree.z):
            message.z = float(tree.z)
        if tree.dbh is not None and not math.isnan(tree.dbh):
            message.dbh = float(tree.dbh)
        out.append(message)
    return out


def _yaw_deg(q: geometry_pb2.Quaternion) -> float:
    """Yaw of the pose, computed exactly as the C++ CLI does (Eigen, SSE2 reduction order)."""
    norm = math.sqrt((q.x * q.x + q.z * q.z) + (q.y * q.y + q.w * q.w))
    x, y, z, w = q.x / norm, q.y / norm, q.z / norm, q.w / norm
    r10 = (2 * y) * x + (2 * z) * w
    r00 = 1 - ((2 * y) * y + (2 * z) * z)
    return math.atan2(r10, r00) * 180.0 / math.pi


def _matrix(pose: geometry_pb2.Pose) -> np.ndarray:
    q, t = pose.rotation, pose.translation
    x, y, z, w = q.x, q.y, q.z, q.w
    matrix = np.eye(4)
    matrix[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                      [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                      [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
    matrix[:3, 3] = [t.x, t.y, t.z]
    return matrix


def _answer(response: relocalization_pb2.RelocalizeResponse) -> Answer:
    status = _label(relocalization_pb2.RelocalizeResponse.Status, response.status)
    localized = status == "LOCALIZED"
    pose = response.map_from_sensor
    q = pose.rotation
    return Answer(status=status,
                  map_from_sensor=_matrix(pose) if localized else None,
                  x=pose.translation.x if localized else None,
                  y=pose.translation.y if localized else None,
                  z=pose.translation.z if localized else None,
                  quaternion=(q.x, q.y, q.z, q.w) if localized else None,
                  yaw_deg=_yaw_deg(q) if localized else None,
                  inliers=response.inliers, rmse_m=response.rmse_m,
                  confidence=response.confidence, server_ms=response.server_time_ms,
                  map_version=response.map_version, detail=response.detail,
                  reason=_label(relocalization_pb2.RelocalizeResponse.Reason, response.reason),
                  coverage_share=response.coverage_share,
                  trees_in_coverage=response.trees_in_coverage)


def _map_info(message: maps_pb2.Map) -> MapInfo:
    extent = None
    if message.HasField("extent"):
        e = message.extent
        extent = (e.min_x, e.min_y, e.max_x, e.max_y)
    return MapInfo(name=message.name, description=message.description, crs=message.crs,
                   version=message.version, tree_count=message.tree_count, extent=extent)


def _pose(matrix: np.ndarray) -> geometry_pb2.Pose:
    """4 x 4 rigid transform -> Pose (rotation as a unit quaternion)."""
    m = np.asarray(matrix, dtype=np.float64)
    w = math.sqrt(max(0.0, 1 + m[0, 0] + m[1, 1] + m[2, 2])) / 2
    x = math.copysign(math.sqrt(max(0.0, 1 + m[0, 0] - m[1, 1] - m[2, 2])) / 2, m[2, 1] - m[1, 2])
    y = math.copysign(math.sqrt(max(0.0, 1 - m[0, 0] + m[1, 1] - m[2, 2])) / 2, m[0, 2] - m[2, 0])
    z = math.copysign(math.sqrt(max(0.0, 1 - m[0, 0] - m[1, 1] + m[2, 2])) / 2, m[1, 0] - m[0, 1])
    return geometry_pb2.Pose(translation=geometry_pb2.Vector3(x=m[0, 3], y=m[1, 3], z=m[2, 3]),
                             rotation=geometry_pb2.Quaternion(x=x, y=y, z=z, w=w))


class Client:
    """One forestmapd (or several replicas: "a:1,b:2"; calls go to the first that answers).

    Every method raises ForestMapError (carrying the gRPC status) when the call fails.
    """

    def __init__(self, address: str, timeout: float = 30.0):
        self.addresses = [a for a in address.split(",") if a]
        if not self.addresses:
            raise ValueError(f"no server address in {address!r}")
        self.timeout = timeout
        self._current = 0
        self.retries = 0  # idempotent calls retried on another replica
        self._connect()

    def _connect(self) -> None:
        self._channel = grpc.insecure_channel(self.addresses[self._current], options=[
            ("grpc.max_receive_message_length", 64 << 20)])
        self._stub = forestmap_service_pb2_grpc.ForestMapStub(self._channel)

    def close(self) -> None:
        self._channel.close()

    def __enter__(self) -> "Client":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _call(self, name: str, request, idempotent: bool = False):
        for attempt in range(len(self.addresses)):
            try:
                return getattr(self._stub, name)(request, timeout=self.timeout)
            except grpc.RpcError as error:
                unreachable = error.code() == grpc.StatusCode.UNAVAILABLE
                if not (idempotent and unreachable) or attempt + 1 == len(self.addresses):
                    raise ForestMapError.of(name, error) from None
            self._channel.close()
            self._current = (self._current + 1) % len(self.addresses)
            self.retries += 1
            self._connect()
        raise AssertionError("unreachable")

    # ---- maps ----

    def create_map(self, name: str, trees: Union[ArrayLike, Iterable[Tree], None] = None,
                   description: str = "", crs: str = "") -> MapInfo:
        """Creates the map and, when given, uploads its trees (N x 2..4 array or Trees)."""
        info = _map_info(self._call("CreateMap", maps_pb2.CreateMapRequest(
            name=name, description=description, crs=crs)))
        if trees is not None and len(trees) > 0:
            info = self.upload(name, trees)
        return info

    def upload(self, name: str, trees: Union[ArrayLike, Iterable[Tree]],
               replace: bool = False, chunk: int = 5000) -> MapInfo:
        messages = _map_trees(trees)

        def requests():
            yield maps_pb2.UploadTreesRequest(
                header=maps_pb2.UploadTreesHeader(name=name, replace=replace))
            for begin in range(0, len(messages), chunk):
                yield maps_pb2.UploadTreesRequest(
                    chunk=maps_pb2.TreeChunk(trees=messages[begin:begin + chunk]))
        try:
            response = self._stub.UploadTrees(requests(), timeout=self.timeout)
        except grpc.RpcError as error:
            raise ForestMapError.of("UploadTrees", error) from None
        return _map_info(response.map)

    def list_maps(self, page_size: int = 0) -> List[MapInfo]:
        """Every map the caller may read, by name (page by page; 0: the server's page size)."""
        maps, token = [], ""
        while True:
            response = self._call("ListMaps", maps_pb2.ListMapsRequest(
                page_size=page_size, page_token=token), idempotent=True)
            maps += [_map_info(m) for m in response.maps]
            token = response.next_page_token
            if not token:
                return maps

    def get_map(self, name: str) -> MapInfo:
        return _map_info(self._call("GetMap", maps_pb2.GetMapRequest(name=name), idempotent=True))

    def delete_map(self, name: str) -> None:
        self._call("DeleteMap", maps_pb2.DeleteMapRequest(name=name))

    def export(self, name: str, version: int = 0) -> List[Tree]:
        """All trees of the map (or of an older version), by id."""
        request = maps_pb2.ExportTreesRequest(name=name, version=version)
        for attempt in range(len(self.addresses)):
            try:
                trees = []
                for chunk in self._stub.ExportTrees(request, timeout=self.timeout):
                    for t in chunk.trees:
                        trees.append(Tree(
                            x=t.x, y=t.y, z=t.z if t.HasField("z") else None,
                            dbh=t.dbh if t.HasField("dbh") else None, id=t.id,
                            attributes={**dict(t.attributes),
                                        **{k: None for k in t.null_attributes}},
                            confirmed=t.status != maps_pb2.TREE_STATUS_CANDIDATE,
                            observations=t.observations))
                return trees
            except grpc.RpcError as error:
                if error.code() != grpc.StatusCode.UNAVAILABLE or attempt + 1 == len(
                        self.addresses):
                    raise ForestMapError.of("ExportTrees", error) from None
            self._current = (self._current + 1) % len(self.addresses)
            self.retries += 1
            self._connect()
        raise AssertionError("unreachable")

    # ---- relocalization ----

    def relocalize(self, name: str, trees: ArrayLike,
                   prior: Optional[Tuple[float, float, float]] = None,
                   gravity: Optional[Sequence[float]] = None) -> Answer:
        """Pose of the sensor in the map from the trees it detected.

        trees: N x 3..8 array, rows x, y, z[, dbh[, axis_x, axis_y, axis_z[, score]]] in the
        sensor frame (m; NaN = unknown). prior: (x, y, radius_m): the sensor is within radius_m
        of (x, y) in the map frame (a 4-tuple (x, y, yaw_deg, radius_m) of older versions is
        read too: the server never used the yaw). gravity: direction of gravity in the sensor
        frame.
        """
        request = relocalization_pb2.RelocalizeRequest(name=name, trees=_detected(trees))
        if prior is not None:
            x, y, radius = (prior[0], prior[1], prior[-1]) if len(prior) == 4 else prior
            request.prior.x, request.prior.y, request.prior.radius_m = x, y, radius
        if gravity is not None:
            request.gravity.x, request.gravity.y, request.gravity.z = (float(g) for g in gravity)
        return _answer(self._call("Relocalize", request, idempotent=True))

    def track(self, name: str, frames: Iterable[Union[ArrayLike, Tuple[int, ArrayLike]]]
              ) -> Iterator[TrackAnswer]:
        """A tracking session: yields one answer per frame (trees, or (frame_id, trees))."""

        def requests():
            yield tracking_pb2.TrackRequest(header=tracking_pb2.TrackHeader(name=name))
            for number, frame in enumerate(frames):
                frame_id, trees = frame if isinstance(frame, tuple) else (number, frame)
                yield tracking_pb2.TrackRequest(frame=tracking_pb2.TrackFrame(
                    trees=_detected(trees), frame_id=frame_id))
        try:
            for response in self._stub.Track(requests()):
                yield TrackAnswer(
                    frame_id=response.frame_id,
                    state=_label(tracking_pb2.TrackResponse.State, response.state),
                    method=_label(tracking_pb2.TrackResponse.Method, response.method),
                    frames_lost=response.frames_lost, answer=_answer(response.result))
        except grpc.RpcError as error:
            raise ForestMapError.of("Track", error) from None

    # ---- shared maps ----

    def observe(self, name: str, frames: Iterable[Tuple[int, ArrayLike, Optional[np.ndarray]]],
                source: str = "forestmap-python") -> ObserveResult:
        """Merges frames (frame_id, trees in the sensor frame, 4 x 4 map_from_sensor or None:
        the server relocalizes the frame) into the map as one new version."""
        request = observations_pb2.ObserveRequest(name=name, source=source)
        for frame_id, trees, map_from_sensor in frames:
            frame = request.frames.add(frame_id=frame_id, trees=_detected(trees))
            if map_from_sensor is not None:
                frame.map_from_sensor.CopyFrom(_pose(map_from_sensor))
        response = self._call("Observe", request)
        merged = sum(f.status == observations_pb2.FrameResult.STATUS_MERGED
                     for f in response.frames)
        details = [f"frame {f.frame_id}: {f.detail}" for f in response.frames if f.detail]
        return ObserveResult(map_version=response.map_version, merged=merged,
                             skipped=len(response.frames) - merged, details=details)
