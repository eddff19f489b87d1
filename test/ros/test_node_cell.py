"""The node in a robot cell, over real DDS: camera frames through TF, covariance, TF and map status out.

tf2_msgs and vision_msgs have no PyPI wheel: ``make test`` builds their messages into the venv
(``test/tf2_msgs/``, ``test/vision_msgs/``), as a ROS machine's apt packages would provide them.
Uses the shared helpers of test/ (``ros_helpers``).
"""

from __future__ import annotations

import math
import subprocess
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import REPO
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import (
    Point,
    Pose,
    PoseArray,
    PoseWithCovariance,
    Quaternion,
    Transform,
    TransformStamped,
    Vector3,
)
from lifecycle_msgs.msg import Transition
from rclpy.parameter import parameter_value_to_python
from rclpy.parameter_client import AsyncParameterClient
from ros_helpers import PHYSICS_MAPPER, Lifecycle, NodeProcess, RosClient, object_status, stamp_ns_of, values
from std_msgs.msg import Float64MultiArray, Header
from tf2_msgs.msg import TFMessage
from vision_msgs.msg import BoundingBox3D, Detection3D, Detection3DArray, ObjectHypothesis, ObjectHypothesisWithPose

from physics_mapper.mapping.topics import MAP_STATUS_TOPIC, TF_STATIC_TOPIC, TF_TOPIC
from physics_mapper.model.geometry import quaternion_about_axis
from physics_mapper.msg_adapters.hypotheses import stamp_from_nanoseconds
from physics_mapper.ros.qos import TF_QOS, TF_STATIC_QOS

SECOND = 1_000_000_000
#: A camera looking straight down: its z is the world's -z.
LOOKING_DOWN = quaternion_about_axis((1.0, 0.0, 0.0), math.pi)
#: A 10 cm cube on the floor rests with its centre 5 cm up.
RESTING = 0.05
SCENE = """
frame_id: world
static:
  - {name: floor, shape: plane}
objects:
  - {name: part, shape: box, size: [0.1, 0.1, 0.1], mass: 0.5}
search: {deadline: 0.15, fallback: settled}
"""
FAST = {"rate_hz": 4.0, "deadline": 0.15, "max_age": 60.0, "diagnostics_period": 0.25, "transform_timeout": 1.0}


def scene_file(folder: Path, extra: str = "") -> Path:
    path = folder / "cell.yaml"
    path.write_text(SCENE + extra)
    return path


@pytest.fixture
def cell(tmp_path: Path, request: pytest.FixtureRequest) -> Iterator[tuple[NodeProcess, RosClient]]:
    """The node on the one-cube scene (``request.param``: extra parameters), and a client in its namespace."""
    namespace = "/cell"
    parameters = {**FAST, **getattr(request, "param", {})}
    node = NodeProcess(scene_file(tmp_path), parameters, tmp_path / "node.log", namespace)
    client = RosClient(namespace)
    try:
        yield node, client
    finally:
        client.close()
        assert node.stop() == 0, node.output()


def transform(
    child: str, stamp_ns: int, position: tuple[float, float, float], rotation: Sequence[float] = LOOKING_DOWN
) -> TransformStamped:
    x, y, z = position
    qx, qy, qz, qw = rotation
    return TransformStamped(
        header=Header(frame_id="world", stamp=stamp_from_nanoseconds(stamp_ns)),
        child_frame_id=child,
        transform=Transform(translation=Vector3(x=x, y=y, z=z), rotation=Quaternion(x=qx, y=qy, z=qz, w=qw)),
    )


def detections(
    frame: str, stamp_ns: int, position: tuple[float, float, float], covariance: np.ndarray | None = None
) -> Detection3DArray:
    """One detection of the part, one result (a single-pose estimator's), in ``frame``."""
    x, y, z = position
    pose = Pose(position=Point(x=x, y=y, z=z), orientation=Quaternion(w=1.0))
    result = ObjectHypothesisWithPose(
        hypothesis=ObjectHypothesis(class_id="part", score=0.9),
        pose=PoseWithCovariance(pose=pose, covariance=np.zeros(36) if covariance is None else covariance.ravel()),
    )
    header = Header(frame_id=frame, stamp=stamp_from_nanoseconds(stamp_ns))
    box = BoundingBox3D(center=pose, size=Vector3(x=0.1, y=0.1, z=0.1))
    return Detection3DArray(header=header, detections=[Detection3D(header=header, results=[result], bbox=box)])


