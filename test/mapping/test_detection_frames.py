"""Detections in a sensor frame are moved into the scene's frame, and a result's covariance gives hypotheses.

:func:`detection_inputs` on the messages rosbags decodes; the transforms are those a
:class:`TransformBuffer` looks up (the node's live path over DDS is ros/test_node_cell.py's).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from physics_mapper.bags.storage import TYPESTORE
from physics_mapper.mapping.detection_data import detection_array_data
from physics_mapper.mapping.detections import DETECTION_ARRAY, detection_inputs
from physics_mapper.mapping.frames import StampedTransform, Transform, TransformBuffer
from physics_mapper.model.geometry import quaternion_about_axis
from physics_mapper.model.scene import Scene
from physics_mapper.model.scene_files import scene_from_dict

TYPES = TYPESTORE.types
HALF_TURN_X = quaternion_about_axis((1.0, 0.0, 0.0), math.pi)  # a camera looking straight down


def scene() -> Scene:
    cube = {"name": "part", "shape": "box", "size": [0.1, 0.1, 0.1], "mass": 0.5}
    return scene_from_dict({"objects": [cube], "static": [{"name": "floor", "shape": "plane"}]}, "test scene")


def result(position: tuple[float, float, float], score: float, covariance: np.ndarray | None = None) -> Any:
    x, y, z = position
    pose = TYPES["geometry_msgs/msg/Pose"](
        position=TYPES["geometry_msgs/msg/Point"](x=x, y=y, z=z),
        orientation=TYPES["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
    )
    values = np.zeros(36) if covariance is None else covariance.reshape(36)
    return TYPES["vision_msgs/msg/ObjectHypothesisWithPose"](
        hypothesis=TYPES["vision_msgs/msg/ObjectHypothesis"](class_id="part", score=score),
        pose=TYPES["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=values),
    )


def array(*results: Any, frame_id: str) -> Any:
    stamp = TYPES["builtin_interfaces/msg/Time"](sec=3, nanosec=0)
    empty = TYPES["std_msgs/msg/Header"](stamp=stamp, frame_id="")
    box = TYPES["vision_msgs/msg/BoundingBox3D"](
        center=results[0].pose.pose, size=TYPES["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
    )
    detection = TYPES["vision_msgs/msg/Detection3D"](header=empty, results=list(results), bbox=box, id="")
    header = TYPES["std_msgs/msg/Header"](stamp=stamp, frame_id=frame_id)
    return TYPES[DETECTION_ARRAY](header=header, detections=[detection])


def camera_above() -> Transform:
    """A camera 1 m above the world origin, looking down (its z is the world's -z)."""
    buffer = TransformBuffer()
    buffer.add(StampedTransform("world", "camera", 0, (0.0, 0.0, 1.0), HALF_TURN_X), static=True)
    found = buffer.lookup("world", "camera", 3_000_000_000)
    assert isinstance(found, Transform)
    return found


def test_a_detection_in_the_camera_frame_lands_in_the_scene_frame() -> None:
    message = array(result((0.1, 0.2, 0.95), 0.9), frame_id="camera")
    assert detection_array_data(message).frames() == {"camera"}
    inputs = detection_inputs(message, scene(), received=1.0, transforms={"camera": camera_above()})
    poses = inputs.objects["part"]
    assert poses.refusal is None
    np.testing.assert_allclose(poses.poses[0, :3], [0.1, -0.2, 0.05], atol=1e-12)
    np.testing.assert_allclose(np.abs(poses.poses[0, 3:]), np.abs(HALF_TURN_X), atol=1e-12)


def test_a_frame_without_a_transform_is_refused_with_the_lookup_reason() -> None:
    message = array(result((0.0, 0.0, 0.95), 0.9), frame_id="camera")
    why = "no transform from 'camera' to 'world': frame 'camera' is unknown (waited 0.2 s)"
    inputs = detection_inputs(message, scene(), received=1.0, unresolved={"camera": why})
    assert inputs.objects["part"].refusal == why
    plain = detection_inputs(message, scene(), received=1.0)
    assert plain.objects["part"].refusal == "frame_id 'camera' is not the scene frame 'world'"


def test_a_single_pose_with_covariance_gives_weighted_alternatives_rotated_into_the_scene_frame() -> None:
    covariance = np.diag([0.0, 0.0, 0.01**2, 0.0, 0.0, 0.0])  # 1 cm along the camera's z
    message = array(result((0.0, 0.0, 0.95), 0.9, covariance), frame_id="camera")
    inputs = detection_inputs(message, scene(), received=1.0, transforms={"camera": camera_above()})
    poses = inputs.objects["part"]
    assert poses.count == 5 and poses.weights is not None
    heights = sorted(round(float(z), 9) for z in poses.poses[:, 2])
    assert heights == [0.03, 0.04, 0.05, 0.06, 0.07]  # along the world's z: the camera's z turned over
    by_height = dict(zip(np.round(poses.poses[:, 2], 9).tolist(), poses.weights.values.tolist(), strict=True))
    assert by_height[0.06] == pytest.approx(by_height[0.05] * math.exp(-0.5))
    assert by_height[0.05] == pytest.approx(0.9 / math.sqrt(101.0))  # the score times rho = sqrt(1e-6 / 1.01e-4)


def test_an_unusable_covariance_is_noted_and_the_result_kept() -> None:
    covariance = np.diag([0.0, 0.0, -1.0, 0.0, 0.0, 0.0])
    inputs = detection_inputs(array(result((0.0, 0.0, 0.05), 0.9, covariance), frame_id="world"), scene(), received=1.0)
    assert inputs.objects["part"].count == 1
    assert "detection 0: result 0: covariance is not positive semi-definite, not used" in inputs.unused
