"""Every field of a relocalization answer, checked against truth: the covariance against the
CLI's sigmas, the geodetic pose against PROJ's cs2cs, the matches against the exported map
trees under the answer's pose, the rival of a map holding the forest twice, the reason, the
echoed stamp. Real data: a Wild_V02 frame in the Wild_V01 map."""

import json
import math
import os
import shutil
import subprocess

import numpy as np
import pytest

from forest_data import V02_FRAME, detections, map_array
from forestmap import Client

# Wild_V01 lies in Venman forest (Brisbane): its map frame moved to UTM zone 56S for the CRS test.
UTM_OFFSET = (513000.0, 6945000.0)


@pytest.fixture(scope="module")
def client(server, data_root):
    client = Client(server)
    wild = map_array(os.path.join(data_root, "sequences", "Wild_V01"))
    client.create_map("answers", wild)
    utm = wild.copy()
    utm["x"] += UTM_OFFSET[0]
    utm["y"] += UTM_OFFSET[1]
    client.create_map("answers-utm", utm, crs="EPSG:32756")
    twice = wild.copy()
    twice["x"] += 2000.0
    client.create_map("answers-twice", np.concatenate([wild, twice]))
    return client


@pytest.fixture(scope="module")
def frame(data_root):
    return detections(os.path.join(data_root, "sequences", "Wild_V02"), V02_FRAME)


def test_covariance_is_a_6x6_array_with_the_clis_sigmas(client, frame, server, cli, tmp_path):
    answer = client.relocalize("answers", frame[0])
    assert answer.localized and answer.covariance.shape == (6, 6)
    c = answer.covariance
    assert np.array_equal(c, c.T) and np.linalg.eigvalsh(c).min() > 0
    path = tmp_path / "frame.csv"
    path.write_text(frame[1])
    line = json.loads(subprocess.run([cli, "--server", server, "relocalize", "answers",
                                      "--trees", str(path)], capture_output=True, text=True,
                                     check=True).stdout)
    assert math.sqrt(c[0, 0] + c[1, 1]) == line["sigma_xy_m"]
    assert math.sqrt(c[5, 5]) * 180.0 / math.pi == line["sigma_yaw_deg"]
    assert 0 < math.sqrt(c[0, 0]) < 0.1  # a few cm, as the V01/V02 offset (5-10 cm) suggests


def test_matches_pair_query_trees_with_map_trees_under_the_pose(client, frame):
    answer = client.relocalize("answers", frame[0])
    assert len(answer.matches) == answer.inliers == len(set(answer.matched_tree_ids)) > 100
    trees = {int(t["id"]): t for t in client.export("answers", as_array=True)}
    query = frame[0]
    for m in answer.matches:
        p = answer.map_from_sensor @ [query["x"][m["query_index"]],
                                      query["y"][m["query_index"]],
                                      query["z"][m["query_index"]], 1.0]
        tree = trees[int(m["map_tree_id"])]
        assert math.hypot(p[0] - tree["x"], p[1] - tree["y"]) == pytest.approx(
            m["distance_m"], abs=1e-3)  # the server poses the levelled query: ~mm apart
    assert answer.matches["distance_m"].max() < 1.0


@pytest.mark.skipif(shutil.which("cs2cs") is None, reason="PROJ's cs2cs (proj-bin) missing")
def test_geodetic_pose_agrees_with_proj(client, frame):
    answer = client.relocalize("answers-utm", frame[0])
    assert answer.localized and answer.geodetic is not None
    run = subprocess.run(["cs2cs", "-f", "%.10f", "EPSG:32756", "EPSG:4326"],
                         input=f"{answer.x} {answer.y}\n", capture_output=True, text=True,
                         check=True)
    lat, lon = (float(v) for v in run.stdout.split()[:2])
    g = answer.geodetic
    assert g.latitude_deg == pytest.approx(lat, abs=1e-8)
    assert g.longitude_deg == pytest.approx(lon, abs=1e-8)
    assert -27.7 < g.latitude_deg < -27.5 and 153.1 < g.longitude_deg < 153.2  # Brisbane
    # True heading = grid heading + convergence; grid heading = 90 deg - yaw (x east, y north).
    grid = (90.0 - answer.yaw_deg) % 360.0
    assert g.true_heading_deg == pytest.approx((grid + g.grid_convergence_deg) % 360.0, abs=1e-6)
    assert client.relocalize("answers", frame[0]).geodetic is None  # no CRS, no geodetic pose


def test_not_localized_answers_say_why(client, frame):
    free = client.relocalize("answers", frame[0])
    assert free.reason == "NONE" and free.rival_map_from_sensor is None
    far = client.relocalize("answers", frame[0], prior=(free.x + 300, free.y, 10.0))
    assert far.status == "NOT_FOUND" and far.reason == "OUTSIDE_PRIOR"
    assert far.covariance is None and far.map_from_sensor is None
    twice = client.relocalize("answers-twice", frame[0])
    assert twice.status == "AMBIGUOUS" and twice.reason == "AMBIGUOUS_RIVAL"
    rival = twice.rival_map_from_sensor
    # The rival is the pose in one of the two copies of the forest, 2,000 m apart.
    offset = rival[0, 3] - free.x
    assert min(abs(offset), abs(offset - 2000.0)) < 0.5 and abs(rival[1, 3] - free.y) < 0.5
    assert np.allclose(rival[:3, :3], free.map_from_sensor[:3, :3], atol=0.02)


def test_the_stamp_is_echoed(client, frame):
    stamp = 1_700_000_000_123_456_789
    assert client.relocalize("answers", frame[0], stamp_ns=stamp).stamp_ns == stamp
    assert client.relocalize("answers", frame[0]).stamp_ns is None
