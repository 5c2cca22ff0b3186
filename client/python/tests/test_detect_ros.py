"""Trunk detection from Python (the installed `forestmap detect`) on real scans, and the ROS 2
helpers on numbers worked out by hand and on a real answer."""

import math
import os
import subprocess

import numpy as np
import pytest

import forestmap
from forest_data import V02_FRAME, detections, map_array
from forestmap import Client, ros

DETECT_COLUMNS = ("x", "y", "z", "dbh", "score", "axis_x", "axis_y", "axis_z", "bh_x", "bh_y",
                  "bh_z", "ground_known", "points", "slices", "residual", "arc_coverage",
                  "range")


@pytest.fixture(scope="module")
def scans(data_root):
    return os.path.join(data_root, "scans")


def test_detect_returns_the_clis_trees_by_name(scans, cli, tmp_path):
    scan = os.path.join(scans, "sloam_uav_ouster", "moving_tree_t0.pcd")
    trees = forestmap.detect(scan, cli=cli)
    assert trees.dtype.names == DETECT_COLUMNS and len(trees) > 20
    out = tmp_path / "trees.csv"
    subprocess.run([cli, "detect", scan, "--out", str(out)], check=True, capture_output=True)
    lines = out.read_text().splitlines()
    assert lines[0].split(",") == list(DETECT_COLUMNS) and len(lines) == len(trees) + 1
    for row, line in zip(trees, lines[1:]):
        values = [float(v) if v else math.nan for v in line.split(",")]
        assert np.array_equal(values, [row[n] for n in DETECT_COLUMNS], equal_nan=True)
    with pytest.raises(RuntimeError, match="forestmap detect .* failed"):
        forestmap.detect(str(out.with_suffix(".csv")), cli=cli, extra_args=["--seed", "x"])
    with pytest.raises(FileNotFoundError, match="no such file"):
        forestmap.detect(str(tmp_path / "none.pcd"), cli=cli)


def test_detected_trees_relocalize_under_a_known_transform(server, scans, cli):
    """The mobile scan's stems as the map; the same detections seen from a sensor at a known
    pose as the query: the answer is that pose."""
    trees = forestmap.detect(os.path.join(scans, "spanner_ponderosa", "MLS_Clip.pcd"), cli=cli)
    client = Client(server)
    client.create_map("ponderosa", trees)  # detect's own columns, by name
    yaw = math.radians(35.0)
    map_from_sensor = np.eye(4)
    map_from_sensor[:3, :3] = [[math.cos(yaw), -math.sin(yaw), 0], [math.sin(yaw),
                                                                   math.cos(yaw), 0], [0, 0, 1]]
    map_from_sensor[:3, 3] = [trees["x"].mean() + 3.0, trees["y"].mean() - 2.0, trees["z"].min()]
    sensor_from_map = np.linalg.inv(map_from_sensor)
    query = trees.copy()
    points = np.column_stack([trees["x"], trees["y"], trees["z"], np.ones(len(trees))])
    query["x"], query["y"], query["z"] = (sensor_from_map @ points.T)[:3]
    axes = np.column_stack([trees["axis_x"], trees["axis_y"], trees["axis_z"]])
    query["axis_x"], query["axis_y"], query["axis_z"] = (sensor_from_map[:3, :3] @ axes.T)
    # The sensor is level: gravity says so (the stem axes of this cluttered plot lean up to
    # ~28 deg, and levelling by their mean finds no constellation).
    answer = client.relocalize("ponderosa", query, gravity=(0.0, 0.0, -1.0))
    assert answer.localized and answer.inliers >= len(trees) - 2
    assert np.allclose(answer.map_from_sensor[:3, 3], map_from_sensor[:3, 3], atol=0.01)
    assert answer.yaw_deg == pytest.approx(35.0, abs=0.05)


def test_ros_map_from_odom_on_numbers():
    # map_from_sensor: yaw 90 deg, at (10, 5, 0); odom_from_sensor: no turn, at (1, 0, 0).
    map_from_sensor = np.array([[0.0, -1, 0, 10], [1, 0, 0, 5], [0, 0, 1, 0], [0, 0, 0, 1]])
    odom_from_sensor = np.array([[1.0, 0, 0, 1], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])
    map_from_odom = ros.map_from_odom(map_from_sensor, odom_from_sensor)
    # p_map = R90 (p_odom - (1, 0, 0)) + (10, 5, 0): translation (10, 4, 0), rotation yaw 90.
    assert np.allclose(map_from_odom, [[0, -1, 0, 10], [1, 0, 0, 4], [0, 0, 1, 0],
                                       [0, 0, 0, 1]], atol=1e-15)
    fields = ros.transform_stamped(map_from_odom, stamp_ns=1_700_000_000_250_000_000)
    assert fields["header"] == {"frame_id": "map", "stamp": (1_700_000_000, 250_000_000)}
    assert fields["child_frame_id"] == "odom"
    assert fields["transform"]["translation"] == (10.0, 4.0, 0.0)
    s = math.sqrt(0.5)
    assert np.allclose(fields["transform"]["rotation"], (0, 0, s, s), atol=1e-15)
    with pytest.raises(ValueError, match="odom_from_sensor: not a rigid transform"):
        ros.map_from_odom(map_from_sensor, np.diag([1.0, 1.0, -1.0, 1.0]))


def test_ros_pose_with_covariance_of_a_real_answer(server, data_root):
    client = Client(server)
    client.create_map("ros", map_array(os.path.join(data_root, "sequences", "Wild_V01")))
    trees = detections(os.path.join(data_root, "sequences", "Wild_V02"), V02_FRAME)[0]
    answer = client.relocalize("ros", trees, stamp_ns=5_000_000_007)
    fields = ros.pose_with_covariance(answer)
    assert fields["header"] == {"frame_id": "map", "stamp": (5, 7)}
    assert fields["pose"]["position"] == (answer.x, answer.y, answer.z)
    assert fields["pose"]["orientation"] == answer.quaternion
    # ROS order (x, y, z, roll, pitch, yaw), row-major: the server's order, element by element.
    cov = fields["covariance"]
    assert len(cov) == 36 and cov[0] == answer.covariance[0, 0]
    assert cov[7] == answer.covariance[1, 1] and cov[35] == answer.covariance[5, 5]
    assert cov[5] == answer.covariance[0, 5] and cov[30] == answer.covariance[5, 0]
    assert cov[21] == cov[28] == pytest.approx(0.017 ** 2)  # roll, pitch: the levelling error
    assert math.sqrt(cov[35]) < math.radians(0.5)  # yaw: a fraction of a degree
    far = client.relocalize("ros", trees, prior=(answer.x + 300, answer.y, 10.0))
    with pytest.raises(ValueError, match="NOT_FOUND"):
        ros.pose_with_covariance(far)
