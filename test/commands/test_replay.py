"""Replay: a bag written here with rosbags goes into a live node (subprocess, real DDS) and into the core offline.

The bag holds three snapshots of two hypotheses per pyramid cube. In each, exactly one
configuration is physically valid: a cube 2 cm into the floor, a cube pushed 2 cm into its
neighbour, or a top cube hovering 3 cm high invalidates every other one. So the expected code of
each snapshot is known, and the live node (``--exhaustive``: the replay waits for its finished
search on each snapshot, so the result does not depend on the machine's speed) and the offline
search must both find it. The cubes are turned by random rotations that leave them resting on a
face, with quaternions that a second normalisation changes in the last bits, as a round trip
through the node does. Like a bag recorded with ``ros2 bag record -a`` while a node ran, it also
holds an old run's outputs, the graph's own topics and a camera, none of which is played.
"""

from __future__ import annotations

import itertools
import json
import os
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import REPO, SCENES
from rclpy.qos import DurabilityPolicy, ReliabilityPolicy
from ros_helpers import NodeProcess, run_cli
from rosbags.interfaces import QosDurability, QosReliability
from rosbags.rosbag2 import Reader, StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore
from scipy.spatial.transform import Rotation

from physics_mapper.bags import storage
from physics_mapper.bags.read_ahead import ReadAhead
from physics_mapper.evaluation import snapshot_results
from physics_mapper.evaluation.scoring import ObjectClasses
from physics_mapper.evaluation.snapshots import BagSnapshot, bag_snapshots
from physics_mapper.mapping import topics
from physics_mapper.model.geometry import Pose, Quaternion, make_pose, rotation_angle
from physics_mapper.model.hypotheses import Hypothesis, RankedHypotheses
from physics_mapper.model.scene_files import load_scene
from physics_mapper.ros.bag_player import Playback, played_topics
from physics_mapper.ros.qos import MAP_QOS, playback_qos

TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
POSE_ARRAY = "geometry_msgs/msg/PoseArray"
WEIGHTS = "std_msgs/msg/Float64MultiArray"
MARKER_ARRAY = "visualization_msgs/msg/MarkerArray"
MARKERS = "/physics_mapper/markers"
#: Topics of a ``ros2 bag record -a`` bag that the node does not consume, with their types.
OTHER_TOPICS = {
    "/rosout": "rcl_interfaces/msg/Log",
    "/parameter_events": "rcl_interfaces/msg/ParameterEvent",
    "/clock": "rosgraph_msgs/msg/Clock",
    "/camera/image_raw": "sensor_msgs/msg/Image",
}
IMAGE_BYTES = 640 * 480 * 3
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
        for topic, msgtype in OTHER_TOPICS.items():
            connections[topic] = writer.add_connection(topic, msgtype, typestore=TYPESTORE)
        types = TYPESTORE.types
        others = {
            "/rosout": types["rcl_interfaces/msg/Log"](
                stamp=types["builtin_interfaces/msg/Time"](sec=0, nanosec=0),
                level=20,
                name="old",
                msg="an old run's log",
                file="",
                function="",
                line=0,
            ),
            "/parameter_events": types["rcl_interfaces/msg/ParameterEvent"](
                stamp=types["builtin_interfaces/msg/Time"](sec=0, nanosec=0),
                node="/old",
                new_parameters=[],
                changed_parameters=[],
                deleted_parameters=[],
            ),
            "/clock": types["rosgraph_msgs/msg/Clock"](clock=types["builtin_interfaces/msg/Time"](sec=0, nanosec=0)),
            "/camera/image_raw": types["sensor_msgs/msg/Image"](
                header=types["std_msgs/msg/Header"](
                    stamp=types["builtin_interfaces/msg/Time"](sec=0, nanosec=0), frame_id="camera"
                ),
                height=480,
                width=640,
                encoding="rgb8",
                is_bigendian=0,
                step=640 * 3,
                data=np.zeros(IMAGE_BYTES, dtype=np.uint8),
            ),
        }

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
            for offset, (topic, message) in enumerate(others.items()):
                write(topic, stamp + 400_000_000 + offset, message)
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
    assert snapshot_results.code_of(published, hypotheses) == tuple(code)
    assert snapshot_results.code_of([moved(published[0], dz=1e-8), *published[1:]], hypotheses) is None


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
    assert "physics-mapper replay: error: no node listens on /hypotheses/cube_left" in completed.stderr
    assert "; no node publishes /physics_mapper/configuration" in completed.stderr
    assert "Traceback" not in completed.stderr


