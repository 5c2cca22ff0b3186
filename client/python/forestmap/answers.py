"""What the server answers, as Python values (dataclasses, numpy arrays), decoded in one place
for the blocking and the asyncio client."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Dict, Iterable, Iterator, List, Optional, Tuple

import numpy as np

from forestmap import geometry
from forestmap.v1 import maps_pb2, observations_pb2, relocalization_pb2, tracking_pb2

# Answer.matches: one row per matched query tree.
MATCH_DTYPE = np.dtype([("query_index", np.int32), ("map_tree_id", np.int64),
                        ("distance_m", np.float64)])


def label(enum, value: int) -> str:
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
    last_seen_unix_ms: Optional[int] = None  # when a drone last saw it (None: not since the survey)


def tree_message(tree: Tree) -> maps_pb2.Tree:
    message = maps_pb2.Tree(
        x=float(tree.x), y=float(tree.y),
        attributes={k: v for k, v in tree.attributes.items() if v is not None},
        null_attributes=sorted(k for k, v in tree.attributes.items() if v is None))
    if tree.id is not None:
        message.id = int(tree.id)
    if tree.z is not None and tree.z == tree.z:
        message.z = float(tree.z)
    if tree.dbh is not None and tree.dbh == tree.dbh:
        message.dbh = float(tree.dbh)
    return message


def tree_of(t: maps_pb2.Tree) -> Tree:
    return Tree(x=t.x, y=t.y, z=t.z if t.HasField("z") else None,
                dbh=t.dbh if t.HasField("dbh") else None, id=t.id,
                attributes={**dict(t.attributes), **{k: None for k in t.null_attributes}},
                confirmed=t.status != maps_pb2.TREE_STATUS_CANDIDATE,
                observations=t.observations,
                last_seen_unix_ms=(t.last_seen_unix_ms if t.HasField("last_seen_unix_ms")
                                   else None))


@dataclass
class MapInfo:
    name: str
    description: str
    crs: str
    version: int
    tree_count: int
    extent: Optional[Tuple[float, float, float, float]]  # min_x, min_y, max_x, max_y (m)
    has_boundary: bool = False  # a survey boundary (Client.boundary), else coverage is derived


def map_info(message: maps_pb2.Map) -> MapInfo:
    extent = None
    if message.HasField("extent"):
        e = message.extent
        extent = (e.min_x, e.min_y, e.max_x, e.max_y)
    return MapInfo(name=message.name, description=message.description, crs=message.crs,
                   version=message.version, tree_count=message.tree_count, extent=extent,
                   has_boundary=message.has_boundary)


@dataclass
class Geodetic:
    """The sensor's pose on the WGS84 ellipsoid (maps with a CRS), via PROJ on the server."""
    latitude_deg: float
    longitude_deg: float            # east positive
    ellipsoidal_height_m: float
    true_heading_deg: float         # sensor x axis, clockwise from true north, [0, 360)
    grid_convergence_deg: float     # true heading minus grid heading
    transformation_accuracy_m: float  # PROJ's stated accuracy; -1: none stated
    ballpark: bool                  # no datum transformation known: may be off by metres


@dataclass
class Answer:
    """A relocalization: status "LOCALIZED", "AMBIGUOUS" or "NOT_FOUND"; the pose when localized.

    Units and frames are the API's (proto/forestmap/v1/geometry.proto): m, map frame, poses
    map_from_sensor as 4 x 4 arrays."""
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
    # When LOCALIZED: 6 x 6 covariance of (x, y, z, roll, pitch, yaw), m and rad about the map's
    # fixed axes (ROS PoseWithCovariance order); an unobserved component has variance 1e6.
    covariance: Optional[np.ndarray] = None
    # Matched trees: structured array (query_index, map_tree_id, distance_m), MATCH_DTYPE.
    matches: np.ndarray = field(default_factory=lambda: np.empty(0, MATCH_DTYPE))
    # When AMBIGUOUS: the best distinct rival pose, 4 x 4.
    rival_map_from_sensor: Optional[np.ndarray] = None
    stamp_ns: Optional[int] = None      # the request's client stamp, echoed
    geodetic: Optional[Geodetic] = None  # when LOCALIZED on a map with a CRS
    # The map the answer refers to (over a set of maps: the one localized in), and when two maps
    # of a set disagree (AMBIGUOUS), the map of rival_map_from_sensor.
    map_name: str = ""
    rival_map_name: str = ""
    # The map of each match's map_tree_id: map_name, or over maps sharing a CRS another map of
    # the set (a view across a plot boundary).
    match_maps: List[str] = field(default_factory=list)

    @property
    def localized(self) -> bool:
        return self.status == "LOCALIZED"

    @property
    def matched_tree_ids(self) -> np.ndarray:
        """Ids of the map trees matched to the query trees (int64)."""
        return self.matches["map_tree_id"]


