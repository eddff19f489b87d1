"""The node fed by a pose estimator's ``vision_msgs/Detection3DArray`` over real DDS.

vision_msgs has no PyPI wheel: ``make test`` builds its detection messages into the venv
(``test/vision_msgs/``), as a ROS machine's apt package would provide them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from conftest import PROBLEMS, SCENES
from geometry_msgs.msg import Point, Pose, PoseWithCovariance, Quaternion, Vector3
from ros_helpers import NodeProcess, RosClient, stamp_ns_of
from std_msgs.msg import Header
from vision_msgs.msg import BoundingBox3D, Detection3D, Detection3DArray, ObjectHypothesis, ObjectHypothesisWithPose

from physics_mapper.model.scene_files import load_problem
from physics_mapper.msg_adapters.hypotheses import stamp_from_nanoseconds
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.search.strategy import solve

NAMESPACE = "/estimator"
STAMP_NS = 7_000_000_000


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


def test_detections_alone_give_the_map_the_problem_file_gives(tmp_path: Path) -> None:
    parameters = {"rate_hz": 4.0, "deadline": 0.2, "max_age": 60.0, "diagnostics_period": 0.25}
    node = NodeProcess(SCENES / "pyramid.yaml", parameters, tmp_path / "node.log", NAMESPACE)
    client = RosClient(NAMESPACE)
    try:
        publisher = client.node.create_publisher(Detection3DArray, "detections", 10)
        message = detections_of_problem()
        client.keep_publishing(
            lambda: publisher.publish(message),
            lambda: any(stamp_ns_of(c) == STAMP_NS for c in client.configurations),
            "a map from the detections",
        )
    finally:
        client.close()
        assert node.stop() == 0, node.output()
    problem = load_problem(PROBLEMS / "pyramid.yaml")
    with PhysicsChecker(problem.scene) as checker:
        expected = solve(checker, problem.hypotheses, problem.scene.search)
    assert expected.poses is not None
    mapped = next(c for c in client.configurations if stamp_ns_of(c) == STAMP_NS)
    chosen = [((p.position.x, p.position.y, p.position.z)) for p in mapped.poses]
    assert chosen == [pose.position for pose in expected.poses]  # the same hypotheses, chosen the same way
    started = next(line for line in node.output().splitlines() if "listening on" in line)
    assert f"{NAMESPACE}/detections" in started
