"""ROS 2 helpers that need no ROS 2: the fields of geometry_msgs/PoseWithCovarianceStamped and
of the map -> odom geometry_msgs/TransformStamped (REP-105), as plain dicts and numbers.

Fill a message with them, e.g. in an rclpy node:

    fields = forestmap.ros.pose_with_covariance(answer, stamp_ns=stamp)
    msg = PoseWithCovarianceStamped()
    msg.header.frame_id = fields["header"]["frame_id"]
    msg.header.stamp.sec, msg.header.stamp.nanosec = fields["header"]["stamp"]
    p, o = fields["pose"]["position"], fields["pose"]["orientation"]
    msg.pose.pose.position.x, msg.pose.pose.position.y, msg.pose.pose.position.z = p
    (msg.pose.pose.orientation.x, msg.pose.pose.orientation.y, msg.pose.pose.orientation.z,
     msg.pose.pose.orientation.w) = o
    msg.pose.covariance = fields["covariance"]

The server's covariance is already in ROS order (x, y, z, rotation about the fixed X, Y, Z axes;
relocalization.proto), 6 x 6 row-major: the 36 numbers go over unchanged. An unobserved
component (z of a map without heights) has variance 1e6, as ROS drivers mark "unknown".
"""

from __future__ import annotations

from typing import Dict, Optional

import numpy as np

from forestmap import geometry


def _stamp(stamp_ns: Optional[int]):
    """builtin_interfaces/Time (sec, nanosec) of ns since the epoch; (0, 0) when unknown."""
    if stamp_ns is None:
        return (0, 0)
    return (int(stamp_ns) // 1_000_000_000, int(stamp_ns) % 1_000_000_000)


def _pose_fields(matrix: np.ndarray) -> Dict:
    return {"position": tuple(float(v) for v in matrix[:3, 3]),
            "orientation": geometry.quaternion_from_matrix(matrix)}


def pose_with_covariance(answer, frame_id: str = "map",
                         stamp_ns: Optional[int] = None) -> Dict:
    """geometry_msgs/PoseWithCovarianceStamped fields of a LOCALIZED answer: header (frame_id,
    stamp (sec, nanosec): stamp_ns, else the answer's echoed stamp), pose: position (x, y, z),
    orientation (x, y, z, w), and covariance: 36 floats, row-major, ROS order."""
    if not answer.localized or answer.covariance is None:
        raise ValueError(f"no pose: the answer is {answer.status} ({answer.reason})")
    stamp = stamp_ns if stamp_ns is not None else answer.stamp_ns
    return {"header": {"frame_id": frame_id, "stamp": _stamp(stamp)},
            "pose": {"position": (answer.x, answer.y, answer.z),
                     "orientation": answer.quaternion},  # as the server sent it
            "covariance": [float(v) for v in np.asarray(answer.covariance).reshape(36)]}


def map_from_odom(map_from_sensor, odom_from_sensor) -> np.ndarray:
    """The map -> odom transform a localizer publishes (REP-105): map_from_odom =
    map_from_sensor @ inverse(odom_from_sensor), with odom_from_sensor the odometry's pose of
    the same sensor at the time of the detections. (Any body frame works on both sides:
    odom_from_sensor = odom_from_base_link @ base_link_from_sensor.)"""
    return (geometry.rigid(map_from_sensor, "map_from_sensor")
            @ geometry.inverse(geometry.rigid(odom_from_sensor, "odom_from_sensor")))


def transform_stamped(parent_from_child, parent: str = "map", child: str = "odom",
                      stamp_ns: Optional[int] = None) -> Dict:
    """geometry_msgs/TransformStamped fields of a 4 x 4 parent_from_child: header (frame_id =
    parent, stamp), child_frame_id, transform: translation (x, y, z), rotation (x, y, z, w)."""
    matrix = geometry.rigid(parent_from_child, "parent_from_child")
    fields = _pose_fields(matrix)
    return {"header": {"frame_id": parent, "stamp": _stamp(stamp_ns)},
            "child_frame_id": child,
            "transform": {"translation": fields["position"], "rotation": fields["orientation"]}}