def replay_live(bag: Path, out: Path, namespace: str, *options: str) -> subprocess.CompletedProcess[str]:
    """``replay`` of ``bag`` into the node running in ``namespace``, exhaustive, recorded into ``out``."""
    arguments = ["replay", str(bag), "--scene", str(SCENE), "-o", str(out), "--namespace", namespace]
    return run_cli(*arguments, *options, "--wait", "60", "--exhaustive", timeout=180)


def test_live_replay_reaches_a_renamed_node(handmade_bag: Path, tmp_path: Path) -> None:
    """A launch file's ``name=`` renames the node (``-r __node:=mapper``): --node-name finds it."""
    node = NodeProcess(SCENE, {}, tmp_path / "node.log", "/renamed", remaps={"__node": "mapper"})
    try:
        completed = replay_live(handmade_bag, tmp_path / "out", "/renamed", "--node-name", "mapper")
    finally:
        node.stop()
    assert completed.returncode == 0, completed.stderr
    messages = recorded(tmp_path / "out")
    assert messages[topics.RECORDED_CONFIGURATION_TOPIC]  # the renamed node's outputs, recorded
    assert any(status.name.startswith("mapper: ") for m in messages["/diagnostics"] for status in m.status)


def test_a_bad_node_name_is_one_error_line(handmade_bag: Path) -> None:
    completed = run_cli("replay", str(handmade_bag), "--scene", str(SCENE), "--node-name", "my node")
    assert completed.returncode == 2
    errors = [line for line in completed.stderr.splitlines() if "error" in line]
    assert errors == [
        "physics-mapper replay: error: --node-name: Invalid node name: node name must not contain "
        "characters other than alphanumerics or '_': 'my node'"
    ]
    assert "Traceback" not in completed.stderr


