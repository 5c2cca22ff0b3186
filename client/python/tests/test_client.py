"""The Python client against a loopback forestmapd: round trips, errors, relocalization equal to
the C++ CLI's answer to the last digit, tracking and observing a real sequence (Wild_V01)."""

import json
import subprocess

import grpc
import math

import numpy as np
import pytest

from forest_data import detections, map_array, poses
from forestmap import Client, FieldViolation, ForestMapError, Tree
from forestmap.v1 import forestmap_service_pb2_grpc, maps_pb2, observations_pb2

FRAME = 300  # a frame of Wild_V01 the map localizes


@pytest.fixture(scope="module")
def wild(server, data_dir):
    client = Client(server)
    client.create_map("wild", map_array(data_dir))
    return client


def test_trees_round_trip_bit_for_bit(server):
    client = Client(server)
    rng = np.random.default_rng(5)
    trees = np.column_stack([rng.uniform(-500, 500, (200, 3)), rng.uniform(0.05, 0.9, 200)])
    info = client.create_map("roundtrip", trees, description="numpy", crs="EPSG:32633",
                             columns=("x", "y", "z", "dbh"))
    assert info.tree_count == 200 and info.version == 2 and info.crs == "EPSG:32633"
    exported = client.export("roundtrip")
    assert [(t.x, t.y, t.z, t.dbh) for t in exported] == [tuple(row) for row in trees]
    assert all(t.confirmed for t in exported)
    client.upload("roundtrip", [Tree(x=1.5, y=2.5, id=1000,
                                     attributes={"species": "Picea", "LI": None})])
    assert client.get_map("roundtrip").tree_count == 201
    assert client.export("roundtrip")[-1].attributes == {"species": "Picea", "LI": None}
    assert "roundtrip" in [m.name for m in client.list_maps()]
    client.delete_map("roundtrip")


def test_errors_carry_the_grpc_status(server):
    client = Client(server)
    with pytest.raises(ForestMapError) as error:
        client.get_map("no-such-map")
    assert error.value.code == grpc.StatusCode.NOT_FOUND
    assert "no-such-map" in error.value.details
    with pytest.raises(ForestMapError) as error:
        client.create_map("bad name!")
    assert error.value.code == grpc.StatusCode.INVALID_ARGUMENT
    # The bad field also comes as a google.rpc.BadRequest in the status details, and is shown.
    assert error.value.violations == [FieldViolation("name", error.value.details)]
    assert str(error.value).endswith("(field: name)")
    with pytest.raises(ValueError):
        client.relocalize("x", np.zeros(3), columns=("x", "y", "z"))  # not an N x 3 array


def test_relocalize_equals_the_cli_to_the_last_digit(wild, server, data_dir, cli, tmp_path):
    trees, text = detections(data_dir, FRAME)
    path = tmp_path / "frame.csv"
    path.write_text(text)
    run = subprocess.run([cli, "--server", server, "relocalize", "wild", "--trees", str(path)],
                         capture_output=True, text=True, check=True)
    expected = json.loads(run.stdout)
    answer = wild.relocalize("wild", trees)
    assert answer.status == expected["status"].upper() == "LOCALIZED"
    got = {"x": answer.x, "y": answer.y, "z": answer.z, "qx": answer.quaternion[0],
           "qy": answer.quaternion[1], "qz": answer.quaternion[2], "qw": answer.quaternion[3],
           "yaw_deg": answer.yaw_deg, "inliers": answer.inliers, "rmse_m": answer.rmse_m,
           "confidence": answer.confidence}
    for key, value in got.items():
        assert value == expected[key], f"{key}: python {value!r}, CLI {expected[key]!r}"
        assert json.dumps(value) == json.dumps(expected[key])  # the same printed digits
    # The 4 x 4 pose agrees with the translation and is a rotation.
    assert answer.map_from_sensor[0, 3] == answer.x
    rotation = answer.map_from_sensor[:3, :3]
    assert np.allclose(rotation @ rotation.T, np.eye(3), atol=1e-12)


