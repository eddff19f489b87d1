"""Replay: a bag written here with rosbags goes into a live node (subprocess, real DDS) and into the core offline.

The bag holds three snapshots of two hypotheses per pyramid cube. In each, exactly one
configuration is physically valid: a cube 2 cm into the floor, a cube pushed 2 cm into its
neighbour, or a top cube hovering 3 cm high invalidates every other one. So the expected code of
each snapshot is known, and the live node and the offline search must both find it. The cubes
are turned by random rotations that leave them resting on a face, with quaternions that a
second normalisation changes in the last bits, as a round trip through the node does. Like a
bag recorded with ``ros2 bag record -a`` while a node ran, it also holds an old run's outputs.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import REPO, SCENES
from ros_helpers import NodeProcess, run_cli
from rosbags.rosbag2 import Reader, StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore
from scipy.spatial.transform import Rotation

from physics_mapper.bags import evaluation, storage
from physics_mapper.bags.snapshots import BagSnapshot, bag_snapshots
from physics_mapper.core.geometry import Pose, Quaternion, make_pose, rotation_angle
from physics_mapper.core.hypotheses import Hypothesis, RankedHypotheses
from physics_mapper.core.scene_files import load_scene
from physics_mapper.mapping import topics

TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
POSE_ARRAY = "geometry_msgs/msg/PoseArray"
WEIGHTS = "std_msgs/msg/Float64MultiArray"
MARKER_ARRAY = "visualization_msgs/msg/MarkerArray"
MARKERS = "/physics_mapper/markers"
SCENE = SCENES / "pyramid.yaml"
NAMES = ("cube_left", "cube_right", "cube_top")
TRUTH = load_scene(SCENE).ground_truth or ()


def moved(pose: Pose, dx: float = 0.0, dz: float = 0.0) -> Pose:
    x, y, z = pose.position
    return replace(pose, position=(x + dx, y, z + dz))


def renormalising_moves(orientation: Quaternion) -> bool:
    """Whether normalising a normalised quaternion again turns it by more than 1e-9 rad (in float arithmetic)."""
    once = make_pose((0.0, 0.0, 0.0), orientation).orientation
    return rotation_angle(once, make_pose((0.0, 0.0, 0.0), once).orientation) > 1e-9


def resting_orientation(rng: np.random.Generator, max_yaw: float) -> Quaternion:
    """A random rotation of a cube that leaves it resting on a face: one of its 24 symmetries, a yaw
    within +-max_yaw (rad) and a tilt of about a milliradian. Drawn again until the quaternion is
    one whose second normalisation moves it (a few in 10000 are)."""
    symmetries = Rotation.create_group("O")
    while True:
        tilt = Rotation.from_rotvec(rng.normal(0.0, 1e-3, 3))
        yaw = Rotation.from_euler("z", rng.uniform(-max_yaw, max_yaw))
        x, y, z, w = (float(v) for v in (tilt * yaw * symmetries[int(rng.integers(len(symmetries)))]).as_quat())
        if renormalising_moves((x, y, z, w)):
            return (x, y, z, w)


# The cubes on the floor stand 1 cm apart; yaws of 1 degree narrow the gap by at most 0.35 cm.
_RNG = np.random.default_rng(2024)
ORIENTATIONS = tuple(resting_orientation(_RNG, max_yaw) for max_yaw in (0.0175, 0.0175, np.pi))
GOOD = tuple(replace(pose, orientation=q) for pose, q in zip(TRUTH, ORIENTATIONS, strict=True))
BAD = (moved(GOOD[0], dz=-0.02), moved(GOOD[1], dx=-0.03), moved(GOOD[2], dz=0.03))
#: An old run's configuration, 1 m off to the side: no configuration the node chooses from the bag.
STALE = tuple(moved(pose, dx=1.0) for pose in TRUTH)
# Per snapshot and object: the weights of (good, bad); a heavier bad hypothesis is ranked first.
SNAPSHOTS = (
    ((0.4, 0.6), (0.7, 0.3), (0.8, 0.2)),
    ((0.9, 0.1), (0.45, 0.55), (0.4, 0.6)),
    ((0.6, 0.4), (0.6, 0.4), (0.6, 0.4)),
)
EXPECTED_CODES = [[2, 1, 1], [1, 2, 2], [1, 1, 1]]
SPACING_NS = 2_000_000_000  # bag time between snapshots: the node resumes its search a few ticks on each
#: Stamp and bag time of the first snapshot: a realistic epoch time, where float seconds would lose nanoseconds.
FIRST_NS = 1_732_233_600_123_456_789
NAMESPACE = "/replay_test"


def pose_array(stamp_ns: int, poses: list[Pose]) -> Any:
    types = TYPESTORE.types
    stamp = types["builtin_interfaces/msg/Time"](sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9)
    return types[POSE_ARRAY](
        header=types["std_msgs/msg/Header"](stamp=stamp, frame_id="world"),
        poses=[
            types["geometry_msgs/msg/Pose"](
                position=types["geometry_msgs/msg/Point"](*pose.position),
                orientation=types["geometry_msgs/msg/Quaternion"](*pose.orientation),
            )
            for pose in poses
        ],
    )


def weights(values: list[float]) -> Any:
    types = TYPESTORE.types
    layout = types["std_msgs/msg/MultiArrayLayout"](dim=[], data_offset=0)
    return types[WEIGHTS](layout=layout, data=np.array(values, dtype=np.float64))


@pytest.fixture(scope="module")
def handmade_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The three snapshots, written with rosbags directly (not by ``generate``), hypotheses in published order."""
    path = tmp_path_factory.mktemp("bags") / "handmade"
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        connections = {
            topic: writer.add_connection(topic, msgtype, typestore=TYPESTORE)
            for name in NAMES
            for topic, msgtype in ((f"/hypotheses/{name}", POSE_ARRAY), (f"/hypotheses/{name}/weights", WEIGHTS))
        }
        for topic in ("/ground_truth", topics.RECORDED_CONFIGURATION_TOPIC, topics.RECORDED_SETTLED_TOPIC):
            connections[topic] = writer.add_connection(topic, POSE_ARRAY, typestore=TYPESTORE)
        connections[MARKERS] = writer.add_connection(MARKERS, MARKER_ARRAY, typestore=TYPESTORE)

        def write(topic: str, time_ns: int, message: Any) -> None:
            writer.write(connections[topic], time_ns, TYPESTORE.serialize_cdr(message, connections[topic].msgtype))

        for index, snapshot in enumerate(SNAPSHOTS):
            stamp = FIRST_NS + index * SPACING_NS
            for offset, (name, (good_weight, bad_weight), good, bad) in enumerate(
                zip(NAMES, snapshot, GOOD, BAD, strict=True)
            ):
                order = [(good, good_weight), (bad, bad_weight)]
                order.sort(key=lambda item: -item[1])
                write(f"/hypotheses/{name}", stamp + 1000 * offset, pose_array(stamp, [p for p, _ in order]))
                write(f"/hypotheses/{name}/weights", stamp + 1000 * offset + 1, weights([w for _, w in order]))
            write("/ground_truth", stamp + 5000, pose_array(stamp, list(TRUTH)))
            # The old run's outputs, stamped like the node's new ones will be.
            write(topics.RECORDED_CONFIGURATION_TOPIC, stamp + 300_000_000, pose_array(stamp, list(STALE)))
            write(topics.RECORDED_SETTLED_TOPIC, stamp + 300_000_001, pose_array(stamp, list(STALE)))
            write(MARKERS, stamp + 300_000_002, TYPESTORE.types[MARKER_ARRAY](markers=[]))
    return path