@pytest.fixture(scope="module")
def live(handmade_bag: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[Any, Path, Path]:
    """The handmade bag replayed into a node started by the test, recorded into a new bag."""
    folder = tmp_path_factory.mktemp("live")
    node = NodeProcess(SCENE, {"diagnostics_period": 0.1}, folder / "node.log", NAMESPACE)
    try:
        completed = replay_live(handmade_bag, folder / "out", NAMESPACE, "--json", str(folder / "result.json"))
        assert node.alive, node.output()
    finally:
        node.stop()
    return completed, folder / "out", folder / "result.json"


def test_live_replay_yields_configurations_recorded_in_the_output_bag(live: tuple[Any, Path, Path]) -> None:
    completed, out, _ = live
    assert completed.returncode == 0, completed.stderr
    messages = recorded(out)
    # A tick while a burst arrives maps only the objects received so far (made_of_hypotheses); the map each
    # search finished on holds all three.
    last_of_stamp = {
        m.header.stamp.sec * 10**9 + m.header.stamp.nanosec: m for m in messages[topics.RECORDED_CONFIGURATION_TOPIC]
    }
    assert {FIRST_NS + k * SPACING_NS for k in range(3)} <= last_of_stamp.keys()
    assert all(len(m.poses) == 3 for m in last_of_stamp.values())
    assert messages[topics.RECORDED_SETTLED_TOPIC]
    assert any(status.name.startswith("physics_mapper") for m in messages["/diagnostics"] for status in m.status)


def made_of_hypotheses(poses: list[Pose], snapshots: list[BagSnapshot]) -> bool:
    """Whether each pose is one of its object's hypotheses in one of ``snapshots``.

    A map holds only the objects present, in scene order: before the node has received an object's first
    hypotheses (a replay's first messages may go out before the node's subscriptions match), the
    object is *absent* and not in the array. So the poses are matched to some objects in scene order.
    """
    objects = range(len(snapshots[0].hypotheses))
    return any(
        all(
            any(snapshot_results.code_of([pose], [snapshot.hypotheses[index]]) is not None for snapshot in snapshots)
            for index, pose in zip(held, poses, strict=True)
        )
        for held in itertools.combinations(objects, len(poses))
    )


def test_live_replay_plays_only_what_the_node_consumes(live: tuple[Any, Path, Path]) -> None:
    """Not the graph's own topics, not a camera: 3 snapshots x 3 cubes x (poses, weights) = 18 messages."""
    completed, _, _ = live
    assert "/ground_truth (not consumed by the node; --topics or --all-topics plays it)" in completed.stderr
    assert "/camera/image_raw (not consumed by the node; --topics or --all-topics plays it)" in completed.stderr
    for topic in ("/rosout", "/parameter_events", "/clock"):
        assert f"{topic} (the graph's own; --topics {topic} plays it)" in completed.stderr
    assert "18/18 messages played" in completed.stderr


def test_other_topics_are_played_when_asked_but_the_graph_s_own_only_when_named(handmade_bag: Path) -> None:
    info = storage.bag_info(handmade_bag)
    consumed = [t for name in NAMES for t in (topics.recorded_poses_topic(name), topics.recorded_weights_topic(name))]
    everything, _ = played_topics(info, consumed, Playback(all_topics=True))
    assert set(everything) == {*consumed, "/ground_truth", "/camera/image_raw"}
    named, _ = played_topics(info, consumed, Playback(topics=("/clock", "/camera/image_raw")))
    assert set(named) == {*consumed, "/clock", "/camera/image_raw"}
    recorded_here, skipped = played_topics(info, consumed, Playback(topics=(topics.RECORDED_CONFIGURATION_TOPIC,)))
    assert topics.RECORDED_CONFIGURATION_TOPIC not in recorded_here  # never, even when named
    assert f"{topics.RECORDED_CONFIGURATION_TOPIC} (recorded by this replay)" in skipped


def test_recorded_outputs_carry_the_qos_their_publishers_offered(live: tuple[Any, Path, Path]) -> None:
    """So that ``ros2 bag play`` of the recording latches the map again (transient local), as the node does."""
    _, out, _ = live
    offered = storage.bag_info(out).offered_qos
    for topic in (topics.RECORDED_CONFIGURATION_TOPIC, topics.RECORDED_SETTLED_TOPIC):
        assert offered[topic], topic
        # The graph does not tell a publisher's history depth (rosbag2 records 0 too).
        assert {(q.reliability, q.durability) for q in offered[topic]} == {
            (QosReliability.RELIABLE, QosDurability.TRANSIENT_LOCAL)
        }
    assert (QosReliability.RELIABLE, QosDurability.VOLATILE) in {
        (q.reliability, q.durability) for q in offered[topics.DIAGNOSTICS_TOPIC]
    }
    assert playback_qos(offered[topics.RECORDED_CONFIGURATION_TOPIC]) == MAP_QOS  # latched, the last map


def test_offline_results_are_recorded_latched_too(offline: tuple[Any, Path, Path]) -> None:
    _, out, _ = offline
    offered = storage.bag_info(out).offered_qos
    assert [(q.reliability, q.durability, q.depth) for q in offered[topics.RECORDED_CONFIGURATION_TOPIC]] == [
        (QosReliability.RELIABLE, QosDurability.TRANSIENT_LOCAL, 1)
    ]


def test_live_replay_records_only_the_node_s_new_outputs(handmade_bag: Path, live: tuple[Any, Path, Path]) -> None:
    """The bag's old configurations are not played, so the recorder does not take them for the node's."""
    completed, out, _ = live
    assert (
        f"{topics.RECORDED_CONFIGURATION_TOPIC} (recorded by this replay), "
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
    """Deterministic: the live replay waited for the node's finished search on each snapshot."""
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
    assert any(line.startswith("total") for line in completed.stdout.splitlines())  # the error table's last row
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
        whole = len(poses) == len(NAMES) and snapshot_results.code_of(poses, snapshots[index].hypotheses) is not None
        assert whole or mixed, data.stamp_ns


def test_on_the_shipped_bag_physics_lowers_the_error() -> None:
    """What the demo shows live, asserted where it is deterministic: offline, every search exhausted.

    The live demo's figures vary with the machine's speed (BENCHMARKS.md, "Live replay").
    """
    scene = load_scene(SCENE)
    snapshots = bag_snapshots(storage.read_bag(REPO / "test" / "data" / "pyramid"), scene)
    results = snapshot_results.search_offline(snapshots, scene, None)
    objects = ObjectClasses.of(scene)
    mean = snapshot_results.mean_scored_errors(snapshot_results.estimate_errors(r, objects) for r in results)
    assert mean is not None
    assert sum(mean["chosen"]) < sum(mean["top"])
    assert sum(mean["settled"]) < sum(mean["chosen"])


def write_camera_bag(path: Path, images: int, size: int) -> None:
    """A bag of ``images`` camera images of ``size`` bytes, 10 ms apart, and a hypotheses topic."""
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        camera = writer.add_connection("/camera/image_raw", "sensor_msgs/msg/Image", typestore=TYPESTORE)
        hypotheses = writer.add_connection("/hypotheses/cube_top", POSE_ARRAY, typestore=TYPESTORE)
        types = TYPESTORE.types
        for index in range(images):
            header = types["std_msgs/msg/Header"](
                stamp=types["builtin_interfaces/msg/Time"](sec=0, nanosec=0), frame_id="camera"
            )
            image = types["sensor_msgs/msg/Image"](
                header=header,
                height=1,
                width=size,
                encoding="mono8",
                is_bigendian=0,
                step=size,
                data=np.full(size, index % 256, dtype=np.uint8),
            )
            writer.write(camera, 10_000_000 * index, TYPESTORE.serialize_cdr(image, "sensor_msgs/msg/Image"))
            writer.write(
                hypotheses,
                10_000_000 * index + 1,
                TYPESTORE.serialize_cdr(pose_array(index, list(TRUTH[2:])), POSE_ARRAY),
            )


def test_a_bag_streams_through_a_bounded_window_in_order(tmp_path: Path) -> None:
    """A slow consumer (the player at the bag's pace) never has more than the window read ahead."""
    path = tmp_path / "camera"
    write_camera_bag(path, images=60, size=200_000)
    expected = storage.read_bag(path).messages
    streamed = storage.stream_messages(path, {"/camera/image_raw", "/hypotheses/cube_top"})
    with ReadAhead(streamed, max_messages=1000, max_bytes=1_000_000) as window:
        got = []
        for message in window:
            got.append(message)
            time.sleep(0.002)  # slower than the reader: the window fills
    assert [(m.topic, m.time_ns, m.raw) for m in got] == [(m.topic, m.time_ns, m.raw) for m in expected]
    assert window.peak_bytes <= 1_000_000 and window.peak_messages >= 4  # full, and no fuller
    only_hypotheses = list(storage.stream_messages(path, {"/hypotheses/cube_top"}))
    assert [m.time_ns for m in only_hypotheses] == [10_000_000 * i + 1 for i in range(60)]


def test_a_message_larger_than_the_window_still_passes_alone(tmp_path: Path) -> None:
    path = tmp_path / "large"
    write_camera_bag(path, images=3, size=300_000)
    with ReadAhead(storage.stream_messages(path, {"/camera/image_raw"}), max_bytes=100_000) as window:
        sizes = [len(message.raw) for message in window]
    assert len(sizes) == 3 and window.peak_messages == 1


def test_a_damaged_bag_is_reported_by_the_stream_after_the_messages_before_it(tmp_path: Path) -> None:
    path = tmp_path / "camera"
    write_camera_bag(path, images=5, size=1000)
    (mcap,) = path.glob("*.mcap")
    mcap.write_bytes(mcap.read_bytes()[:-200])  # truncated: no summary, no footer
    with pytest.raises(storage.BagError, match="cannot read bag"):
        list(ReadAhead(storage.stream_messages(path, {"/camera/image_raw"})))


def test_a_topic_is_replayed_with_the_reliability_and_durability_its_publishers_offered() -> None:
    """As ``ros2 bag play``: recorded profiles that agree are honoured; mixed ones or none: reliable, volatile."""
    latched = storage.offered_qos(topics.MAP_TOPIC_QOS)
    sensor = storage.offered_qos(topics.input_topic_qos("best_effort"))
    profile = playback_qos([sensor, sensor])
    assert (profile.reliability, profile.durability) == (ReliabilityPolicy.BEST_EFFORT, DurabilityPolicy.VOLATILE)
    assert playback_qos([latched]) == MAP_QOS
    for offers in ([], [latched, sensor]):
        profile = playback_qos(offers)
        assert (profile.reliability, profile.durability) == (ReliabilityPolicy.RELIABLE, DurabilityPolicy.VOLATILE)
