"""The methods of Client and AsyncClient, written once.

Each method is a plan: a generator that yields the calls it needs (connection.Unary, Upload,
Export) and receives their responses. Client runs a plan to its end with blocking calls;
AsyncClient's methods return a coroutine that runs the same plan with grpc.aio. So request
building, checks and answer decoding exist once.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Iterable, List, Optional, Sequence, Tuple

from forestmap import answers, geometry, inputs
from forestmap.answers import MapInfo, Tree
from forestmap.connection import READ, WRITE, Export, Unary, Upload
from forestmap.exports import Gather, boundary_message, box_message
from forestmap.v1 import maps_pb2, observations_pb2, relocalization_pb2


@dataclass
class VersionInfo:
    """One entry of a map's history (ListVersions)."""
    version: int
    created_unix_ms: int
    kind: str     # "CREATE", "UPLOAD", "REPLACE", "OBSERVE", "RESTORE", ...
    source: str   # OBSERVE / REMOVE_SOURCE: the source id
    tree_count: int
    confirmed_count: int


def _is_tree_list(trees) -> bool:
    return isinstance(trees, (list, tuple)) and len(trees) > 0 and isinstance(trees[0], Tree)


def _NO_CHUNKS():  # an upload of a header alone (a boundary without trees)
    return iter(())


def _chunks(trees, columns, chunk, header):
    """The upload's chunks; a named table's attribute columns, in its order, into `header`."""
    if not isinstance(chunk, int) or chunk < 1:
        raise ValueError(f"chunk must be >= 1 trees, got {chunk!r}")
    if _is_tree_list(trees):
        return lambda: answers.tree_chunks(trees, chunk)
    chunks = inputs.map_tree_chunks(trees, columns, chunk)
    header.attribute_columns.extend(chunks.attribute_columns)
    return chunks


def _pages(rpc: str, request, items: str):
    """Plan: every page of a paged list (AIP-158), each page from any replica."""
    out = []
    while True:
        response = yield Unary(rpc, request, READ)
        out += list(getattr(response, items))
        if not response.next_page_token:
            return out
        request.page_token = response.next_page_token