def answer(response: relocalization_pb2.RelocalizeResponse) -> Answer:
    status = label(relocalization_pb2.RelocalizeResponse.Status, response.status)
    localized = status == "LOCALIZED"
    pose = response.map_from_sensor
    q = pose.rotation
    matches = np.array([(m.query_index, m.map_tree_id, m.distance_m) for m in response.matches],
                       dtype=MATCH_DTYPE)
    g = response.geodetic
    return Answer(
        status=status,
        map_from_sensor=geometry.from_pose(pose) if localized else None,
        x=pose.translation.x if localized else None,
        y=pose.translation.y if localized else None,
        z=pose.translation.z if localized else None,
        quaternion=(q.x, q.y, q.z, q.w) if localized else None,
        yaw_deg=geometry.yaw_deg(q) if localized else None,
        inliers=response.inliers, rmse_m=response.rmse_m, confidence=response.confidence,
        server_ms=response.server_time_ms, map_version=response.map_version,
        detail=response.detail,
        reason=label(relocalization_pb2.RelocalizeResponse.Reason, response.reason),
        coverage_share=response.coverage_share, trees_in_coverage=response.trees_in_coverage,
        covariance=(np.array(response.covariance, dtype=np.float64).reshape(6, 6)
                    if len(response.covariance) == 36 else None),
        matches=matches,
        rival_map_from_sensor=(geometry.from_pose(response.rival_map_from_sensor)
                               if response.HasField("rival_map_from_sensor") else None),
        stamp_ns=response.client_stamp_ns if response.HasField("client_stamp_ns") else None,
        geodetic=Geodetic(g.latitude_deg, g.longitude_deg, g.ellipsoidal_height_m,
                          g.true_heading_deg, g.grid_convergence_deg,
                          g.transformation_accuracy_m, g.ballpark_transformation)
        if response.HasField("geodetic") else None,
        map_name=response.map_name, rival_map_name=response.rival_map_name,
        match_maps=[m.map_name or response.map_name for m in response.matches])


@dataclass
class TrackAnswer:
    frame_id: int
    state: str   # "TRACKING", "RECOVERED" or "LOST"
    method: str  # "LOCAL", "PRIOR" or "GLOBAL"
    frames_lost: int
    answer: Answer


def track_answer(response: tracking_pb2.TrackResponse) -> TrackAnswer:
    return TrackAnswer(frame_id=response.frame_id,
                       state=label(tracking_pb2.TrackResponse.State, response.state),
                       method=label(tracking_pb2.TrackResponse.Method, response.method),
                       frames_lost=response.frames_lost, answer=answer(response.result))


@dataclass
class ObserveResult:
    map_version: int
    merged: int   # frames merged
    skipped: int  # frames not merged (see details)
    details: List[str]
    missed: int = 0   # map trees the frames should have seen and did not
    removed: int = 0  # trees their evidence showed gone (removed from the map)


def observe_result(response: observations_pb2.ObserveResponse) -> ObserveResult:
    merged = sum(f.status == observations_pb2.FrameResult.STATUS_MERGED
                 for f in response.frames)
    details = [f"frame {f.frame_id}: {f.detail}" for f in response.frames if f.detail]
    return ObserveResult(map_version=response.map_version, merged=merged,
                         skipped=len(response.frames) - merged, details=details,
                         missed=sum(f.trees_missed for f in response.frames),
                         removed=sum(f.trees_removed for f in response.frames))


def tree_chunks(trees: Iterable[Tree], chunk: int) -> Iterator[List[maps_pb2.Tree]]:
    batch = []
    for tree in trees:
        batch.append(tree_message(tree))
        if len(batch) == chunk:
            yield batch
            batch = []
    if batch:
        yield batch