def mapped_position(client: RosClient, stamp_ns: int) -> tuple[float, float, float]:
    """The chosen position of the part in the map of ``stamp_ns``."""
    (pose,) = next(c for c in client.configurations if stamp_ns_of(c) == stamp_ns).poses
    return (pose.position.x, pose.position.y, pose.position.z)


def publish_until_mapped(client: RosClient, publish: Sequence[tuple[Any, Any]], stamp_ns: int) -> None:
    """Publish each (publisher, message) until a map of ``stamp_ns`` comes out."""

    def publish_all() -> None:
        for publisher, message in publish:
            publisher.publish(message)

    client.keep_publishing(
        publish_all,
        lambda: any(stamp_ns_of(c) == stamp_ns for c in client.configurations),
        f"a map stamped {stamp_ns}",
    )


@pytest.mark.parametrize("cell", [{}], indirect=True)
def test_a_camera_frame_detection_is_moved_by_the_static_transform(cell: tuple[NodeProcess, RosClient]) -> None:
    _node, client = cell
    static = client.node.create_publisher(TFMessage, TF_STATIC_TOPIC, TF_STATIC_QOS)
    static.publish(TFMessage(transforms=[transform("camera_color_optical_frame", 0, (0.0, 0.0, 1.0))]))
    found = client.node.create_publisher(Detection3DArray, "detections", 10)
    stamp = 5 * SECOND
    # 95 cm in front of a camera 1 m up, looking down: 5 cm above the floor, y mirrored.
    message = detections("camera_color_optical_frame", stamp, (0.1, 0.2, 0.95))
    publish_until_mapped(client, [(found, message)], stamp)
    assert mapped_position(client, stamp) == pytest.approx((0.1, -0.2, RESTING), abs=1e-9)
    assert next(c for c in client.configurations if stamp_ns_of(c) == stamp).header.frame_id == "world"
    status = client.latched(DiagnosticArray, MAP_STATUS_TOPIC)
    client.wait_for(lambda: any(s.header.stamp == stamp_from_nanoseconds(stamp) for s in status), what="map status")
    (valid,) = next(s for s in status if s.header.stamp == stamp_from_nanoseconds(stamp)).status
    assert (valid.level, valid.message) == (DiagnosticStatus.OK, "valid")
    assert values(valid) == {"valid": "true", "fallback": "none", "code": "C1", "objects": "part"}
    # A PoseArray in the camera frame takes the same way.
    later = 6 * SECOND
    header = Header(frame_id="camera_color_optical_frame", stamp=stamp_from_nanoseconds(later))
    seen = PoseArray(header=header, poses=[Pose(position=Point(x=-0.1, y=0.0, z=0.95), orientation=Quaternion(w=1.0))])
    client.keep_publishing(
        lambda: client.publish("part", seen, Float64MultiArray(data=[1.0])),
        lambda: any(stamp_ns_of(c) == later for c in client.configurations),
        "a map from the PoseArray",
    )
    assert mapped_position(client, later) == pytest.approx((-0.1, 0.0, RESTING), abs=1e-9)


@pytest.mark.parametrize("cell", [{}], indirect=True)
def test_an_eye_in_hand_camera_moves_on_tf_and_stamps_between_samples_are_interpolated(
    cell: tuple[NodeProcess, RosClient],
) -> None:
    _node, client = cell
    tf = client.node.create_publisher(TFMessage, TF_TOPIC, TF_QOS)
    moving = TFMessage(
        transforms=[
            transform("wrist_camera", 10 * SECOND, (0.0, 0.0, 1.0)),
            transform("wrist_camera", 12 * SECOND, (0.4, 0.0, 1.0)),
        ]
    )
    found = client.node.create_publisher(Detection3DArray, "detections", 10)
    at_end = detections("wrist_camera", 12 * SECOND, (0.0, 0.0, 0.95))
    publish_until_mapped(client, [(tf, moving), (found, at_end)], 12 * SECOND)
    assert mapped_position(client, 12 * SECOND) == pytest.approx((0.4, 0.0, RESTING), abs=1e-9)
    between = 11 * SECOND + SECOND // 4  # five eighths of the way from the first sample to the second
    in_between = detections("wrist_camera", between, (0.0, 0.0, 0.95))
    publish_until_mapped(client, [(tf, moving), (found, in_between)], between)
    assert mapped_position(client, between) == pytest.approx((0.25, 0.0, RESTING), abs=1e-9)