class Methods:
    """The API of the ForestMap service (proto/forestmap/v1). Units and frames are the API's:
    metres, map frame, poses `map_from_sensor` as 4 x 4 numpy arrays. Tree tables are read by
    column NAME (see forestmap.inputs): a structured array, a mapping of name -> array, a CSV
    path, or a plain array with `columns=`."""

    def _run(self, plan):  # Client: the result; AsyncClient: a coroutine
        raise NotImplementedError

    # ---- maps ----

    def create_map(self, name: str, trees=None, description: str = "", crs: str = "", *,
                   columns: Optional[Sequence[str]] = None, chunk: int = 5000,
                   boundary=None) -> MapInfo:
        """Creates the map with its trees in ONE transaction (UploadTrees with create_map): a
        bad tree (checked here, then by the server) leaves no map behind. boundary: the survey's
        polygons (see upload)."""
        return self._run(self._create_map(name, trees, description, crs, columns, chunk,
                                          boundary))

    def _create_map(self, name, trees, description, crs, columns, chunk, boundary):
        empty = trees is None or (isinstance(trees, (list, tuple)) and len(trees) == 0)
        if empty and boundary is None:
            return answers.map_info((yield Unary("CreateMap", maps_pb2.CreateMapRequest(
                name=name, description=description, crs=crs), WRITE)))
        header = maps_pb2.UploadTreesHeader(name=name, create_map=True,
                                            description=description, crs=crs)
        if boundary is not None:
            header.boundary.CopyFrom(boundary_message(boundary))
        response = yield Upload(header, _NO_CHUNKS if empty
                                else _chunks(trees, columns, chunk, header))
        return answers.map_info(response.map)

    def upload(self, name: str, trees, replace: bool = False, chunk: int = 5000, *,
               columns: Optional[Sequence[str]] = None, boundary=None) -> MapInfo:
        """Adds trees to the map (or, with replace, makes them its only trees); one new version,
        all or nothing. Trees: a named table, or a list of Tree. boundary: the survey's
        polygons in the map frame, each an outer ring of (x, y) or an (outer, holes) pair; it
        replaces the map's boundary in the same version (None: the map keeps its own)."""
        return self._run(self._upload(name, trees, replace, chunk, columns, boundary))

    def _upload(self, name, trees, replace, chunk, columns, boundary):
        header = maps_pb2.UploadTreesHeader(name=name, replace=replace)
        if boundary is not None:
            header.boundary.CopyFrom(boundary_message(boundary))
        response = yield Upload(header, _NO_CHUNKS if trees is None
                                else _chunks(trees, columns, chunk, header))
        return answers.map_info(response.map)

    def boundary(self, name: str, version: int = 0) -> List:
        """The survey boundary of the map (or of an older version): [(outer, [holes...])], each
        ring an (n, 2) array of x, y in the map frame; [] when the map has none."""
        # The boundary rides on the export's first message; a box beyond every tree's
        # coordinates (the server keeps them within 1e7 m) sends no tree.
        request = maps_pb2.ExportTreesRequest(name=name, version=version)
        request.box.CopyFrom(box_message((1e9, 1e9, 1e9, 1e9)))
        gather = Gather(False)
        return self._run(self._one(Export(request, gather), lambda _: gather.boundary))

    def attribute_columns(self, name: str, version: int = 0) -> List[str]:
        """The order of the map's attribute columns (as the survey's file or table had them), the
        order exports write them in; [] when no order is known."""
        request = maps_pb2.ExportTreesRequest(name=name, version=version)
        request.box.CopyFrom(box_message((1e9, 1e9, 1e9, 1e9)))  # no tree: see boundary()
        gather = Gather(False)
        return self._run(self._one(Export(request, gather), lambda _: gather.attribute_columns))

    def list_maps(self, page_size: int = 0) -> List[MapInfo]:
        """Every map the caller may read, by name (page by page; 0: the server's page size)."""
        return self._run(self._list_maps(page_size))

    def _list_maps(self, page_size):
        maps = yield from _pages("ListMaps", maps_pb2.ListMapsRequest(page_size=page_size),
                                 "maps")
        return [answers.map_info(m) for m in maps]

    def get_map(self, name: str) -> MapInfo:
        return self._run(self._one(Unary("GetMap", maps_pb2.GetMapRequest(name=name), READ),
                                   answers.map_info))

    def delete_map(self, name: str) -> None:
        return self._run(self._one(Unary("DeleteMap", maps_pb2.DeleteMapRequest(name=name),
                                         WRITE), lambda response: None))

    def export(self, name: str, version: int = 0, *, box=None, as_array: bool = False,
               attributes: Sequence[str] = ()):
        """The map's trees by id (or those of an older version, or only inside
        box = (min_x, min_y, max_x, max_y)): a list of Tree, or with as_array a structured array
        of exports.TREE_DTYPE (NaN: unknown) plus the named `attributes` as text columns."""
        request = maps_pb2.ExportTreesRequest(name=name, version=version)
        if box is not None:
            request.box.CopyFrom(box_message(box))
        return self._run(self._one(Export(request, Gather(as_array, attributes)), None))

    # ---- relocalization ----

    def relocalize(self, name: Optional[str], trees, prior: Optional[Tuple[float, ...]] = None,
                   gravity: Optional[Sequence[float]] = None, *,
                   columns: Optional[Sequence[str]] = None,
                   stamp_ns: Optional[int] = None, maps: Optional[Sequence[str]] = None,
                   maps_matching: Optional[str] = None,
                   all_maps: bool = False) -> answers.Answer:
        """Pose of the sensor in the map from the trees it detected (sensor frame, m).

        prior: (x, y, radius_m): the sensor is within radius_m of (x, y) in the map frame (a
        4-tuple (x, y, yaw_deg, radius_m) of older versions is read too: the yaw was never
        used). gravity: direction of gravity (down) in the sensor frame. stamp_ns: your time
        stamp of the detections, echoed in Answer.stamp_ns.

        Instead of one map (name None): one question over a set of maps, ``maps`` (names),
        ``maps_matching`` (a glob, "district-*") or ``all_maps`` (every map the token may read);
        Answer.map_name says which map the sensor was found in."""
        return self._run(self._relocalize(name, trees, prior, gravity, columns, stamp_ns,
                                          (maps, maps_matching, all_maps)))

    def _relocalize(self, name, trees, prior, gravity, columns, stamp_ns, map_set=(None, None,
                                                                                   False)):
        request = relocalization_pb2.RelocalizeRequest(
            name=name or "", trees=inputs.detected_trees(trees, columns))
        names, pattern, every = map_set
        if names or pattern or every:
            request.maps.names.extend(names or ())
            request.maps.name_pattern = pattern or ""
            request.maps.all_readable = bool(every)
        if prior is not None:
            x, y, radius = (prior[0], prior[1], prior[-1]) if len(prior) == 4 else prior
            request.prior.x, request.prior.y, request.prior.radius_m = x, y, radius
        if gravity is not None:
            request.gravity.CopyFrom(geometry.vector3(gravity, "gravity"))
        if stamp_ns is not None:
            request.client_stamp_ns = int(stamp_ns)
        return answers.answer((yield Unary("Relocalize", request, READ)))

    # ---- shared maps ----

    def observe(self, name: str, frames: Iterable[Tuple], source: str = "forestmap-python", *,
                columns: Optional[Sequence[str]] = None, base_version: int = 0,
                reject_stale: bool = False, pose_sigma: float = 0.0, yaw_sigma: float = 0.0,
                sensor_range: float = 0.0, detection_probability: float = 0.0,
                merge_only: bool = False) -> answers.ObserveResult:
        """Merges frames (frame_id, trees in the sensor frame, 4 x 4 map_from_sensor or None:
        the server relocalizes the frame) into the map as ONE new version, or nothing. A frame
        with a pose is evidence of absence too (trees may be empty: it saw none); map trees that
        several sources should have seen and did not are removed.
        reject_stale: ABORTED unless the map is still at base_version.
        pose_sigma (m per axis), yaw_sigma (rad): the error of the poses (0: exact).
        sensor_range (m), detection_probability (near the sensor): 0 learns them.
        merge_only: merge the detections without weighing what the frames did not see."""
        return self._run(self._observe(name, frames, source, columns, base_version,
                                       reject_stale, pose_sigma, yaw_sigma, sensor_range,
                                       detection_probability, merge_only))

    def _observe(self, name, frames, source, columns, base_version, reject_stale, pose_sigma,
                 yaw_sigma, sensor_range, detection_probability, merge_only):
        request = observations_pb2.ObserveRequest(
            name=name, source=source, base_version=base_version,
            conflict_policy=(observations_pb2.CONFLICT_POLICY_REJECT_IF_STALE if reject_stale
                             else observations_pb2.CONFLICT_POLICY_MERGE),
            sensor_range=sensor_range, detection_probability=detection_probability,
            merge_only=merge_only)
        for frame_id, trees, map_from_sensor in frames:
            frame = request.frames.add(frame_id=frame_id, trees=inputs.detected_trees(
                trees, columns, f"frames[{len(request.frames)}].trees"),
                position_sigma=pose_sigma, yaw_sigma=yaw_sigma)
            if map_from_sensor is not None:
                frame.map_from_sensor.CopyFrom(geometry.to_pose(map_from_sensor,
                                                                "map_from_sensor"))
        return answers.observe_result((yield Unary("Observe", request, WRITE)))

    def list_versions(self, name: str, limit: int = 0) -> List[VersionInfo]:
        """The map's history, oldest first (limit: only the newest `limit` versions)."""
        return self._run(self._list_versions(name, limit))

    def _list_versions(self, name, limit):
        versions = yield from _pages("ListVersions", observations_pb2.ListVersionsRequest(
            name=name, limit=limit), "versions")
        kind = observations_pb2.MapVersion.Kind
        return [VersionInfo(v.version, v.created_unix_ms, answers.label(kind, v.kind), v.source,
                            v.tree_count, v.confirmed_count) for v in versions]

    def restore_version(self, name: str, version: int) -> MapInfo:
        request = observations_pb2.RestoreVersionRequest(name=name, version=version)
        return self._run(self._one(Unary("RestoreVersion", request, WRITE),
                                   lambda response: answers.map_info(response.map)))

    def remove_source(self, name: str, source: str) -> MapInfo:
        request = observations_pb2.RemoveSourceRequest(name=name, source=source)
        return self._run(self._one(Unary("RemoveSource", request, WRITE),
                                   lambda response: answers.map_info(response.map)))

    def prune_versions(self, name: str, keep: int) -> MapInfo:
        request = observations_pb2.PruneVersionsRequest(name=name, keep=keep)
        return self._run(self._one(Unary("PruneVersions", request, WRITE),
                                   lambda response: answers.map_info(response.map)))

    @staticmethod
    def _one(call, decode):
        """Plan of one call; `decode` turns its response into the result (None: as it is)."""
        response = yield call
        return response if decode is None else decode(response)


__all__ = ["Methods", "VersionInfo"]
