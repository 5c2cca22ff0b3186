"""Real data of ../shared/data for the tests: Wild_V01's map and frames, Wild_V02's frames,
ground-truth poses."""

import functools
import math
import os

import numpy as np

import forestmap

V02_FRAME = 300  # a frame of Wild_V02 that the Wild_V01 map localizes (191 inliers)


def detections(data_dir, frame):
    """One frame's detections as a structured array of trees.csv's columns (x, y, z, dbh,
    axis_x, ..., score), and the frame's lines as CSV text for the CLI."""
    with open(os.path.join(data_dir, "trees.csv")) as f:
        header = f.readline()
        lines = [line for line in f if int(line.split(",", 1)[0]) == frame]
    names = header.strip().split(",")
    rows = [tuple(float(v) if v else math.nan for v in line.strip().split(",")) for line in lines]
    return np.array(rows, dtype=[(n, np.float64) for n in names]), header + "".join(lines)


def map_array(data_dir):
    """map.csv (id, x, y, z, dbh, count) as a structured array of x, y, z, dbh."""
    return forestmap.read_csv(os.path.join(data_dir, "map.csv"))[["x", "y", "z", "dbh"]]


@functools.lru_cache(maxsize=None)
def poses(data_dir):
    """frame -> 4 x 4 world_from_sensor (ground truth of poses.csv)."""
    table = forestmap.read_csv(os.path.join(data_dir, "poses.csv"))
    out = {}
    for r in table:
        q = np.array([r["qx"], r["qy"], r["qz"], r["qw"]])
        q /= np.linalg.norm(q)
        out[int(r["frame"])] = forestmap.geometry.matrix_from_quaternion(
            tuple(q), (r["x"], r["y"], r["z"]))
    return out
