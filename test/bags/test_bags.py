"""Bags from ``generate``, read back with the rosbags library alone; bad bags give one clear error line."""

from __future__ import annotations

import random
import shutil
import subprocess
import sys
from dataclasses import dataclass, replace
from itertools import pairwise
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from conftest import REPO, SCENES
from message_compare import LAST_BITS, Tolerance, differences
from rosbags.rosbag2 import Reader, StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from physics_mapper.bags.mcap_storage import verify_checksums
from physics_mapper.bags.storage import TYPESTORE as BAG_TYPES  # Jazzy's types and vision_msgs
from physics_mapper.bags.storage import BagError, BagWriter, read_bag
from physics_mapper.cli import main
from physics_mapper.evaluation.scoring import position_errors, rank_one_poses
from physics_mapper.evaluation.snapshot_results import SnapshotResult, recorded_results, write_results
from physics_mapper.evaluation.snapshots import BagSnapshot, bag_snapshots, input_topics
from physics_mapper.experiments.common import ExperimentOptions
from physics_mapper.experiments.tracking import track_and_search
from physics_mapper.mapping.topics import RECORDED_CONFIGURATION_TOPIC
from physics_mapper.model.errors import EXIT_BAD_INPUT
from physics_mapper.model.geometry import make_pose
from physics_mapper.model.hypotheses import Hypothesis, RankedHypotheses
from physics_mapper.model.scene_files import load_scene, scene_from_dict
from physics_mapper.perception.particle_filter import TrackerSettings

TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
POSE_ARRAY = "geometry_msgs/msg/PoseArray"
WEIGHTS = "std_msgs/msg/Float64MultiArray"
PYRAMID = ("cube_left", "cube_right", "cube_top")
RUNS, ITERATIONS, TOP_M = 2, 3, 3
DATA = REPO / "test" / "data"
FLOOR = {"name": "floor", "shape": "plane"}
#: A 10 cm box on the floor.
ON_FLOOR_POSE = make_pose((0.0, 0.0, 0.05))


@dataclass(frozen=True)
class RawBag:
    """What rosbags alone reports about a bag."""

    storage: str
    files: list[str]
    topics: dict[str, str]
    counts: dict[str, int]
    messages: list[tuple[str, int, bytes]]  # topic, receive time (ns), raw CDR

    def decoded(self, topic: str) -> list[Any]:
        return [TYPESTORE.deserialize_cdr(raw, self.topics[topic]) for t, _, raw in self.messages if t == topic]


def stamp_ns(message: Any) -> int:
    return int(message.header.stamp.sec) * 1_000_000_000 + int(message.header.stamp.nanosec)


