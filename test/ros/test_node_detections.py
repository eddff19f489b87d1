"""The node fed by a pose estimator's ``vision_msgs/Detection3DArray`` over real DDS.

The node subscribes to the serialised arrays and reads them without a Python object per result
(``physics_mapper.msg_adapters.detection_array_cdr``); bytes that view does not take go to rclpy's
deserialiser, and bytes neither reads are refused in the log. vision_msgs has no PyPI wheel: ``make
test`` builds its detection messages into the venv (``test/vision_msgs/``), as a ROS machine's apt
package would provide them.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
from conftest import PROBLEMS, SCENES
from geometry_msgs.msg import Point, Pose, PoseWithCovariance, Quaternion, Vector3
from rclpy.serialization import serialize_message
from ros_helpers import NodeProcess, RosClient
from std_msgs.msg import Header
from vision_msgs.msg import BoundingBox3D, Detection3D, Detection3DArray, ObjectHypothesis, ObjectHypothesisWithPose

from physics_mapper.bags.storage import TYPESTORE
from physics_mapper.mapping.detections import DETECTION_ARRAY
from physics_mapper.model.scene_files import load_problem
from physics_mapper.msg_adapters.hypotheses import stamp_from_nanoseconds
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.search.strategy import solve

NAMESPACE = "/estimator"
STAMP_NS = 7_000_000_000
OBJECTS = 3  # the pyramid's cubes


def pose_msg(position: tuple[float, float, float], orientation: tuple[float, float, float, float]) -> Pose:
    x, y, z = position
    qx, qy, qz, qw = orientation
    return Pose(position=Point(x=x, y=y, z=z), orientation=Quaternion(x=qx, y=qy, z=qz, w=qw))


def detections_of_problem() -> Detection3DArray:
    """The pyramid problem as a FoundationPose-style estimator would publish it: a Detection3D per
    object, each hypothesis a result with its weight as score, the class id the object's name."""
    problem = load_problem(PROBLEMS / "pyramid.yaml")
    header = Header(stamp=stamp_from_nanoseconds(STAMP_NS), frame_id="world")
    detections = []
    for name, hypotheses in zip(problem.scene.object_names, problem.hypotheses, strict=True):
        results = [
            ObjectHypothesisWithPose(
                hypothesis=ObjectHypothesis(class_id=name, score=h.weight),
                pose=PoseWithCovariance(pose=pose_msg(h.pose.position, h.pose.orientation), covariance=np.zeros(36)),
            )
            for h in hypotheses.hypotheses
        ]
        box = BoundingBox3D(center=results[0].pose.pose, size=Vector3(x=0.2, y=0.2, z=0.2))
        detections.append(Detection3D(header=header, results=results, bbox=box, id=name))
    return Detection3DArray(header=header, detections=detections)


#: The node's parameters in these tests: ticks at 4 Hz, hypotheses kept a minute.
PARAMETERS = {"rate_hz": 4.0, "deadline": 0.2, "max_age": 60.0, "diagnostics_period": 0.25}


def test_detections_alone_give_the_map_the_problem_file_gives(tmp_path: Path) -> None:
    node = NodeProcess(SCENES / "pyramid.yaml", PARAMETERS, tmp_path / "node.log", NAMESPACE)
    client = RosClient(NAMESPACE)
    try:
        publisher = client.node.create_publisher(Detection3DArray, "detections", 10)
        message = detections_of_problem()
        publish_until_mapped(client, lambda: publisher.publish(message), "a map from the detections")
    finally:
        client.close()
        assert node.stop() == 0, node.output()
    assert_the_problem_s_map(client)
    started = next(line for line in node.output().splitlines() if "listening on" in line)
    assert f"{NAMESPACE}/detections" in started


def publish_until_mapped(client: RosClient, publish: Callable[[], None], what: str) -> None:
    """Publish until the node's map of the array stamped STAMP_NS holds the problem's three objects."""
    client.keep_publishing(publish, lambda: client.map_of(STAMP_NS, OBJECTS) is not None, what)


def assert_the_problem_s_map(client: RosClient) -> None:
    """The map of the array stamped STAMP_NS is the one the problem file's hypotheses give."""
    problem = load_problem(PROBLEMS / "pyramid.yaml")
    with PhysicsChecker(problem.scene) as checker:
        expected = solve(checker, problem.hypotheses, problem.scene.search)
    assert expected.poses is not None
    mapped = client.map_of(STAMP_NS, OBJECTS)
    assert mapped is not None
    chosen = [((p.position.x, p.position.y, p.position.z)) for p in mapped.poses]
    assert chosen == [pose.position for pose in expected.poses]  # the same hypotheses, chosen the same way


def test_big_endian_arrays_map_the_same_and_bytes_no_reader_takes_are_refused_once(tmp_path: Path) -> None:
    little = serialize_message(detections_of_problem())
    message = TYPESTORE.deserialize_cdr(little, DETECTION_ARRAY)
    big = bytes(TYPESTORE.serialize_cdr(message, DETECTION_ARRAY, little_endian=False))
    refusal = "detections: Detection3DArray refused: 12 bytes that are no Detection3DArray ("
    node = NodeProcess(SCENES / "pyramid.yaml", PARAMETERS, tmp_path / "node.log", NAMESPACE)
    client = RosClient(NAMESPACE)
    try:
        publisher = client.node.create_publisher(Detection3DArray, "detections", 10)
        # 12 bytes: the transport pads a payload to a multiple of 4, and the node is handed those
        client.keep_publishing(lambda: publisher.publish(little[:12]), lambda: refusal in node.output(), "a refusal")
        publish_until_mapped(client, lambda: publisher.publish(big), "a map from big-endian detections")
    finally:
        client.close()
        assert node.stop() == 0, node.output()
    assert big[:2] == b"\x00\x00"  # CDR big-endian; rclpy writes this machine's little-endian
    assert_the_problem_s_map(client)
    assert node.output().count(refusal) == 1  # once, however many arrived