def test_relocalize_with_a_prior(wild, data_dir):
    trees, _ = detections(data_dir, FRAME)
    free = wild.relocalize("wild", trees)
    near = wild.relocalize("wild", trees, prior=(free.x + 3, free.y - 2, 10.0))
    assert near.localized and abs(near.x - free.x) < 0.05 and abs(near.y - free.y) < 0.05
    # The 0.1.0 form, (x, y, yaw_deg, radius_m): the same pose, the yaw was never used.
    old = wild.relocalize("wild", trees, prior=(free.x + 3, free.y - 2, 77.0, 10.0))
    assert (old.x, old.y, old.quaternion, old.inliers) == (near.x, near.y, near.quaternion,
                                                           near.inliers)
    # A prior far from the true position: nothing within its radius.
    far = wild.relocalize("wild", trees, prior=(free.x + 300, free.y, 10.0))
    assert not far.localized


def test_relocalize_over_a_set_of_maps_names_the_map(wild, data_dir):
    trees, _ = detections(data_dir, FRAME)
    rng = np.random.default_rng(9)
    wild.create_map("wild-elsewhere", rng.uniform(0, 300, (3000, 2)), columns=("x", "y"))
    one = wild.relocalize("wild", trees)
    assert one.map_name == "wild"
    for chosen in ({"maps": ["wild-elsewhere", "wild"]}, {"maps_matching": "wild*"}):
        answer = wild.relocalize(None, trees, **chosen)
        assert answer.localized and answer.map_name == "wild", chosen
        assert (answer.x, answer.y) == pytest.approx((one.x, one.y), abs=0.05)
    tracked = list(wild.track(None, [trees, trees], maps=["wild-elsewhere", "wild"]))
    assert [t.answer.map_name for t in tracked] == ["wild", "wild"]
    assert tracked[0].state == "RECOVERED" and tracked[1].state == "TRACKING"
    with pytest.raises(ForestMapError) as error:
        wild.relocalize(None, trees, maps_matching="no-such-*")
    assert error.value.code == grpc.StatusCode.NOT_FOUND
    wild.delete_map("wild-elsewhere")


def test_plot_maps_of_one_crs_answer_a_view_across_them_with_each_matchs_map(wild, data_dir):
    trees, _ = detections(data_dir, FRAME)
    one = wild.relocalize("wild", trees)
    assert one.localized
    surveyed = map_array(data_dir)
    west = surveyed["x"] < one.x  # the cut runs through the sensor
    wild.create_map("cut-west", surveyed[west], crs="EPSG:32633")
    wild.create_map("cut-east", surveyed[~west], crs="EPSG:32633")
    answer = wild.relocalize(None, trees, maps_matching="cut-*")
    assert answer.localized and answer.map_name in ("cut-west", "cut-east")
    assert (answer.x, answer.y) == pytest.approx((one.x, one.y), abs=0.05)
    assert set(answer.match_maps) == {"cut-west", "cut-east"}
    assert len(answer.match_maps) == len(answer.matches)
    for name in ("cut-west", "cut-east"):
        wild.delete_map(name)


def test_a_bad_tree_names_its_field_in_the_error_details(wild):
    trees = np.array([[1.0, 2.0, 0.0], [1.0, 1.0, -1.0], [3.0, 4.0, 0.0]])
    with pytest.raises(ForestMapError) as error:
        wild.relocalize("wild", trees, columns=("x", "y", "dbh"))
    assert error.value.code == grpc.StatusCode.INVALID_ARGUMENT
    assert [v.field for v in error.value.violations] == ["trees[1].dbh"]
    assert "trees[1].dbh" in error.value.violations[0].description


@pytest.fixture(scope="module")
def stub(server):
    with grpc.insecure_channel(server) as channel:
        yield forestmap_service_pb2_grpc.ForestMapStub(channel)