@pytest.mark.parametrize("cell", [{"transform_timeout": 0.3}], indirect=True)
def test_a_detection_without_a_transform_is_refused_and_logged(cell: tuple[NodeProcess, RosClient]) -> None:
    node, client = cell
    found = client.node.create_publisher(Detection3DArray, "detections", 10)
    client.wait_for(lambda: found.get_subscription_count() > 0, what="the node's detections subscription")
    message = detections("uncalibrated_camera", 3 * SECOND, (0.0, 0.0, 0.95))
    why = "no transform from 'uncalibrated_camera' to 'world': frame 'uncalibrated_camera' is unknown (waited 0.3 s)"

    def refused() -> bool:
        diagnostics = client.diagnostics[-1] if client.diagnostics else None
        return diagnostics is not None and why in object_status(diagnostics, "part").message

    client.keep_publishing(lambda: found.publish(message), refused, "the refusal in the diagnostics")
    assert object_status(client.diagnostics[-1], "part").message == f"detection refused: {why}"
    client.wait_for(lambda: f"part: detection refused: {why}" in node.output(), what="the refusal's log line")
    assert node.output().count(f"part: detection refused: {why}") == 1  # once, however many arrive
    assert client.configurations == []


def test_a_single_pose_with_covariance_sunk_into_the_floor_takes_a_valid_alternative(tmp_path: Path) -> None:
    """The camera is a fixed frame of the scene file (no TF at all); its z is the world's -z."""
    frames = "frames:\n  camera: {position: [0.0, 0.0, 1.0], orientation: [1.0, 0.0, 0.0, 0.0]}\n"
    node = NodeProcess(scene_file(tmp_path, frames), FAST, tmp_path / "node.log", "/covariance")
    client = RosClient("/covariance")
    try:
        found = client.node.create_publisher(Detection3DArray, "detections", 10)
        covariance = np.diag([0.0, 0.0, 0.01**2, 0.0, 0.0, 0.0])  # 1 cm along the camera's z: the world's z
        stamp = 4 * SECOND
        sunk = detections("camera", stamp, (0.0, 0.0, 0.97), covariance)  # 2 cm into the floor
        publish_until_mapped(client, [(found, sunk)], stamp)
        client.wait_for(
            lambda: any(values(d.status[0]).get("valid") == "true" for d in client.diagnostics[-1:]),
            what="a valid map",
        )
    finally:
        client.close()
        assert node.stop() == 0, node.output()
    x, y, z = mapped_position(client, stamp)
    assert (x, y) == pytest.approx((0.0, 0.0), abs=1e-9)
    assert z == pytest.approx(RESTING, abs=1e-9)  # the mean 2 sigma up, out of the floor
    assert values(client.diagnostics[-1].status[0])["best code"] != "C1"  # not the mean, ranked first


@pytest.mark.parametrize("cell", [{"publish_tf": True, "tf_prefix": "cell/"}], indirect=True)
def test_tf_carries_every_object_and_a_fallback_map_is_marked(cell: tuple[NodeProcess, RosClient]) -> None:
    _node, client = cell
    frames: list[TFMessage] = []
    client.node.create_subscription(TFMessage, TF_TOPIC, frames.append, TF_QOS)
    status = client.latched(DiagnosticArray, MAP_STATUS_TOPIC)
    client.wait_for(lambda: bool(status), what="the map status before the first map")
    assert (status[0].status[0].message, values(status[0].status[0])["objects"]) == ("no map yet", "part")
    weights = Float64MultiArray(data=[1.0])
    header = Header(frame_id="world", stamp=stamp_from_nanoseconds(6 * SECOND))
    flying = PoseArray(header=header, poses=[Pose(position=Point(z=0.3), orientation=Quaternion(w=1.0))])
    client.keep_publishing(
        lambda: client.publish("part", flying, weights),
        lambda: any(stamp_ns_of(c) == 6 * SECOND for c in client.configurations),
        "the fallback map",
    )
    client.wait_for(lambda: any(s.status[0].message == "fallback settled" for s in status), what="fallback status")
    fallback = next(s for s in status if s.status[0].message == "fallback settled")
    assert fallback.header.stamp == stamp_from_nanoseconds(6 * SECOND)
    assert values(fallback.status[0])["valid"] == "false" and fallback.status[0].level == DiagnosticStatus.WARN
    client.wait_for(lambda: bool(frames), what="the objects' frames on /tf")
    (part,) = frames[-1].transforms
    assert (part.header.frame_id, part.child_frame_id) == ("world", "cell/part")
    assert part.transform.translation.z == pytest.approx(RESTING, abs=0.005)  # fallen onto the floor


