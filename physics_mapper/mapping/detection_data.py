"""A ``vision_msgs/Detection3DArray`` as arrays: what the rules of detections read (ROS-free).

Each ``Detection3D`` is one :class:`DetectionData`: its frame and id, and its M results as
arrays, scores (M,), poses (M, 7: x, y, z, qx, qy, qz, qw) and covariances (M, 6, 6; None when
all are zero, as estimators without covariance send them), with each result's class id as an index
into the detection's distinct class ids. Two readers make them:
:func:`detection_array_data` reads a deserialised message (rclpy's or rosbags') by attribute, a
Python loop over the results; the node reads the serialised bytes without a Python object per
result (:mod:`physics_mapper.msg_adapters.detection_array_cdr`). The rules
(:mod:`physics_mapper.mapping.detections`) then run on arrays whichever read them.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from physics_mapper.mapping.covariance import covariance_matrices
from physics_mapper.mapping.inputs import POSE_COLUMNS, PoseBlock
from physics_mapper.mapping.stamps import to_nanoseconds


@dataclass(frozen=True)
class DetectionData:
    """One Detection3D as read: ``frame_id`` (its header's, '' for none), ``key`` (its ``id``), and its
    results: result i is of class ``class_ids[result_classes[i]]`` (``class_ids`` distinct), scored
    ``scores[i]``, at ``poses[i]`` with covariance ``covariances[i]`` (None: every result's is zero)."""

    frame_id: str
    key: str
    class_ids: tuple[str, ...]
    result_classes: NDArray[np.intp]  # (M,)
    scores: NDArray[np.float64]  # (M,)
    poses: PoseBlock  # (M, 7)
    covariances: NDArray[np.float64] | None  # (M, 6, 6)


@dataclass(frozen=True)
class DetectionArrayData:
    """A Detection3DArray as read: its header's stamp (ns) and frame, and its detections in order."""

    stamp_ns: int
    frame_id: str
    detections: tuple[DetectionData, ...]

    def frames(self) -> set[str]:
        """The frames its poses are in: each detection's, or the array's where it names none."""
        return {detection.frame_id or self.frame_id for detection in self.detections}


def distinct_classes(names: Sequence[str]) -> tuple[tuple[str, ...], NDArray[np.intp]]:
    """``names`` as their distinct values (in order of first appearance) and each one's index among them."""
    class_ids = tuple(dict.fromkeys(names))
    index = {name: position for position, name in enumerate(class_ids)}
    return class_ids, np.fromiter((index[name] for name in names), np.intp, len(names))


def given_covariances(covariances: NDArray[np.float64]) -> NDArray[np.float64] | None:
    """Results' (M, 6, 6) covariances, or None if all are zero (no estimator's covariance)."""
    return covariances if covariances.any() else None


def detection_array_data(message: Any) -> DetectionArrayData:
    """A deserialised ``Detection3DArray`` (rclpy's or rosbags'), read by attribute."""
    stamp = message.header.stamp
    detections = tuple(_detection_data(detection) for detection in message.detections)
    return DetectionArrayData(to_nanoseconds(stamp.sec, stamp.nanosec), str(message.header.frame_id), detections)


def _detection_data(detection: Any) -> DetectionData:
    results = list(detection.results)
    class_ids, result_classes = distinct_classes([str(result.hypothesis.class_id) for result in results])
    scores = np.fromiter((float(result.hypothesis.score) for result in results), np.float64, len(results))
    poses = np.array([_pose_row(result.pose.pose) for result in results], dtype=np.float64)
    return DetectionData(
        str(detection.header.frame_id),
        str(detection.id),
        class_ids,
        result_classes,
        scores,
        poses.reshape(-1, POSE_COLUMNS),
        given_covariances(covariance_matrices([result.pose.covariance for result in results])),
    )


def _pose_row(pose: Any) -> tuple[float, ...]:
    p, q = pose.position, pose.orientation
    return (p.x, p.y, p.z, q.x, q.y, q.z, q.w)
