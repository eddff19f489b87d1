"""Scored detections (``vision_msgs/Detection3DArray``) as hypotheses: the rules, scene class maps, and bags.

The rules are :func:`detection_inputs`, tested here on the messages rosbags decodes (the association of
instances across frames in mapping/test_association.py); the bag path runs end to end (generate, replay,
evaluate); the node's live subscription is test_node_detections.py's.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import SCENES
from rosbags.rosbag2 import Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from physics_mapper.bags.storage import TYPESTORE, detections_from_cdr, read_bag
from physics_mapper.bags.vision_msgs import DEFINITIONS
from physics_mapper.cli import main
from physics_mapper.evaluation.snapshots import bag_snapshots
from physics_mapper.mapping.detections import DETECTION_ARRAY, RECORDED_DETECTIONS_TOPIC, detection_inputs
from physics_mapper.model.scene import Scene
from physics_mapper.model.scene_files import SceneError, load_scene, scene_from_dict

TYPES = TYPESTORE.types
PYRAMID = SCENES / "pyramid.yaml"
GENERATE = ["--runs", "1", "--sigma", "0.005", "--sigma-rotation", "0.005", "--seed", "1", "--iterations", "4"]


def header(frame_id: str = "world", sec: int = 1) -> Any:
    return TYPES["std_msgs/msg/Header"](
        stamp=TYPES["builtin_interfaces/msg/Time"](sec=sec, nanosec=0), frame_id=frame_id
    )


def result(class_id: str, score: float, z: float) -> Any:
    pose = TYPES["geometry_msgs/msg/Pose"](
        position=TYPES["geometry_msgs/msg/Point"](x=0.0, y=0.0, z=z),
        orientation=TYPES["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
    )
    return TYPES["vision_msgs/msg/ObjectHypothesisWithPose"](
        hypothesis=TYPES["vision_msgs/msg/ObjectHypothesis"](class_id=class_id, score=score),
        pose=TYPES["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
    )


def detection(*results: Any, frame_id: str = "") -> Any:
    box = TYPES["vision_msgs/msg/BoundingBox3D"](
        center=results[0].pose.pose, size=TYPES["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
    )
    return TYPES["vision_msgs/msg/Detection3D"](header=header(frame_id), results=list(results), bbox=box, id="")


def array(*detections: Any, frame_id: str = "world") -> Any:
    return TYPES[DETECTION_ARRAY](header=header(frame_id), detections=list(detections))


def scene_with(class_map: dict[str, Any] | None = None) -> Scene:
    cubes = [{"name": n, "shape": "box", "size": [0.1, 0.1, 0.1], "mass": 0.5} for n in ("a", "b", "c")]
    data: dict[str, Any] = {"objects": cubes, "static": [{"name": "floor", "shape": "plane"}]}
    if class_map is not None:
        data["class_map"] = class_map
    return scene_from_dict(data, "test scene")


def heights(inputs: Any, name: str) -> list[float]:
    return [float(row[2]) for row in inputs.objects[name].poses]


def test_a_class_id_naming_an_object_gives_it_every_result_of_that_class_with_its_score() -> None:
    message = array(
        detection(result("a", 0.7, 0.05), result("a", 0.1, 0.07)),
        detection(result("a", 0.3, 0.06)),
        detection(result("b", 0.2, 0.3)),
    )
    inputs = detection_inputs(message, scene_with(), received=2.0)
    assert sorted(inputs.objects) == ["a", "b"]  # c, not detected, keeps what it has
    assert heights(inputs, "a") == [0.05, 0.07, 0.06]
    weights = inputs.objects["a"].weights
    assert weights is not None and weights.values.tolist() == [0.7, 0.1, 0.3]
    assert inputs.objects["a"].refusal is None and inputs.objects["a"].stamp_ns == 1_000_000_000
    assert inputs.unused == ()


def test_a_class_of_several_objects_gives_each_detection_to_one_instance() -> None:
    scene = scene_with({"cube": ["b", "c"], "first": "a"})
    message = array(
        detection(result("cube", 1.0, 0.1)),
        detection(result("cube", 1.0, 0.3)),
        detection(result("cube", 1.0, 0.5)),
        detection(result("first", 1.0, 0.4), result("mug", 0.5, 0.5)),
    )
    inputs = detection_inputs(message, scene, received=0.0)
    assert (heights(inputs, "b"), heights(inputs, "c"), heights(inputs, "a")) == ([0.1], [0.3], [0.4])
    assert inputs.unused == (
        "class id 'mug' is no object of the scene",
        "1 detection(s) of class 'cube' outside every gate, with no free instance",
    )
    assert "a" not in scene.objects_of_class("a")  # mapped: its own name is no class id any more


def test_the_frame_is_the_detection_s_else_the_array_s_and_must_be_the_scene_s() -> None:
    scene = scene_with()
    own = detection_inputs(array(detection(result("a", 1.0, 0.1), frame_id="camera")), scene, received=0.0)
    assert own.objects["a"].refusal == "frame_id 'camera' is not the scene frame 'world'"
    inherited = detection_inputs(array(detection(result("a", 1.0, 0.1)), frame_id="camera"), scene, received=0.0)
    assert inherited.objects["a"].refusal == "frame_id 'camera' is not the scene frame 'world'"
    unnamed = detection_inputs(array(detection(result("a", 1.0, 0.1)), frame_id=""), scene, received=0.0)
    assert unnamed.objects["a"].refusal is None and unnamed.objects["a"].frame_assumed


@pytest.mark.parametrize(
    ("class_map", "problem"),
    [
        ({"cube": ["a", "z"]}, "class_map.cube: 'z' is not an object of the scene"),
        ({"cube": ["a"], "box": "a"}, "class_map.box: 'a' is already the object of class 'cube'"),
        ({"cube": []}, "class_map.cube: needs at least one object"),
    ],
)
def test_a_bad_class_map_is_one_error(class_map: dict[str, Any], problem: str) -> None:
    with pytest.raises(SceneError, match="^test scene: " + problem.replace(".", r"\.").replace("'", "'")):
        scene_with(class_map)


def generated(tmp_path: Path, name: str, *extra: str) -> Path:
    assert main(["generate", str(PYRAMID), "-o", str(tmp_path / name), *GENERATE, *extra]) == 0
    return tmp_path / name


def replayed(bag: Path, tmp_path: Path) -> list[Any]:
    out = tmp_path / f"{bag.name}.json"
    assert main(["replay", str(bag), "--scene", str(PYRAMID), "--offline", "--exhaustive", "--json", str(out)]) == 0
    return list(json.loads(out.read_text())["snapshots"])


def test_detections_from_a_bag_map_as_the_same_hypotheses_as_pose_arrays(tmp_path: Path) -> None:
    detections = generated(tmp_path, "detections", "--format", "detections")
    assert set(read_bag(detections).topics) == {RECORDED_DETECTIONS_TOPIC, "/ground_truth"}
    poses = replayed(generated(tmp_path, "pose_arrays"), tmp_path)
    assert [s["code"] for s in replayed(detections, tmp_path)] == [s["code"] for s in poses] and len(poses) == 4
    report = tmp_path / "report"
    assert main(["evaluate", str(detections), "--scene", str(PYRAMID), "-o", str(report), "--workers", "0"]) == 0
    assert json.loads((report / "report.json").read_text())["counts"]["evaluated"] == 1


def test_a_bag_s_own_definition_of_the_detections_is_the_one_decoded(tmp_path: Path) -> None:
    """An estimator's vision_msgs may differ from ours (here Detection3D has one more field): the bag says how."""
    typestore = get_typestore(Stores.ROS2_JAZZY)
    definitions = {
        **DEFINITIONS,
        "vision_msgs/msg/Detection3D": DEFINITIONS["vision_msgs/msg/Detection3D"] + "bool is_tracking\n",
    }
    for name, text in definitions.items():
        typestore.register(get_types_from_msg(text, name))
    types = typestore.types
    pose = TYPES["geometry_msgs/msg/Pose"](
        position=TYPES["geometry_msgs/msg/Point"](x=0.0, y=0.0, z=0.1),
        orientation=TYPES["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
    )
    results = [
        types["vision_msgs/msg/ObjectHypothesisWithPose"](
            hypothesis=types["vision_msgs/msg/ObjectHypothesis"](class_id=name, score=1.0),
            pose=types["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
        )
        for name in ("cube_left", "cube_right", "cube_top")
    ]
    box = types["vision_msgs/msg/BoundingBox3D"](center=pose, size=TYPES["geometry_msgs/msg/Vector3"](x=0, y=0, z=0))
    detected = [
        types["vision_msgs/msg/Detection3D"](header=header(), results=[one], bbox=box, id="", is_tracking=True)
        for one in results
    ]
    message = types[DETECTION_ARRAY](header=header(), detections=detected)
    with Writer(tmp_path / "bag", version=8) as writer:
        connection = writer.add_connection(RECORDED_DETECTIONS_TOPIC, DETECTION_ARRAY, typestore=typestore)
        writer.write(connection, 1_000, typestore.serialize_cdr(message, DETECTION_ARRAY))
    bag = read_bag(tmp_path / "bag")
    (snapshot,) = bag_snapshots(bag, load_scene(PYRAMID))
    assert [len(h) for h in snapshot.hypotheses] == [1, 1, 1]
    decoded = detections_from_cdr(bag.on(RECORDED_DETECTIONS_TOPIC)[0].raw, bag.definitions)
    assert decoded.detections[0].is_tracking  # the field only the bag's definition has