def codes(json_path: Path) -> list[list[int] | None]:
    return [snapshot["code"] for snapshot in json.loads(json_path.read_text())["snapshots"]]


def recorded(path: Path) -> dict[str, list[Any]]:
    """Messages of a recorded bag by topic, read with rosbags alone."""
    messages: dict[str, list[Any]] = {}
    with Reader(path) as reader:
        for connection, _, raw in reader.messages():
            messages.setdefault(connection.topic, []).append(TYPESTORE.deserialize_cdr(raw, connection.msgtype))
    return messages


def test_recorded_topic_names_are_those_the_node_resolves_in_the_root_namespace() -> None:
    assert topics.recorded("hypotheses/a") == topics.recorded("/hypotheses/a") == "/hypotheses/a"
    assert (
        topics.recorded_poses_topic("a") == "/hypotheses/a"
        and topics.recorded_weights_topic("a") == "/hypotheses/a/weights"
    )
    assert topics.RECORDED_CONFIGURATION_TOPIC == "/physics_mapper/configuration"
    assert topics.RECORDED_SETTLED_TOPIC == "/physics_mapper/settled_configuration"
    assert topics.DIAGNOSTICS_TOPIC == "/diagnostics"
    assert topics.output_topic(topics.CONFIGURATION_TOPIC, "/robot1") == "/robot1/physics_mapper/configuration"


