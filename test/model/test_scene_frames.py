"""A scene file's fixed sensor frames (``frames:``), for cells without TF."""

from __future__ import annotations

import math
from typing import Any

import pytest

from physics_mapper.model.geometry import Pose
from physics_mapper.model.scene import FixedFrame
from physics_mapper.model.scene_files import SceneError, scene_from_dict

CUBE = {"name": "part", "shape": "box", "size": [0.1, 0.1, 0.1]}


def scene_data(frames: Any) -> dict[str, Any]:
    return {"frame_id": "world", "objects": [CUBE], "frames": frames}


def test_fixed_frames_are_read_with_their_parents() -> None:
    half = math.sqrt(0.5)
    scene = scene_from_dict(
        scene_data(
            {
                "camera": {"position": [0.0, 0.0, 1.0], "orientation": [1.0, 0.0, 0.0, 0.0]},
                "camera_optical": {"parent": "camera", "position": [0.0, 0.0, 0.0], "orientation": [0, 0, half, half]},
                "wrist_camera": {"parent": "tool0", "position": [0.0, 0.05, 0.0]},  # tool0 comes from /tf
            }
        ),
        "cell.yaml",
    )
    assert scene.frames[0] == FixedFrame("camera", "world", Pose((0.0, 0.0, 1.0), (1.0, 0.0, 0.0, 0.0)))
    assert [(f.name, f.parent) for f in scene.frames[1:]] == [("camera_optical", "camera"), ("wrist_camera", "tool0")]
    assert scene_from_dict({"objects": [CUBE]}, "plain.yaml").frames == ()


@pytest.mark.parametrize(
    ("frames", "message"),
    [
        ({"world": {"position": [0, 0, 1]}}, "cell.yaml: frames.world: the scene's frame 'world' is the root"),
        (
            {"a": {"parent": "b", "position": [0, 0, 0]}, "b": {"parent": "a", "position": [0, 0, 0]}},
            "cell.yaml: frames.a: the parents loop: a -> b -> a",
        ),
        ({"camera": {"position": [0, 0, 1], "orientation": [0, 0, 0, 1.7]}}, "quaternion norm 1.7"),
        ({"camera": {"position": [0, 0, 1], "rotation": [0, 0, 0, 1]}}, "rotation"),
        ({"camera": {"orientation": [0, 0, 0, 1]}}, "position"),
    ],
)
def test_a_bad_frame_is_one_clear_error(frames: Any, message: str) -> None:
    with pytest.raises(SceneError) as error:
        scene_from_dict(scene_data(frames), "cell.yaml")
    assert message in str(error.value)