def test_list_maps_pages_concatenate_to_the_whole_list(server, stub):
    client = Client(server)
    for i in range(7):
        client.create_map(f"page-{i}")
    everything = [m.name for m in client.list_maps()]
    assert everything == sorted(everything) and len(everything) >= 7
    for size in (1, 2, 3, 1000, 10**6):  # more than the maximum is the maximum (1000)
        names, token, pages = [], "", 0
        while True:
            page = stub.ListMaps(maps_pb2.ListMapsRequest(page_size=size, page_token=token))
            assert len(page.maps) <= size
            names += [m.name for m in page.maps]
            token, pages = page.next_page_token, pages + 1
            # Opaque: the token does not spell the last name it follows.
            assert not any(m.name in token for m in page.maps)
            if not token:
                break
        assert names == everything and pages == -(-len(everything) // size)
    assert [m.name for m in client.list_maps(page_size=2)] == everything
    for i in range(7):
        client.delete_map(f"page-{i}")


def test_bad_page_requests_are_invalid_arguments(stub):
    def error_of(call, request):
        with pytest.raises(grpc.RpcError) as raised:
            call(request)
        return ForestMapError.of("call", raised.value)

    bad_token = error_of(stub.ListMaps, maps_pb2.ListMapsRequest(page_token="not-a-token"))
    assert bad_token.code == grpc.StatusCode.INVALID_ARGUMENT
    assert [v.field for v in bad_token.violations] == ["page_token"]
    negative = error_of(stub.ListMaps, maps_pb2.ListMapsRequest(page_size=-1))
    assert [v.field for v in negative.violations] == ["page_size"]
    # A token of one map's history is no token of another's, nor of the list of maps.
    for name in ("tokens-a", "tokens-b"):
        _make_map_with_versions(stub, name, 3)
    page = stub.ListVersions(observations_pb2.ListVersionsRequest(name="tokens-a", page_size=1))
    assert len(page.versions) == 1 and page.next_page_token
    other = error_of(stub.ListVersions, observations_pb2.ListVersionsRequest(
        name="tokens-b", page_size=1, page_token=page.next_page_token))
    assert [v.field for v in other.violations] == ["page_token"]
    listing = error_of(stub.ListMaps, maps_pb2.ListMapsRequest(page_token=page.next_page_token))
    assert [v.field for v in listing.violations] == ["page_token"]
    for name in ("tokens-a", "tokens-b"):
        stub.DeleteMap(maps_pb2.DeleteMapRequest(name=name))


def _make_map_with_versions(stub, name, versions):
    """Map `name` with `versions` versions: created, then one upload of one tree per version."""
    stub.CreateMap(maps_pb2.CreateMapRequest(name=name))
    for i in range(versions - 1):
        stub.UploadTrees(iter([
            maps_pb2.UploadTreesRequest(header=maps_pb2.UploadTreesHeader(name=name)),
            maps_pb2.UploadTreesRequest(chunk=maps_pb2.TreeChunk(
                trees=[maps_pb2.Tree(x=float(i), y=0.0)]))]))


def test_list_versions_pages_and_limit(stub):
    _make_map_with_versions(stub, "history", 6)

    def versions(limit, size):
        out, token = [], ""
        while True:
            page = stub.ListVersions(observations_pb2.ListVersionsRequest(
                name="history", limit=limit, page_size=size, page_token=token))
            assert len(page.versions) <= size
            out += [v.version for v in page.versions]
            token = page.next_page_token
            if not token:
                return out

    assert versions(0, 100) == [1, 2, 3, 4, 5, 6]
    assert versions(0, 4) == [1, 2, 3, 4, 5, 6]
    assert versions(4, 3) == [3, 4, 5, 6]  # the newest 4, oldest first, over two pages
    stub.DeleteMap(maps_pb2.DeleteMapRequest(name="history"))


def test_the_0_1_0_stream_layout_is_still_accepted(stub):
    """Upload messages of release 0.1.0: the map named on every message, no header."""
    stub.CreateMap(maps_pb2.CreateMapRequest(name="legacy"))
    old = [maps_pb2.UploadTreesRequest(name="legacy", trees=[maps_pb2.Tree(x=1.0, y=2.0)]),
           maps_pb2.UploadTreesRequest(trees=[maps_pb2.Tree(x=3.0, y=4.0)])]
    assert stub.UploadTrees(iter(old)).map.tree_count == 2
    mixed = [maps_pb2.UploadTreesRequest(name="legacy",
                                         header=maps_pb2.UploadTreesHeader(name="legacy"))]
    with pytest.raises(grpc.RpcError) as error:
        stub.UploadTrees(iter(mixed))
    assert error.value.code() == grpc.StatusCode.INVALID_ARGUMENT
    stub.DeleteMap(maps_pb2.DeleteMapRequest(name="legacy"))


def test_track_yields_one_answer_per_frame(wild, data_dir):
    frames = [(frame, detections(data_dir, frame)[0]) for frame in range(FRAME, FRAME + 10)]
    answers = list(wild.track("wild", frames))
    assert [a.frame_id for a in answers] == list(range(FRAME, FRAME + 10))
    assert sum(a.state in ("TRACKING", "RECOVERED") for a in answers) >= 8


def test_observe_builds_a_shared_map(server, data_dir):
    client = Client(server)
    client.create_map("observed")
    truth = poses(data_dir)
    frames = [(f, detections(data_dir, f)[0], truth[f]) for f in range(0, 25)]
    result = client.observe("observed", frames, source="py-drone")
    assert result.merged == 25 and result.skipped == 0
    trees = client.export("observed")
    assert len(trees) > 20 and result.map_version == 2
    assert all(t.observations >= 1 for t in trees)


def test_frames_that_see_nothing_remove_the_trees_of_a_clear_cut(server):
    client = Client(server)
    trees = np.array([(x, y, 0.3) for x in range(0, 40, 4) for y in range(0, 40, 4)], float)
    client.create_map("clear-cut", trees, columns=("x", "y", "dbh"))
    pose = np.eye(4)
    pose[:3, 3] = (18.0, 18.0, 1.5)
    frames = [(k, np.empty((0, 2)), pose) for k in range(3)]
    results = [client.observe("clear-cut", frames, source=f"drone-{d}", columns=("x", "y"),
                              sensor_range=10.0, detection_probability=0.9, pose_sigma=0.05)
               for d in range(4)]
    assert results[0].missed > 0 and results[0].removed == 0
    assert sum(r.removed for r in results) > 0
    left = client.export("clear-cut")
    assert len(left) == len(trees) - sum(r.removed for r in results)
    # The trees near the sensor are gone, those far from it stand, unseen since the survey.
    assert all(math.hypot(t.x - 18, t.y - 18) > 2 for t in left)
    assert all(t.last_seen_unix_ms is None for t in left)


def test_replicas_fail_over(server):
    # A dead address first: the idempotent call moves on to the live server and says so.
    client = Client("127.0.0.1:1," + server)
    assert isinstance(client.list_maps(), list)
    assert client.retries == 1


def test_a_survey_boundary_round_trips_and_is_versioned(server):
    client = Client(server)
    outer = [(0, 0), (50, 0), (50, 40), (0, 40)]
    hole = [(10, 10), (10, 20), (20, 20), (20, 10)]
    trees = np.array([(5.0, 5.0), (30.0, 30.0), (45.0, 5.0)])
    info = client.create_map("bounded", trees, columns=("x", "y"), boundary=[(outer, [hole])])
    assert info.has_boundary and client.get_map("bounded").has_boundary
    [(got_outer, got_holes)] = client.boundary("bounded")
    assert got_outer.tolist() == [list(map(float, p)) for p in outer]
    assert [h.tolist() for h in got_holes] == [[list(map(float, p)) for p in hole]]
    assert len(client.export("bounded")) == 3  # the export still sends every tree
    # A new boundary alone makes a version; the old version keeps its own.
    client.upload("bounded", None, boundary=[[(0, 0), (60, 0), (60, 60), (0, 60)]])
    assert client.get_map("bounded").version == info.version + 1
    assert client.boundary("bounded")[0][0].shape == (4, 2)
    assert client.boundary("bounded", version=info.version)[0][1][0].shape == (4, 2)
    with pytest.raises(ValueError):
        client.upload("bounded", None, boundary=[[(0, 0), (1, 1)]])
    with pytest.raises(ValueError):
        client.upload("bounded", None, boundary=[[(0, 0), (1, float("nan")), (1, 1)]])
    client.delete_map("bounded")