def test_scene_file_is_refused_before_configure_and_configure_loads_the_given_one(tmp_path: Path) -> None:
    """A read-only parameter refuses changes in every state, also while the managed node is unconfigured."""
    node = NodeProcess(scene_file(tmp_path), FAST, tmp_path / "node.log", "/managed", managed=True)
    client = RosClient("/managed")
    try:
        assert client.set_parameter("scene_file", str(REPO / "config/scenes/pyramid.yaml")) == (
            False,
            "scene_file is read-only: read once, when the node is configured (restart the node to change it)",
        )
        assert client.set_parameter("deadline", 0.1)[0]  # others are judged at configure, and kept
        assert Lifecycle(client, "/managed").change(Transition.TRANSITION_CONFIGURE)
        assert client.get_parameters("scene_file", "deadline") == [str(tmp_path / "cell.yaml"), 0.1]
        assert client.set_parameter("input_reliability", "reliable")[0] is False
    finally:
        client.close()
        assert node.stop() == 0, node.output()
    assert "objects part in frame 'world'" in node.output()


def test_a_renamed_node_runs_with_the_shipped_parameters_file(tmp_path: Path) -> None:
    """The file's key is /**: it applies to the node it is given to, whatever its name."""
    params = REPO / "config" / "params" / "node.yaml"
    log = (tmp_path / "node.log").open("w")
    command = [str(PHYSICS_MAPPER), "node", "--ros-args", "--params-file", str(params)]
    command += ["-r", "__node:=mapper", "-r", "__ns:=/renamed"]
    process = subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT, text=True)
    client = RosClient("/renamed")
    try:
        parameters = AsyncParameterClient(client.node, "/renamed/mapper")
        client.wait_for(lambda: parameters.wait_for_services(timeout_sec=0.1), what="the renamed node's parameters")
        names = ["deadline", "rate_hz", "fallback", "penetration_threshold", "scene_file"]
        # A request sent before the service's reply writer matched this client is lost: sent again until answered.
        answer = client.answered(lambda: parameters.get_parameters(names), "its parameters")
        got = [parameter_value_to_python(v) for v in answer.values]
    finally:
        client.close()
        process.send_signal(2)
        code = process.wait(timeout=30)
        log.close()
    assert got == [0.3, 2.0, "none", 0.005, "package://physics_mapper/config/scenes/pyramid.yaml"]
    assert code == 0


@pytest.mark.parametrize("cell", [{}], indirect=True)
def test_poses_dropped_at_a_tick_and_missing_weights_are_logged_once(cell: tuple[NodeProcess, RosClient]) -> None:
    """Refusals only a tick finds (a pose's quaternion, a pose far outside the workspace, no weights)."""
    node, client = cell
    header = Header(frame_id="world", stamp=stamp_from_nanoseconds(2 * SECOND))
    poses = [
        Pose(position=Point(z=RESTING), orientation=Quaternion(w=1.0)),
        Pose(position=Point(z=RESTING), orientation=Quaternion(w=1.7)),
        Pose(position=Point(x=86.0, z=RESTING), orientation=Quaternion(w=1.0)),
    ]
    client.keep_publishing(
        lambda: client.publish("part", PoseArray(header=header, poses=poses)),
        lambda: any(stamp_ns_of(c) == 2 * SECOND for c in client.configurations),
        "a map from the usable pose",
    )
    uniform = "part: no weights message: uniform weights, ranked in published order"
    client.wait_for(lambda: uniform in node.output(), what="the uniform weights' log line")
    (dropped,) = [line for line in node.output().splitlines() if "part: dropped 2 of 3 poses" in line]
    assert "poses[1]: quaternion norm 1.7 is not 1" in dropped
    assert "poses[2]: (86, 0, 0.05) m is outside the workspace" in dropped
    assert node.output().count(uniform) == 1