@pytest.fixture(scope="module")
def offline(handmade_bag: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[Any, Path, Path]:
    folder = tmp_path_factory.mktemp("offline")
    args = ["replay", str(handmade_bag), "--scene", str(SCENE), "--offline", "--exhaustive"]
    completed = run_cli(*args, "-o", str(folder / "out"), "--json", str(folder / "result.json"))
    return completed, folder / "out", folder / "result.json"


def test_code_of_recognises_published_poses_after_a_cdr_round_trip() -> None:
    """Random poses come back through CDR and make_pose; near twins 1 um or 1e-5 rad away stay apart."""
    rng = np.random.default_rng(5)
    hypotheses, chosen, code = [], [], []
    for _ in range(1000):
        quaternion = rng.normal(size=4)
        pose = make_pose(tuple(rng.uniform(-1.0, 1.0, 3)), tuple(quaternion / np.linalg.norm(quaternion)))
        turned = (Rotation.from_rotvec([1e-5, 0.0, 0.0]) * Rotation.from_quat(pose.orientation)).as_quat()
        twins = [moved(pose, dx=1e-6), make_pose(pose.position, tuple(turned))]
        rank = int(rng.integers(1, 4))
        twins.insert(rank - 1, pose)
        hypotheses.append(RankedHypotheses.from_weighted([Hypothesis(p, 1.0) for p in twins]))  # ties keep order
        chosen.append(pose)
        code.append(rank)
    published = storage.pose_array_from_cdr(storage.pose_array_cdr(0, "world", chosen)).checked_poses()
    assert evaluation.code_of(published, hypotheses) == tuple(code)
    assert evaluation.code_of([moved(published[0], dz=1e-8), *published[1:]], hypotheses) is None


def test_offline_replay_finds_the_valid_configurations(offline: tuple[Any, Path, Path]) -> None:
    completed, _, result = offline
    assert completed.returncode == 0, completed.stderr
    assert codes(result) == EXPECTED_CODES
    assert "3 snapshots, 3 with a configuration: C111 in 1, another configuration in 2" in completed.stdout


def test_offline_output_bag_holds_the_chosen_poses(offline: tuple[Any, Path, Path]) -> None:
    _, out, _ = offline
    messages = recorded(out)
    configurations = messages[topics.RECORDED_CONFIGURATION_TOPIC]
    assert len(configurations) == len(messages[topics.RECORDED_SETTLED_TOPIC]) == 3
    first = configurations[0]
    assert [p.position.z for p in first.poses] == pytest.approx([t.position[2] for t in TRUTH])


def test_replay_without_a_node_says_so(handmade_bag: Path, tmp_path: Path) -> None:
    # A domain of its own, so that no node started by another test can answer.
    domain = str((int(os.environ["ROS_DOMAIN_ID"]) + 101) % 233)
    command = [sys.executable, "-m", "physics_mapper", "replay", str(handmade_bag), "--scene", str(SCENE)]
    completed = subprocess.run(
        [*command, "--wait", "2", "-o", str(tmp_path / "out")],
        env={**os.environ, "ROS_DOMAIN_ID": domain},
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert completed.returncode == 1
    assert "physics-mapper replay: error: no node is listening on /hypotheses/cube_left" in completed.stderr
    assert "Traceback" not in completed.stderr


@pytest.fixture(scope="module")
def live(handmade_bag: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[Any, Path, Path]:
    """The handmade bag replayed into a node started by the test, recorded into a new bag."""
    folder = tmp_path_factory.mktemp("live")
    node = NodeProcess(SCENE, {}, folder / "node.log", NAMESPACE)
    try:
        completed = run_cli(
            "replay",
            str(handmade_bag),
            "--scene",
            str(SCENE),
            "-o",
            str(folder / "out"),
            "--json",
            str(folder / "result.json"),
            "--namespace",
            NAMESPACE,
            "--wait",
            "60",
            timeout=180,
        )
        assert node.alive, node.output()
    finally:
        node.stop()
    return completed, folder / "out", folder / "result.json"


def test_live_replay_yields_configurations_recorded_in_the_output_bag(live: tuple[Any, Path, Path]) -> None:
    completed, out, _ = live
    assert completed.returncode == 0, completed.stderr
    messages = recorded(out)
    stamps = {
        m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for m in messages[topics.RECORDED_CONFIGURATION_TOPIC]
    }
    assert {FIRST_NS + k * SPACING_NS for k in range(3)} <= stamps
    assert all(len(m.poses) == 3 for m in messages[topics.RECORDED_CONFIGURATION_TOPIC])
    assert messages[topics.RECORDED_SETTLED_TOPIC]
    assert any(status.name.startswith("physics_mapper") for m in messages["/diagnostics"] for status in m.status)


def made_of_hypotheses(poses: list[Pose], snapshots: list[BagSnapshot]) -> bool:
    """Whether each pose is one of its object's hypotheses in one of ``snapshots``."""
    return all(
        any(evaluation.code_of([pose], [snapshot.hypotheses[index]]) is not None for snapshot in snapshots)
        for index, pose in enumerate(poses)
    )


def test_live_replay_records_only_the_node_s_new_outputs(handmade_bag: Path, live: tuple[Any, Path, Path]) -> None:
    """The bag's old configurations are not played, so the recorder does not take them for the node's."""
    completed, out, _ = live
    assert (
        f"not played: {topics.RECORDED_CONFIGURATION_TOPIC} (recorded by this replay), "
        f"{topics.RECORDED_SETTLED_TOPIC} (recorded by this replay)" in completed.stderr
    )
    assert f"{MARKERS} (an old run's map: the node under test publishes its own)" in completed.stderr
    snapshots = bag_snapshots(storage.read_bag(handmade_bag), load_scene(SCENE))
    output = storage.read_bag(out, (topics.RECORDED_CONFIGURATION_TOPIC,))
    assert output.messages
    for message in output.messages:
        poses = list(storage.pose_array_from_cdr(message.raw).checked_poses())
        assert made_of_hypotheses(poses, snapshots), f"not the node's: {poses}"
    settled_x = [pose.position.x for message in recorded(out)[topics.RECORDED_SETTLED_TOPIC] for pose in message.poses]
    assert settled_x and max(settled_x) < 0.5  # the old run's are 1 m to the side


def test_live_and_offline_choose_the_same_codes(live: tuple[Any, Path, Path], offline: tuple[Any, Path, Path]) -> None:
    assert codes(live[2]) == codes(offline[2]) == EXPECTED_CODES


def test_live_summary_compares_errors_with_and_without_physics(live: tuple[Any, Path, Path]) -> None:
    completed, _, result = live
    assert "mean position error against ground truth over the 3 snapshots" in completed.stdout
    mean = json.loads(result.read_text())["mean_errors"]
    assert sum(mean["chosen"]) == pytest.approx(0.0, abs=1e-9)  # the good hypotheses are the truth
    assert sum(mean["top"]) == pytest.approx((0.02 + 0.03 + 0.03) / 3)  # snapshot 1: left; 2: right, top
    assert "replay:" in completed.stderr and "messages played" in completed.stderr  # progress


def test_start_node_replays_the_shipped_bag(tmp_path: Path) -> None:
    completed = run_cli(
        "replay",
        str(REPO / "test" / "data" / "pyramid"),
        "--scene",
        str(SCENE),
        "--start-node",
        "--rate",
        "4",
        "-o",
        str(tmp_path / "out"),
        "--wait",
        "60",
        timeout=180,
    )
    assert completed.returncode == 0, completed.stderr
    assert "started the node" in completed.stderr
    assert "total" in completed.stdout.splitlines()[-1]
    snapshots = bag_snapshots(storage.read_bag(REPO / "test" / "data" / "pyramid"), load_scene(SCENE))
    index_of = {snapshot.stamp_ns: index for index, snapshot in enumerate(snapshots)}
    configurations = storage.read_bag(tmp_path / "out", (topics.RECORDED_CONFIGURATION_TOPIC,)).messages
    assert configurations
    for message in configurations:
        data = storage.pose_array_from_cdr(message.raw)
        poses, index = list(data.checked_poses()), index_of[data.stamp_ns]
        # A tick while bursts arrive (4x speed: 8 per second) mixes the newest with hypotheses still in
        # use from earlier ones (an object's poses wait for their weights); recorded_outcomes counts no code.
        mixed = made_of_hypotheses(poses, snapshots[: index + 1])
        assert evaluation.code_of(poses, snapshots[index].hypotheses) is not None or mixed, data.stamp_ns
