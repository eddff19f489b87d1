"""Detection3DArrays built as rosbags decodes them, for the rules of detections and instances.

The node reads rclpy's messages by the same attributes, so the ROS-free rules are tested on these.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from physics_mapper.bags.storage import TYPESTORE
from physics_mapper.mapping.detections import DETECTION_ARRAY

TYPES = TYPESTORE.types


def result(
    position: Sequence[float],
    score: float = 0.9,
    class_id: str = "box",
    orientation: Sequence[float] = (0.0, 0.0, 0.0, 1.0),
) -> Any:
    """One scored result at ``position`` (m), turned by the quaternion ``orientation`` (x, y, z, w)."""
    qx, qy, qz, qw = (float(q) for q in orientation)
    pose = TYPES["geometry_msgs/msg/Pose"](
        position=TYPES["geometry_msgs/msg/Point"](x=float(position[0]), y=float(position[1]), z=float(position[2])),
        orientation=TYPES["geometry_msgs/msg/Quaternion"](x=qx, y=qy, z=qz, w=qw),
    )
    return TYPES["vision_msgs/msg/ObjectHypothesisWithPose"](
        hypothesis=TYPES["vision_msgs/msg/ObjectHypothesis"](class_id=class_id, score=score),
        pose=TYPES["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
    )


def detection(*results: Any, key: str = "") -> Any:
    """One Detection3D of ``results``, its ``id`` ``key``, in the array's frame."""
    header = TYPES["std_msgs/msg/Header"](stamp=TYPES["builtin_interfaces/msg/Time"](sec=1, nanosec=0), frame_id="")
    box = TYPES["vision_msgs/msg/BoundingBox3D"](
        center=results[0].pose.pose, size=TYPES["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
    )
    return TYPES["vision_msgs/msg/Detection3D"](header=header, results=list(results), bbox=box, id=key)


def array(detections: Sequence[Any], sec: int = 1) -> Any:
    """A Detection3DArray in ``world`` stamped ``sec`` seconds."""
    stamp = TYPES["builtin_interfaces/msg/Time"](sec=sec, nanosec=0)
    header = TYPES["std_msgs/msg/Header"](stamp=stamp, frame_id="world")
    return TYPES[DETECTION_ARRAY](header=header, detections=list(detections))
