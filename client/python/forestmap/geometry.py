"""Rigid transforms as 4 x 4 numpy arrays and their wire form (forestmap.v1.Pose).

Frames are named in variables as in the API: `a_from_b` maps coordinates in frame b to frame a,
p_a = a_from_b @ p_b; `a_from_c = a_from_b @ b_from_c`. Quaternions are (x, y, z, w), Hamilton,
as in ROS and the proto.
"""

from __future__ import annotations

import math
from typing import Tuple

import numpy as np

from forestmap.v1 import geometry_pb2


def matrix_from_quaternion(q: Tuple[float, float, float, float],
                           t: Tuple[float, float, float] = (0.0, 0.0, 0.0)) -> np.ndarray:
    """4 x 4 transform of the unit quaternion q = (x, y, z, w) and translation t."""
    x, y, z, w = q
    matrix = np.eye(4)
    matrix[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                      [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                      [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
    matrix[:3, 3] = t
    return matrix


def quaternion_from_matrix(matrix: np.ndarray) -> Tuple[float, float, float, float]:
    """(x, y, z, w) of the rotation part of a 4 x 4 (or 3 x 3) rigid transform, w >= 0."""
    m = np.asarray(matrix, dtype=np.float64)
    w = math.sqrt(max(0.0, 1 + m[0, 0] + m[1, 1] + m[2, 2])) / 2
    x = math.copysign(math.sqrt(max(0.0, 1 + m[0, 0] - m[1, 1] - m[2, 2])) / 2, m[2, 1] - m[1, 2])
    y = math.copysign(math.sqrt(max(0.0, 1 - m[0, 0] + m[1, 1] - m[2, 2])) / 2, m[0, 2] - m[2, 0])
    z = math.copysign(math.sqrt(max(0.0, 1 - m[0, 0] - m[1, 1] + m[2, 2])) / 2, m[1, 0] - m[0, 1])
    return (x, y, z, w)


def rigid(matrix, what: str) -> np.ndarray:
    """`matrix` as a 4 x 4 float array; ValueError unless it is a finite rigid transform (the
    rotation orthonormal within 2e-3, as the server accepts quaternions within 1e-3 of unit)."""
    m = np.asarray(matrix, dtype=np.float64)
    if m.shape != (4, 4) or not np.isfinite(m).all():
        raise ValueError(f"{what}: want a finite 4 x 4 transform, got shape {m.shape}")
    rotation = m[:3, :3]
    if (not np.allclose(rotation @ rotation.T, np.eye(3), atol=2e-3)
            or np.linalg.det(rotation) < 0 or not np.allclose(m[3], [0, 0, 0, 1])):
        raise ValueError(f"{what}: not a rigid transform (rotation not orthonormal, or last row "
                         "not 0 0 0 1)")
    return m


def inverse(matrix: np.ndarray) -> np.ndarray:
    """Inverse of a rigid transform (b_from_a of a_from_b)."""
    out = np.eye(4)
    out[:3, :3] = matrix[:3, :3].T
    out[:3, 3] = -matrix[:3, :3].T @ matrix[:3, 3]
    return out


def to_pose(matrix, what: str = "pose") -> geometry_pb2.Pose:
    """4 x 4 rigid transform -> Pose (rotation as a unit quaternion)."""
    m = rigid(matrix, what)
    x, y, z, w = quaternion_from_matrix(m)
    return geometry_pb2.Pose(translation=geometry_pb2.Vector3(x=m[0, 3], y=m[1, 3], z=m[2, 3]),
                             rotation=geometry_pb2.Quaternion(x=x, y=y, z=z, w=w))


def from_pose(pose: geometry_pb2.Pose) -> np.ndarray:
    q, t = pose.rotation, pose.translation
    return matrix_from_quaternion((q.x, q.y, q.z, q.w), (t.x, t.y, t.z))


def yaw_deg(q: geometry_pb2.Quaternion) -> float:
    """Yaw of the pose, computed exactly as the C++ CLI does (Eigen, SSE2 reduction order)."""
    norm = math.sqrt((q.x * q.x + q.z * q.z) + (q.y * q.y + q.w * q.w))
    x, y, z, w = q.x / norm, q.y / norm, q.z / norm, q.w / norm
    r10 = (2 * y) * x + (2 * z) * w
    r00 = 1 - ((2 * y) * y + (2 * z) * z)
    return math.atan2(r10, r00) * 180.0 / math.pi


def vector3(value, what: str) -> geometry_pb2.Vector3:
    v = np.asarray(value, dtype=np.float64)
    if v.shape != (3,) or not np.isfinite(v).all():
        raise ValueError(f"{what}: want 3 finite numbers, got {value!r}")
    return geometry_pb2.Vector3(x=float(v[0]), y=float(v[1]), z=float(v[2]))
