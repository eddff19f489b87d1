"""A bin of identical boxes fed to the node over real DDS as an estimator sees it: shuffled arrays,
no ids; ``~/objects`` (``vision_msgs/Detection3DArray``) names each box by its instance, frame after
frame. vision_msgs comes from ``make .venv/.vision_msgs`` (``test/vision_msgs/``)."""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest
from geometry_msgs.msg import Point, Pose, PoseWithCovariance, Quaternion, Vector3
from ros_helpers import NodeProcess, RosClient
from std_msgs.msg import Header
from vision_msgs.msg import BoundingBox3D, Detection3D, Detection3DArray, ObjectHypothesis, ObjectHypothesisWithPose

from physics_mapper.mapping.topics import OBJECTS_TOPIC, output_topic
from physics_mapper.msg_adapters.hypotheses import nanoseconds_from_stamp, stamp_from_nanoseconds
from physics_mapper.ros.qos import MAP_QOS

NAMESPACE = "/bin_camera"
#: Twelve 10 cm boxes, 4 x 3 on the floor, 1 cm apart.
BOXES = [(0.11 * (i % 4), 0.11 * (i // 4), 0.05) for i in range(12)]
FRAMES = 20


def box_scene(count: int, search: str = "") -> str:
    """A scene file of ``count`` identical 10 cm boxes on a floor, with a ``search:`` section's lines."""
    return f"""\
frame_id: world
static:
  - {{name: floor, shape: plane}}
objects:
  - {{name: box, count: {count}, shape: box, size: [0.1, 0.1, 0.1], mass: 0.2}}
{search}"""


SCENE = box_scene(12)


def result(position: np.ndarray, score: float) -> ObjectHypothesisWithPose:
    x, y, z = (float(v) for v in position)
    pose = Pose(position=Point(x=x, y=y, z=z), orientation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0))
    return ObjectHypothesisWithPose(
        hypothesis=ObjectHypothesis(class_id="box", score=score), pose=PoseWithCovariance(pose=pose)
    )


def frame(index: int, rng: np.random.Generator) -> Detection3DArray:
    """Every box detected once, in a new order, 2 mm of noise across and 0.5 mm in height (within Rule 1's
    5 mm), a second result 5 cm up; no ids."""
    header = Header(stamp=stamp_from_nanoseconds(stamp_of(index)), frame_id="world")
    detections = []
    for centre in BOXES:
        true = np.asarray(centre) + rng.normal(0.0, (0.002, 0.002, 0.0005))
        results = [result(true, 0.8), result(true + np.array([0.0, 0.0, 0.05]), 0.2)]
        box = BoundingBox3D(center=results[0].pose.pose, size=Vector3(x=0.1, y=0.1, z=0.1))
        detections.append(Detection3D(header=header, results=results, bbox=box, id=""))
    order = rng.permutation(len(detections))
    return Detection3DArray(header=header, detections=[detections[i] for i in order])


def stamp_of(index: int) -> int:
    return (index + 1) * 1_000_000_000


def nearest_box(detection: Detection3D) -> int:
    p = detection.results[0].pose.pose.position
    return int(np.argmin([np.linalg.norm(np.array([p.x, p.y, p.z]) - np.asarray(c)) for c in BOXES]))


def test_a_bin_of_identical_boxes_keeps_every_identity_over_shuffled_arrays(tmp_path: Path) -> None:
    """Each frame is published until a map of it holds every box (a tick whose search the deadline cut may
    leave tentative boxes out: that is no identity lost); every map published, whole or not, names each box
    as the first whole one did."""
    scene = tmp_path / "bin.yaml"
    scene.write_text(SCENE)
    parameters = {"rate_hz": 4.0, "deadline": 0.2, "max_age": 60.0, "association_gate": 0.04, "confirm_hits": 2}
    node = NodeProcess(scene, parameters, tmp_path / "node.log", NAMESPACE)
    client = RosClient(NAMESPACE)
    maps: defaultdict[int, list[Detection3DArray]] = defaultdict(list)
    rng = np.random.default_rng(31)
    try:
        publisher = client.node.create_publisher(Detection3DArray, "detections", 10)

        def on_objects(msg: Detection3DArray) -> None:
            maps[nanoseconds_from_stamp(msg.header.stamp)].append(msg)

        client.node.create_subscription(Detection3DArray, output_topic(OBJECTS_TOPIC, NAMESPACE), on_objects, MAP_QOS)
        for index in range(FRAMES):
            message = frame(index, rng)
            client.keep_publishing(
                lambda message=message: publisher.publish(message),  # type: ignore[misc]
                lambda index=index: bool(whole_maps(maps[stamp_of(index)])),  # type: ignore[misc]
                f"a map of frame {index} holding every box",
            )
    finally:
        client.close()
        assert node.stop() == 0, node.output()
    assert "unknown parameters" not in node.output()  # the association's parameters are the node's
    first = whole_maps(maps[stamp_of(0)])[0]
    identities = {d.id: nearest_box(d) for d in first.detections}
    assert sorted(identities) == sorted(f"box_{k}" for k in range(1, 13))
    assert sorted(identities.values()) == list(range(12))  # each box one instance
    for index in range(FRAMES):
        for msg in maps[stamp_of(index)]:  # and the same one in every map of every frame
            named = [(d.id, nearest_box(d)) for d in msg.detections]
            assert len({name for name, _ in named}) == len(named), f"frame {index}: a name twice"
            assert all(identities.get(name) == box for name, box in named), f"frame {index}: {named}"
    assert first.detections[0].results[0].hypothesis.class_id == "box"
    size = first.detections[0].bbox.size
    assert (size.x, size.y, size.z) == (0.1, 0.1, 0.1)


def whole_maps(maps: list[Detection3DArray]) -> list[Detection3DArray]:
    """The maps that hold every box."""
    return [msg for msg in maps if len(msg.detections) == len(BOXES)]


SUNK_SCENE = box_scene(1, "search:\n  fallback: refine\n")


@pytest.mark.parametrize(("tf_pose", "height"), [("settled", 0.05), ("chosen", 0.03)])
def test_objects_carry_the_pose_tf_has_the_refined_one_by_default(tmp_path: Path, tf_pose: str, height: float) -> None:
    """A box detected 2 cm into the floor, its only result: no valid configuration, so the map is the refined
    one, the box on the floor. ``~/objects`` carries it there, as ``~/settled_configuration`` and ``/tf`` do,
    not at the detection; with ``tf_pose: chosen``, at the detection, as ``~/configuration`` does."""
    scene = tmp_path / "sunk.yaml"
    scene.write_text(SUNK_SCENE)
    namespace = f"{NAMESPACE}_{tf_pose}"
    node = NodeProcess(scene, {"rate_hz": 4.0, "tf_pose": tf_pose}, tmp_path / "node.log", namespace)
    client = RosClient(namespace)
    maps: list[Detection3DArray] = []
    header = Header(stamp=stamp_from_nanoseconds(stamp_of(0)), frame_id="world")
    sunk = result(np.array([0.0, 0.0, 0.03]), 0.9)
    box = BoundingBox3D(center=sunk.pose.pose, size=Vector3(x=0.1, y=0.1, z=0.1))
    message = Detection3DArray(header=header, detections=[Detection3D(header=header, results=[sunk], bbox=box)])
    try:
        publisher = client.node.create_publisher(Detection3DArray, "detections", 10)
        client.node.create_subscription(Detection3DArray, output_topic(OBJECTS_TOPIC, namespace), maps.append, MAP_QOS)
        client.keep_publishing(lambda: publisher.publish(message), lambda: bool(maps and client.settled), "the map")
    finally:
        client.close()
        assert node.stop() == 0, node.output()
    (detection,) = maps[-1].detections
    assert detection.id == "box_1"
    assert detection.results[0].pose.pose.position.z == pytest.approx(height, abs=0.005)
    assert detection.bbox.center.position.z == pytest.approx(height, abs=0.005)
    assert client.settled[-1].poses[0].position.z == pytest.approx(0.05, abs=0.005)  # the refined map