def read_with_rosbags(path: Path) -> RawBag:
    metadata = yaml.safe_load((path / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    with Reader(path) as reader:
        return RawBag(
            storage=metadata["storage_identifier"],
            files=metadata["relative_file_paths"],
            topics={c.topic: c.msgtype for c in reader.connections},
            counts={c.topic: c.msgcount for c in reader.connections},
            messages=[(c.topic, t, bytes(raw)) for c, t, raw in reader.messages()],
        )


def generate(output: Path, *extra: str) -> None:
    arguments = ["generate", str(SCENES / "pyramid.yaml"), "-o", str(output), "--runs", str(RUNS)]
    arguments += ["--iterations", str(ITERATIONS), "--top-m", str(TOP_M), "--particles", "200", *extra]
    assert main(arguments) == 0


@pytest.fixture(scope="module", params=["mcap", "sqlite3"])
def generated(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> tuple[str, RawBag]:
    storage = str(request.param)
    path = tmp_path_factory.mktemp(storage) / "pyramid"
    generate(path, "--storage", storage, "--seed", "5")
    return storage, read_with_rosbags(path)


def test_storage_format_as_requested(generated: tuple[str, RawBag]) -> None:
    storage, bag = generated
    assert bag.storage == storage
    assert [Path(f).suffix for f in bag.files] == [".mcap" if storage == "mcap" else ".db3"]


def test_topics_types_and_counts(generated: tuple[str, RawBag]) -> None:
    _, bag = generated
    expected = {"/ground_truth": POSE_ARRAY}
    for name in PYRAMID:
        expected[f"/hypotheses/{name}"] = POSE_ARRAY
        expected[f"/hypotheses/{name}/weights"] = WEIGHTS
    assert bag.topics == expected
    assert bag.counts == dict.fromkeys(expected, RUNS * ITERATIONS)
    assert len(bag.messages) == len(expected) * RUNS * ITERATIONS


def test_timestamps_strictly_increasing(generated: tuple[str, RawBag]) -> None:
    _, bag = generated
    times = [t for _, t, _ in bag.messages]
    assert all(a < b for a, b in pairwise(times))
    # Iterations are 0.5 s apart; every PoseArray of an iteration carries the iteration's stamp.
    first = stamp_ns(bag.decoded("/ground_truth")[0])
    for topic, msgtype in bag.topics.items():
        if msgtype == POSE_ARRAY:
            offsets = [stamp_ns(m) - first for m in bag.decoded(topic)]
            assert offsets == [k * 500_000_000 for k in range(RUNS * ITERATIONS)]


def test_message_contents(generated: tuple[str, RawBag]) -> None:
    _, bag = generated
    for name in PYRAMID:
        pairs = zip(bag.decoded(f"/hypotheses/{name}"), bag.decoded(f"/hypotheses/{name}/weights"), strict=True)
        for poses, weights in pairs:
            assert poses.header.frame_id == "world"
            assert len(poses.poses) == len(weights.data) == TOP_M
            assert weights.data.sum() == pytest.approx(1.0)
            assert list(weights.data) == sorted(weights.data, reverse=True)
            for pose in poses.poses:
                q = pose.orientation
                assert np.hypot.reduce([q.x, q.y, q.z, q.w]) == pytest.approx(1.0)
    truth = bag.decoded("/ground_truth")
    assert all(len(m.poses) == len(PYRAMID) for m in truth)
    assert truth[0].poses[2].position.z == pytest.approx(0.3, abs=0.002)  # the top cube rests on the others


def test_same_seed_same_messages(tmp_path: Path) -> None:
    generate(tmp_path / "a", "--seed", "3")
    generate(tmp_path / "b", "--seed", "3")
    generate(tmp_path / "c", "--seed", "4")
    a, b, c = (read_with_rosbags(tmp_path / name).messages for name in "abc")
    assert a == b
    assert a != c


#: Bags of the mesh scenes: pybullet settles their ground truth with principal moments and axes that
#: numpy's LAPACK (``eigh``) factors from the meshes' inertias with kernels chosen for the CPU, and
#: objects resting on one another carry last-bit differences of those into their resting poses, and
#: the hypotheses drawn around them: 5.1e-6 m in tray_pile between OpenBLAS's SkylakeX kernels and its
#: Haswell, Zen, Sandybridge, Nehalem or Prescott ones. 1e-4 (0.1 mm, a fiftieth of the bags' 5 mm
#: noise) bounds that twenty times over; a changed seed, sigma or particle count moves hypotheses by
#: millimetres.
SETTLED_MESHES = Tolerance(rel=1e-9, abs=1e-4)
#: Shipped bag -> the command that made it (test/data/README.md) and how closely a bag made again by
#: it on any machine must agree. The primitive scenes' ground truth is settled from exact inputs, the
#: same on every CPU; only the weights' last bits differ (numpy's ``exp`` and sums): LAST_BITS.
SHIPPED_BAGS: dict[str, tuple[str, Tolerance]] = {
    "pyramid": (
        "generate config/scenes/pyramid.yaml -o test/data/pyramid --runs 2 --sigma 0.005 --sigma-rotation 0.005 "
        "--seed 1",
        LAST_BITS,
    ),
    "sphere_groove_sqlite3": (
        "generate config/scenes/sphere_groove.yaml -o test/data/sphere_groove_sqlite3 --runs 2 --sigma 0.1 "
        "--seed 2 --storage sqlite3",
        LAST_BITS,
    ),
    **{
        scene: (
            f"generate config/scenes/{scene}.yaml -o test/data/{scene} --runs 1 --particles 300 --sigma 0.005 "
            f"--seed {seed}",
            SETTLED_MESHES,
        )
        for scene, seed in (("tabletop", 1), ("tray_pile", 2), ("jenga_tower", 3))
    },
    "box_bin": (
        "generate config/scenes/box_bin.yaml -o test/data/box_bin --runs 1 --iterations 10 --particles 300 "
        "--sigma 0.005 --seed 1 --format detections --shuffle --miss 0.1 --false-positives 0.1 --double 0.05 "
        "--wrong-first 0.25 --results 3-5 --confidence 0.7-0.95",
        LAST_BITS,
    ),
}


def bag_differences(expected: RawBag, actual: RawBag, tolerance: Tolerance) -> list[str]:
    """Where ``actual`` differs from ``expected``, one line each: storage, files, topics and their types,
    counts, and each message's topic and receive time exactly; decoded messages field by field, floats
    within ``tolerance`` (stamps, frame ids and sizes exactly)."""
    layout = [
        (name, getattr(expected, name), getattr(actual, name)) for name in ("storage", "files", "topics", "counts")
    ]
    found = [f"{name}: {a!r} != {b!r}" for name, a, b in layout if a != b]
    order = differences([m[:2] for m in expected.messages], [m[:2] for m in actual.messages], where="messages")
    if order:
        return found + order
    for (topic, time_ns, raw), (_, _, other) in zip(expected.messages, actual.messages, strict=True):
        want, got = (BAG_TYPES.deserialize_cdr(r, bag.topics[topic]) for r, bag in ((raw, expected), (other, actual)))
        found += differences(want, got, tolerance, f"{topic} at {time_ns} ns")
    return found


def regenerate(bag: str, output: Path, change: tuple[str, str] | None = None) -> RawBag:
    """Run a shipped bag's command (from the repository root) into ``output``, with ``change`` = (option,
    value) set if given (added if the command lacks the option); what rosbags reads of the result."""
    arguments = SHIPPED_BAGS[bag][0].split()
    arguments[arguments.index("-o") + 1] = str(output)
    if change is not None:
        option, value = change
        if option in arguments:
            arguments[arguments.index(option) + 1] = value
        else:
            arguments += [option, value]
    assert main(arguments) == 0
    return read_with_rosbags(output)


@pytest.mark.parametrize("bag", SHIPPED_BAGS)
def test_shipped_bags_are_what_their_recorded_command_makes(
    bag: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    command, tolerance = SHIPPED_BAGS[bag]
    assert f"`physics-mapper {command}`" in (DATA / "README.md").read_text()
    monkeypatch.chdir(REPO)
    assert bag_differences(read_with_rosbags(DATA / bag), regenerate(bag, tmp_path / bag), tolerance) == []


@pytest.mark.parametrize(
    ("change", "reported"),
    [
        (("--seed", "3"), "/hypotheses/"),
        (("--sigma", "0.006"), "/hypotheses/"),
        (("--particles", "301"), "/hypotheses/"),
        (("--storage", "sqlite3"), "storage: 'mcap' != 'sqlite3'"),
    ],
)
def test_a_bag_made_with_another_argument_is_told_apart_from_the_shipped_one(
    change: tuple[str, str], reported: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """tray_pile's command with one argument changed: even the loosest tolerance (SETTLED_MESHES) tells
    the bag apart from the shipped one, so the comparison above would see a command that no longer makes it."""
    monkeypatch.chdir(REPO)
    changed = regenerate("tray_pile", tmp_path / "tray_pile", change)
    found = bag_differences(read_with_rosbags(DATA / "tray_pile"), changed, SHIPPED_BAGS["tray_pile"][1])
    assert any(line.startswith(reported) for line in found), found[:5]


def test_the_comparison_allows_last_bits_and_reports_every_other_difference() -> None:
    shipped = read_with_rosbags(DATA / "pyramid")
    weights, poses = shipped.decoded("/hypotheses/cube_top/weights")[0], shipped.decoded("/hypotheses/cube_top")[0]
    last_bits = np.nextafter(np.nextafter(weights.data, np.inf), np.inf)  # two units in the last place up
    assert not np.array_equal(last_bits, weights.data)
    assert differences(weights, replace(weights, data=last_bits)) == []
    first, changed = float(weights.data[0]), float(weights.data[0]) * (1.0 + 1e-8)
    found = differences(weights, replace(weights, data=np.array([changed, *weights.data[1:]])), where="w")
    assert found == [f"w.data[0]: {first!r} != {changed!r} (beyond rel 1e-09, abs 1e-12)"]
    stamp = replace(poses.header.stamp, nanosec=poses.header.stamp.nanosec + 1)
    assert differences(poses, replace(poses, header=replace(poses.header, stamp=stamp))) == [
        f".header.stamp.nanosec: {poses.header.stamp.nanosec} != {stamp.nanosec}"
    ]
    assert differences(poses, replace(poses, header=replace(poses.header, frame_id="map"))) == [
        ".header.frame_id: 'world' != 'map'"
    ]
    assert differences(poses, replace(poses, poses=poses.poses[:-1])) == [".poses: 5 items != 4"]


def test_shipped_bags_are_small() -> None:
    assert sum(f.stat().st_size for f in DATA.rglob("*") if f.is_file()) < 2_000_000


# ---- bad bags and bad arguments: one error line, exit 2, no traceback ------------------------------------


def write_bag(
    path: Path,
    topics: dict[str, tuple[str, Any]],
    storage: StoragePlugin = StoragePlugin.MCAP,
    garbage: str | None = None,
) -> Path:
    """A bag written with rosbags: topic -> (type, message), one message each at 1, 2, ... ns.

    The message on topic ``garbage`` is replaced by bytes that are not CDR.
    """
    with Writer(path, version=9, storage_plugin=storage) as writer:
        for time_ns, (topic, (msgtype, message)) in enumerate(topics.items(), start=1):
            connection = writer.add_connection(topic, msgtype, typestore=TYPESTORE)
            raw = b"\x00\x01\x00\x00\xff" if topic == garbage else TYPESTORE.serialize_cdr(message, msgtype)
            writer.write(connection, time_ns, raw)
    return path


def pose_array(count: int, frame_id: str = "world") -> Any:
    types = TYPESTORE.types
    stamp = types["builtin_interfaces/msg/Time"](sec=1, nanosec=0)
    header = types["std_msgs/msg/Header"](stamp=stamp, frame_id=frame_id)
    pose = types["geometry_msgs/msg/Pose"](
        position=types["geometry_msgs/msg/Point"](x=0.0, y=0.0, z=0.1),
        orientation=types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
    )
    return types[POSE_ARRAY](header=header, poses=[pose] * count)


def copy_of_fixture(tmp_path: Path, name: str) -> tuple[Path, Path]:
    """A copy of a shipped bag and its storage file."""
    target = tmp_path / name
    target.mkdir()
    for item in (DATA / name).iterdir():
        (target / item.name).write_bytes(item.read_bytes())
    return target, next(p for p in target.iterdir() if p.suffix in (".mcap", ".db3"))


def replay_error(capsys: pytest.CaptureFixture[str], bag: Path, scene: str = "pyramid") -> str:
    """Run ``replay --offline`` through the CLI's main; assert exit 2 and return the one error line."""
    capsys.readouterr()
    status = main(["replay", str(bag), "--scene", str(SCENES / f"{scene}.yaml"), "--offline"])
    errors = [line for line in capsys.readouterr().err.splitlines() if "error" in line]
    assert status == EXIT_BAD_INPUT
    assert len(errors) == 1, errors
    return errors[0]


def test_bags_written_here_carry_every_mcap_checksum(tmp_path: Path) -> None:
    """Chunk, data-section and summary CRCs, in generated bags and the shipped one."""
    fresh = tmp_path / "fresh"
    generate(fresh)
    for mcap_file in (fresh / "fresh.mcap", DATA / "pyramid" / "pyramid.mcap"):
        verified = verify_checksums(mcap_file)
        assert verified.chunks >= 1 and verified.chunks_with_crc == verified.chunks
        assert verified.data_section and verified.summary


#: Copies of the shipped mcap bag with 16 bytes overwritten at a random place, and the seed choosing them.
DAMAGED_COPIES, DAMAGE_SEED = 40, 12


def test_a_damaged_mcap_is_reported_and_never_read_as_other_messages(tmp_path: Path) -> None:
    """16 random bytes overwritten gave exit 0 and silently different results in 7 of 40 copies."""
    bag, storage_file = copy_of_fixture(tmp_path, "pyramid")
    intact = storage_file.read_bytes()
    rng = random.Random(DAMAGE_SEED)
    reported = []
    for _ in range(DAMAGED_COPIES):
        offset = rng.randrange(len(intact) - 16)
        damaged = bytearray(intact)
        damaged[offset : offset + 16] = rng.randbytes(16)
        storage_file.write_bytes(bytes(damaged))
        with pytest.raises(BagError) as raised:
            read_bag(bag)
        reported.append(str(raised.value))
    assert all(r.startswith(f"{bag}: cannot read bag (corrupt or truncated?): ") for r in reported)
    assert sum("checksum mismatch" in r for r in reported) >= DAMAGED_COPIES // 2


def test_a_damaged_chunk_is_one_error_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bag, storage_file = copy_of_fixture(tmp_path, "pyramid")
    data = bytearray(storage_file.read_bytes())
    data[len(data) // 2] ^= 0x01  # one bit of a message, inside the only chunk
    storage_file.write_bytes(bytes(data))
    assert replay_error(capsys, bag) == (
        f"physics-mapper replay: error: {bag}: cannot read bag (corrupt or truncated?): "
        "pyramid.mcap: chunk checksum mismatch: the file is damaged"
    )


def test_truncated_mcap(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bag, storage_file = copy_of_fixture(tmp_path, "pyramid")
    storage_file.write_bytes(storage_file.read_bytes()[: storage_file.stat().st_size // 2])
    line = replay_error(capsys, bag)
    assert line.startswith(f"physics-mapper replay: error: {bag}: cannot read bag (corrupt or truncated?)")


def test_truncated_sqlite3(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bag, storage_file = copy_of_fixture(tmp_path, "sphere_groove_sqlite3")
    storage_file.write_bytes(storage_file.read_bytes()[: storage_file.stat().st_size // 2])
    assert "cannot read bag (corrupt or truncated?)" in replay_error(capsys, bag, "sphere_groove")


def test_corrupt_metadata(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bag, _ = copy_of_fixture(tmp_path, "pyramid")
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: [\n")
    assert "cannot read bag (corrupt or truncated?)" in replay_error(capsys, bag)


def test_storage_file_missing(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bag, storage_file = copy_of_fixture(tmp_path, "pyramid")
    storage_file.unlink()
    assert "files are missing" in replay_error(capsys, bag)


def test_no_such_bag(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert replay_error(capsys, tmp_path / "nothing").endswith("nothing: no such bag")


def test_missing_topics(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bag = write_bag(tmp_path / "partial", {"/hypotheses/cube_left": (POSE_ARRAY, pose_array(2))})
    line = replay_error(capsys, bag)
    assert "no messages on /hypotheses/cube_right, /hypotheses/cube_top" in line
    assert "(topics in the bag: /hypotheses/cube_left)" in line


def test_wrong_message_type(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    text = TYPESTORE.types["std_msgs/msg/String"](data="not poses")
    topics = {f"/hypotheses/{name}": (POSE_ARRAY, pose_array(1)) for name in PYRAMID}
    topics["/hypotheses/cube_top"] = ("std_msgs/msg/String", text)
    bag = write_bag(tmp_path / "mistyped", topics, StoragePlugin.SQLITE3)
    line = replay_error(capsys, bag)
    assert "topic /hypotheses/cube_top has type std_msgs/msg/String, expected geometry_msgs/msg/PoseArray" in line


def test_ground_truth_of_the_wrong_size(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    topics = {f"/hypotheses/{name}": (POSE_ARRAY, pose_array(1)) for name in PYRAMID}
    topics["/ground_truth"] = (POSE_ARRAY, pose_array(2))
    bag = write_bag(tmp_path / "truth", topics)
    assert replay_error(capsys, bag).endswith(f"error: {bag}: /ground_truth at 4 ns: 2 poses for 3 scene objects")


@pytest.mark.parametrize(
    ("topic", "msgtype"),
    [("/hypotheses/cube_right", POSE_ARRAY), ("/hypotheses/cube_top/weights", WEIGHTS), ("/ground_truth", POSE_ARRAY)],
)
def test_message_bytes_that_are_not_cdr(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], topic: str, msgtype: str
) -> None:
    """One message of a good bag replaced by garbage: the error names the bag, the topic and the time."""
    topics = {f"/hypotheses/{name}": (POSE_ARRAY, pose_array(1)) for name in PYRAMID}
    layout = TYPESTORE.types["std_msgs/msg/MultiArrayLayout"](dim=[], data_offset=0)
    topics["/hypotheses/cube_top/weights"] = (WEIGHTS, TYPESTORE.types[WEIGHTS](layout=layout, data=np.array([1.0])))
    topics["/ground_truth"] = (POSE_ARRAY, pose_array(3))
    path = write_bag(tmp_path / "garbage", topics, garbage=topic)
    time_ns = list(topics).index(topic) + 1
    assert replay_error(capsys, path).startswith(
        f"physics-mapper replay: error: {path}: {topic} at {time_ns} ns: a {msgtype} message is not valid CDR ("
    )


def test_relative_topic_names_read_as_absolute(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bag = write_bag(tmp_path / "relative", {f"hypotheses/{name}": (POSE_ARRAY, pose_array(1)) for name in PYRAMID})
    capsys.readouterr()
    assert main(["replay", str(bag), "--scene", str(SCENES / "pyramid.yaml"), "--offline"]) == 0
    assert capsys.readouterr().out.startswith("1 snapshots, 0 with a configuration")  # three cubes in one place


def test_hypotheses_in_another_frame_leave_nothing_to_search(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bag = write_bag(tmp_path / "map", {f"/hypotheses/{name}": (POSE_ARRAY, pose_array(1, "map")) for name in PYRAMID})
    capsys.readouterr()
    assert main(["replay", str(bag), "--scene", str(SCENES / "pyramid.yaml"), "--offline"]) == 0
    captured = capsys.readouterr()
    assert "warning: at no time does every object have usable hypotheses (frame_id must be 'world'" in captured.err
    assert captured.out.startswith("0 snapshots, 0 with a configuration")


def test_a_corrupted_position_far_outside_the_workspace_is_not_searched(tmp_path: Path) -> None:
    """A 4e292 m position, as corrupted bags give, is dropped by the input rules; the object's other pose is used."""
    topics = {f"/hypotheses/{name}": (POSE_ARRAY, pose_array(1)) for name in PYRAMID}
    corrupted = pose_array(2)
    corrupted.poses[0] = replace(corrupted.poses[0], position=replace(corrupted.poses[0].position, x=4e292))
    topics["/hypotheses/cube_top"] = (POSE_ARRAY, corrupted)
    bag = write_bag(tmp_path / "corrupted", topics)
    (snapshot,) = bag_snapshots(read_bag(bag), load_scene(SCENES / "pyramid.yaml"))
    top = snapshot.hypotheses[2]
    assert len(top) == 1 and top.pose(1).position == (0.0, 0.0, 0.1)


def test_a_json_file_in_a_missing_folder_is_refused_before_replaying(capsys: pytest.CaptureFixture[str]) -> None:
    capsys.readouterr()
    arguments = ["replay", str(DATA / "pyramid"), "--scene", str(SCENES / "pyramid.yaml"), "--offline"]
    assert main([*arguments, "--json", "/dev/null/dir/x.json"]) == EXIT_BAD_INPUT
    captured = capsys.readouterr()
    missing = "/dev/null/dir/x.json: folder /dev/null/dir does not exist"
    assert captured.err == f"physics-mapper replay: error: cannot write {missing}\n"


def test_offline_output_path_is_checked_before_searching(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "taken").mkdir()
    capsys.readouterr()
    arguments = ["replay", str(DATA / "pyramid"), "--scene", str(SCENES / "pyramid.yaml"), "--offline"]
    assert main([*arguments, "-o", str(tmp_path / "taken")]) == EXIT_BAD_INPUT
    captured = capsys.readouterr()
    assert "exists already" in captured.err
    assert "snapshot 1/" not in captured.err


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (["--offline", "--start-node"], "--start-node is for a live replay"),
        (["--deadline", "1.0"], "--deadline is for --offline"),
        (["--offline", "--all-topics"], "--topics and --all-topics are for a live replay"),
        (["--offline", "--topics", "/clock"], "--topics and --all-topics are for a live replay"),
        (["--rate", "0"], "--rate must be positive"),
        (["--offline", "--deadline", "0"], "--deadline: deadline must be positive"),
        (["--namespace", "no_slash"], "--namespace: Invalid namespace: namespace must be absolute"),
    ],
)
def test_replay_refuses_options_that_do_not_fit(
    capsys: pytest.CaptureFixture[str], options: list[str], message: str
) -> None:
    status = main(["replay", str(DATA / "pyramid"), "--scene", str(SCENES / "pyramid.yaml"), *options])
    assert status == EXIT_BAD_INPUT
    assert message in capsys.readouterr().err


def test_generate_refuses_an_existing_output(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "taken").mkdir()
    status = main(["generate", str(SCENES / "pyramid.yaml"), "-o", str(tmp_path / "taken")])
    assert status == EXIT_BAD_INPUT
    assert "exists already" in capsys.readouterr().err


def test_generate_needs_a_ground_truth(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    scene = tmp_path / "scene.yaml"
    scene.write_text("objects:\n  - {name: box, shape: box, size: [0.1, 0.1, 0.1]}\n")
    status = main(["generate", str(scene), "-o", str(tmp_path / "out")])
    assert status == EXIT_BAD_INPUT
    assert "ground_truth: missing" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    ("option", "message"),
    [
        (["--top-m", "0"], "top_m must be at least 1"),
        (["--sigma", "-1"], "sigma_position must be a positive"),
        (["--runs", "0"], "--runs must be at least 1"),
        (["--period", "0"], "--period must be positive"),
        (["--period", "inf"], "--period must be positive and finite"),
        (["--period", "6e-9"], "--period 6e-09 s is 6 ns: an iteration's 7 messages take 7 ns (1 ns apart)"),
        (["--seed", "-1"], "--seed must not be negative"),
    ],
)
def test_generate_refuses_bad_settings(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], option: list[str], message: str
) -> None:
    status = main(["generate", str(SCENES / "pyramid.yaml"), "-o", str(tmp_path / "out"), *option])
    assert status == EXIT_BAD_INPUT
    assert message in capsys.readouterr().err


def test_the_installed_command_exits_2_without_traceback(tmp_path: Path) -> None:
    bag, storage_file = copy_of_fixture(tmp_path, "pyramid")
    storage_file.write_bytes(storage_file.read_bytes()[:1000])
    command = [str(Path(sys.executable).parent / "physics-mapper"), "replay", str(bag), "--offline"]
    completed = subprocess.run(
        [*command, "--scene", str(SCENES / "pyramid.yaml")], capture_output=True, text=True, timeout=120, check=False
    )
    assert completed.returncode == EXIT_BAD_INPUT
    assert "Traceback" not in completed.stderr
    assert "physics-mapper replay: error:" in completed.stderr


def test_generate_and_offline_replay_run_without_ros(tmp_path: Path) -> None:
    """Both commands in a fresh interpreter: afterwards no ROS module has been loaded."""
    scene, bag = str(SCENES / "pyramid.yaml"), str(tmp_path / "bag")
    code = f"""
import contextlib, io, sys
from physics_mapper.cli import main
with contextlib.redirect_stdout(io.StringIO()):
    assert main(["generate", {scene!r}, "-o", {bag!r}, "--particles", "50"]) == 0
    assert main(["replay", {bag!r}, "--scene", {scene!r}, "--offline"]) == 0
roots = {{name.split(".")[0] for name in sys.modules}}
print(sorted(r for r in roots if r in ("rclpy", "rmw") or r.endswith("_msgs") or r.startswith("rosidl")))
"""
    completed = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=False)
    assert completed.returncode == 0, completed.stderr
    assert completed.stdout.strip() == "[]"


def test_a_continuous_stream_is_snapshot_like_a_ticking_node(tmp_path: Path) -> None:
    """Three objects at 30 Hz, staggered: no 50 ms gap ever, yet a snapshot at least every 0.5 s."""
    scene = load_scene(SCENES / "pyramid.yaml")
    assert scene.ground_truth is not None
    with BagWriter(tmp_path / "stream") as writer:
        for frame in range(60):  # 2 s
            for index, (name, truth) in enumerate(zip(PYRAMID, scene.ground_truth, strict=True)):
                time_ns = 10**9 + frame * 33_333_333 + index * 11_000_000
                x, y, z = truth.position
                pose = make_pose((x + 1e-4 * frame, y, z))
                writer.write_hypotheses(time_ns, time_ns, "world", name, RankedHypotheses((Hypothesis(pose, 1.0),)))
    snapshots = bag_snapshots(read_bag(tmp_path / "stream"), scene)
    assert 4 <= len(snapshots) <= 5
    times = [s.time_ns for s in snapshots]
    assert all(b - a <= 500_000_000 + 33_333_333 for a, b in pairwise(times))
    # Each snapshot is stamped with the newest PoseArray it uses, as the node stamps its output.
    assert all(s.stamp_ns <= s.time_ns for s in snapshots)


def test_the_shortest_period_keeps_iterations_apart_and_warns(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """7 ns: three cubes' poses and weights and the ground truth at 7 consecutive nanoseconds per iteration."""
    generate(tmp_path / "short", "--period", "7e-9")
    assert "warning: --period 7e-09 s leaves less than 0.05 s between iterations" in capsys.readouterr().err
    bag = read_with_rosbags(tmp_path / "short")
    times = [t for _, t, _ in bag.messages]
    assert times == list(range(times[0], times[0] + 7 * RUNS * ITERATIONS))
    # The warning's point: offline replay sees all iterations as one burst.
    assert len(bag_snapshots(read_bag(tmp_path / "short"), load_scene(SCENES / "pyramid.yaml"))) == 1


def test_the_default_period_gives_no_warning(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    generate(tmp_path / "default")
    assert "warning" not in capsys.readouterr().err


def test_read_bag_reads_only_the_topics_asked_for() -> None:
    everything = read_bag(DATA / "pyramid")
    truth_only = read_bag(DATA / "pyramid", ["/ground_truth"])
    assert truth_only.topics == everything.topics  # every topic's type, for the type checks
    assert len(everything.topics) == 7
    assert truth_only.messages == everything.on("/ground_truth") and len(truth_only.messages) == 20
    assert read_bag(DATA / "pyramid", []).messages == ()


def test_other_topics_change_no_snapshot(tmp_path: Path) -> None:
    """A recording's busy unrelated topic (100 Hz, never a 50 ms gap) is not read offline nor counted in bursts."""
    scene = load_scene(SCENES / "pyramid.yaml")
    plain = read_bag(DATA / "pyramid")
    with BagWriter(tmp_path / "busy") as writer:
        for message in plain.messages:
            writer.write(message.topic, message.msgtype, message.time_ns, message.raw)
        for time_ns in range(plain.messages[0].time_ns, plain.messages[-1].time_ns, 10_000_000):
            writer.write("/camera/points", "sensor_msgs/msg/PointCloud2", time_ns + 3, b"not read")
    busy = read_bag(tmp_path / "busy", input_topics(scene))
    assert "/camera/points" in busy.topics and not busy.on("/camera/points")
    expected = bag_snapshots(plain, scene)
    assert len(expected) == 20
    assert bag_snapshots(busy, scene) == bag_snapshots(read_bag(tmp_path / "busy"), scene) == expected


def test_undecodable_recorded_output_names_the_bag_and_topic(tmp_path: Path) -> None:
    scene = load_scene(SCENES / "pyramid.yaml")
    snapshots = bag_snapshots(read_bag(DATA / "pyramid"), scene)
    with BagWriter(tmp_path / "out") as writer:
        writer.write(RECORDED_CONFIGURATION_TOPIC, POSE_ARRAY, 42, b"\x00\x01\x00\x00\xff")
    with pytest.raises(BagError) as raised:
        recorded_results(snapshots, read_bag(tmp_path / "out"), scene)
    assert str(raised.value).startswith(
        f"{tmp_path / 'out'}: {RECORDED_CONFIGURATION_TOPIC} at 42 ns: a {POSE_ARRAY} message"
    )


def test_a_recorded_pose_where_an_earlier_map_rested_an_instance_is_its_held_hypothesis(tmp_path: Path) -> None:
    """A node's previous-map check may put an instance where an earlier map of the node's rested it (its held
    hypothesis, not one of the bag's): the recorded configuration is still the snapshot's, the pose held."""
    box = {"shape": "box", "size": [0.1, 0.1, 0.1], "mass": 0.2}
    scene = scene_from_dict({"objects": [{"name": "box", "count": 2, **box}], "static": [FLOOR]}, "test")
    seen, rested = make_pose((0.3, 0.0, 0.05)), make_pose((0.3, 0.0, 0.049))  # it rested 1 mm lower
    hypotheses = tuple(RankedHypotheses.from_weighted([Hypothesis(p, 1.0)]) for p in (ON_FLOOR_POSE, seen))
    snapshots = [BagSnapshot(1, 10, hypotheses, None), BagSnapshot(2, 20, hypotheses, None)]
    with BagWriter(tmp_path / "out") as writer:
        write_results(
            writer,
            [
                SnapshotResult(snapshots[0], (1, 1), (ON_FLOOR_POSE, seen), (ON_FLOOR_POSE, rested)),
                SnapshotResult(snapshots[1], (1, 2), (ON_FLOOR_POSE, rested), (ON_FLOOR_POSE, rested)),
            ],
            "world",
        )
    first, second = recorded_results(snapshots, read_bag(tmp_path / "out"), scene)
    assert first.code == (1, 1) and first.snapshot == snapshots[0]
    assert second.code == (1, 2) and second.chosen is not None
    assert second.snapshot.hypotheses[1].held_rank() == 2
    assert second.snapshot.hypotheses[1].pose(2) == second.chosen[1]


def test_generate_draws_each_run_as_the_experiments_do(tmp_path: Path) -> None:
    """``generate --seed S`` then the offline replay's snapshots: the hypotheses and C111 errors of the experiments."""
    scene = load_scene(SCENES / "pyramid.yaml")
    assert scene.ground_truth is not None
    generate(tmp_path / "bag", "--seed", "11")  # RUNS runs of ITERATIONS iterations, 200 particles, top TOP_M
    settings = TrackerSettings(particles=200, iterations=ITERATIONS, top_m=TOP_M)
    options = ExperimentOptions(output_dir=tmp_path, seed=11, runs=RUNS)
    (experiment,) = track_and_search(
        scene, scene.ground_truth, settings, options, "test", lambda _: None, [scene.search]
    )
    snapshots = bag_snapshots(read_bag(tmp_path / "bag", input_topics(scene)), scene)
    assert len(snapshots) == RUNS * ITERATIONS
    positions = [[[h.pose.position for h in ranked.hypotheses] for ranked in s.hypotheses] for s in snapshots]
    assert np.array_equal(np.array(positions), experiment.hypothesis_positions.reshape(RUNS * ITERATIONS, 3, TOP_M, 3))
    top_errors_cm = [
        [100.0 * e for e in position_errors(rank_one_poses(s.hypotheses), s.ground_truth or ())] for s in snapshots
    ]
    assert np.array_equal(np.array(top_errors_cm), experiment.without_physics_errors.reshape(RUNS * ITERATIONS, 3))


ONE_HYPOTHESIS = RankedHypotheses.from_weighted([Hypothesis(make_pose((0.0, 0.0, 0.1)), 1.0)])


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_written_bags_name_jazzy_as_their_ros_distro(storage: str, tmp_path: Path) -> None:
    """As ``ros2 bag record`` on Jazzy does: ``ros2 bag info`` and rosbag2's reader see the distribution."""
    with BagWriter(tmp_path / "bag", "mcap" if storage == "mcap" else "sqlite3") as writer:
        writer.write_hypotheses(1, 1, "world", "cube", ONE_HYPOTHESIS)
    with Reader(tmp_path / "bag") as reader:
        assert reader.ros_distro == "jazzy"
    if storage == "mcap":
        assert verify_checksums(next((tmp_path / "bag").glob("*.mcap"))).summary  # the record rewritten, CRCs intact


def test_a_bag_in_another_serialisation_is_named_as_such(tmp_path: Path) -> None:
    bag = tmp_path / "json_bag"
    with BagWriter(bag) as writer:
        writer.write_hypotheses(1, 1, "world", "cube", ONE_HYPOTHESIS)
    metadata = bag / "metadata.yaml"
    metadata.write_text(metadata.read_text().replace("serialization_format: cdr", "serialization_format: json"))
    with pytest.raises(BagError, match=r"cannot read bag: Serialization format \{'json'\} is not supported"):
        read_bag(bag)


def test_a_folder_without_metadata_is_named_as_such(tmp_path: Path) -> None:
    bag = tmp_path / "no_metadata"
    shutil.copytree(DATA / "pyramid", bag)
    (bag / "metadata.yaml").unlink()
    with pytest.raises(BagError, match=r"no metadata\.yaml: not a rosbag2 bag"):
        read_bag(bag)
