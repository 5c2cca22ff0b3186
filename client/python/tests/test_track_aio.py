"""track() with odometry, gravity and stamps on a real sequence (Wild_V01 frames in its map,
ground-truth poses), and the asyncio client: the same answers as the blocking one."""

import asyncio
import os

import grpc
import numpy as np
import pytest

from forest_data import V02_FRAME, detections, map_array, poses
from forestmap import AsyncClient, Client, ForestMapError, Frame

FIRST, COUNT = 300, 15


@pytest.fixture(scope="module")
def client(server, data_dir):
    client = Client(server)
    client.create_map("tracked", map_array(data_dir))
    return client


def frames_with_odometry(data_dir):
    truth = poses(data_dir)
    out = []
    for f in range(FIRST, FIRST + COUNT):
        world_from_sensor = truth[f]
        odometry = np.linalg.inv(truth[f - 1]) @ world_from_sensor  # previous_from_current
        gravity = world_from_sensor[:3, :3].T @ [0.0, 0.0, -1.0]   # down, in the sensor frame
        out.append(Frame(detections(data_dir, f)[0], frame_id=f, stamp_ns=10**18 + f,
                         gravity=gravity, odometry=odometry))
    return out, truth


def test_track_with_odometry_gravity_and_stamps(client, data_dir):
    frames, truth = frames_with_odometry(data_dir)
    answers = list(client.track("tracked", iter(frames)))  # a lazy iterator, as a live feed
    assert [a.frame_id for a in answers] == list(range(FIRST, FIRST + COUNT))
    assert [a.answer.stamp_ns for a in answers] == [10**18 + f for f in range(FIRST,
                                                                               FIRST + COUNT)]
    assert all(a.state in ("TRACKING", "RECOVERED") for a in answers)
    assert sum(a.method == "LOCAL" for a in answers) >= COUNT - 2  # odometry-predicted
    for a in answers:  # the map is the sequence's own: the pose is the ground truth
        error = a.answer.map_from_sensor[:3, 3] - truth[a.frame_id][:3, 3]
        assert np.hypot(error[0], error[1]) < 0.3, (a.frame_id, error)


def test_a_bad_frame_ends_the_session_after_the_good_ones(client, data_dir):
    frames, _ = frames_with_odometry(data_dir)
    frames[3].odometry = np.diag([2.0, 1.0, 1.0, 1.0])  # not a rigid transform
    answers = []
    with pytest.raises(ValueError, match=r"frames\[3\].odometry: not a rigid transform"):
        for answer in client.track("tracked", frames):
            answers.append(answer)
    assert [a.frame_id for a in answers] == list(range(FIRST, FIRST + 3))


def test_async_client_mirrors_the_blocking_one(client, server, data_root):
    trees = detections(os.path.join(data_root, "sequences", "Wild_V02"), V02_FRAME)[0]
    blocking = client.relocalize("tracked", trees, stamp_ns=42)
    exported = client.export("tracked", as_array=True)

    async def frames():
        for f in range(FIRST, FIRST + 3):
            await asyncio.sleep(0)
            yield Frame(trees, frame_id=f, stamp_ns=f)

    async def run():
        async with AsyncClient(f"127.0.0.1:1,{server}") as aclient:
            answer = await aclient.relocalize("tracked", trees, stamp_ns=42)
            assert aclient.retries == 1  # failed over from the dead replica
            maps = await aclient.list_maps()
            array = await aclient.export("tracked", as_array=True)
            tracked = [a async for a in aclient.track("tracked", frames())]
            with pytest.raises(ForestMapError) as missing:
                await aclient.get_map("no-such-map")
            info = await aclient.create_map("async-made", {"x": [0.0, 1.0], "y": [2.0, 3.0]})
            await aclient.delete_map("async-made")
            return answer, maps, array, tracked, missing.value, info

    answer, maps, array, tracked, missing, info = asyncio.run(run())
    for field in ("status", "x", "y", "z", "quaternion", "inliers", "rmse_m", "stamp_ns"):
        assert getattr(answer, field) == getattr(blocking, field), field
    assert np.array_equal(answer.covariance, blocking.covariance)
    assert np.array_equal(answer.matches, blocking.matches)
    assert "tracked" in [m.name for m in maps]
    for name in exported.dtype.names:
        assert np.array_equal(array[name], exported[name],
                              equal_nan=exported[name].dtype.kind == "f"), name
    assert [(a.frame_id, a.answer.stamp_ns) for a in tracked] == [(f, f) for f in
                                                                  range(FIRST, FIRST + 3)]
    assert all(a.answer.localized for a in tracked)
    assert missing.code == grpc.StatusCode.NOT_FOUND and info.tree_count == 2
