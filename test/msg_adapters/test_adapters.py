"""msg_adapters with real message objects: round trips, every rejection class, results and diagnostics."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import PROBLEMS, SCENES
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseArray
from mesh_builders import MUG_FILE, floor_scene_dict, load_inline, mesh_object
from rclpy.serialization import deserialize_message, serialize_message
from ros_helpers import REQUIRED_DIAGNOSTIC_KEYS
from rosbags.typesys import Stores, get_typestore
from std_msgs.msg import Float64MultiArray
from visualization_msgs.msg import Marker

from physics_mapper.mapping.inputs import InputSettings, InputTracker, Level, ObjectInputs, rank
from physics_mapper.mapping.mapper import Mapper, MapperSettings
from physics_mapper.model.geometry import Pose, make_pose
from physics_mapper.model.hypotheses import Hypothesis, RankedHypotheses
from physics_mapper.model.limits import MAX_DIAGNOSTIC_TEXT
from physics_mapper.model.scene import (
    Box,
    Cylinder,
    ObjectModel,
    Plane,
    Scene,
    SearchParams,
    Sphere,
    StaticBody,
    Strategy,
    Workspace,
)
from physics_mapper.model.scene_files import load_problem, load_scene
from physics_mapper.msg_adapters.diagnostics import diagnostics_msg
from physics_mapper.msg_adapters.hypotheses import (
    hypotheses_msgs,
    nanoseconds_from_stamp,
    pose_array_msg,
    raw_pose,
    received_pose_array,
    received_poses,
    received_weights,
    stamp_from_nanoseconds,
)
from physics_mapper.msg_adapters.pose_array_cdr import pose_array_view
from physics_mapper.msg_adapters.results import (
    FALLBACK_COLOR,
    LABEL_NAMESPACE,
    PLANE_MARKER_SIZE,
    SHAPE_NAMESPACE,
    STATIC_COLOR,
    STATIC_NAMESPACE,
    configuration_msgs,
    markers_msg,
    object_pose_msgs,
    static_markers_msg,
)
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.search.report import COUNTER_WORDS, counters_text, stats_dict
from physics_mapper.search.strategy import paper_search

#: A 20 m box about the origin, as a scene's default workspace may be.
WORKSPACE = Workspace((-10.0, -10.0, -10.0), (10.0, 10.0, 10.0))
TILTED = make_pose((0.1, -0.2, 0.3), (0.1, 0.2, 0.3, math.sqrt(1.0 - 0.14)))


def pose_array(*poses: tuple[tuple[float, ...], tuple[float, ...]], frame: str = "world") -> PoseArray:
    """A PoseArray with raw (unvalidated) values, as a publisher may send them."""
    msg = pose_array_msg([], frame_id=frame, stamp_ns=12_500_000_000)
    for position, orientation in poses:
        pose = pose_array_msg([Pose((0.0, 0.0, 0.0))], frame_id=frame, stamp_ns=0).poses[0]
        pose.position.x, pose.position.y, pose.position.z = position
        pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w = orientation
        msg.poses.append(pose)
    return msg


#: A stamp of today's epoch magnitude, where float seconds resolve only ~0.2 us.
REALISTIC_STAMP_NS = 1_732_233_600_123_456_789


def test_stamps_round_trip_to_the_nanosecond() -> None:
    stamp = stamp_from_nanoseconds(REALISTIC_STAMP_NS)
    assert (stamp.sec, stamp.nanosec) == (1_732_233_600, 123_456_789)
    assert nanoseconds_from_stamp(stamp) == REALISTIC_STAMP_NS
    assert nanoseconds_from_stamp(stamp_from_nanoseconds(2_500_000_000)) == 2_500_000_000


@pytest.mark.parametrize("serialised", [False, True], ids=["message", "serialised"])
def test_poses_round_trip_through_a_pose_array(serialised: bool) -> None:
    msg = pose_array_msg([TILTED, Pose((1.0, 2.0, 3.0))], frame_id="world", stamp_ns=7_250_000_000)
    assert msg.header.frame_id == "world"
    if serialised:  # as the node's raw subscription receives it
        received = received_pose_array(
            serialize_message(msg), expected_frame="world", workspace=WORKSPACE, received=8.0
        )
    else:
        received = received_poses(msg, expected_frame="world", workspace=WORKSPACE, received=8.0)
    assert (received.stamp_ns, received.received, received.count, received.refusal) == (7_250_000_000, 8.0, 2, None)
    in_use = rank(received, None, max_hypotheses=100)
    assert not isinstance(in_use, str)
    assert [h.pose for h in in_use.hypotheses.hypotheses] == [TILTED, Pose((1.0, 2.0, 3.0))]


def test_serialised_pose_arrays_are_read_like_rclpy_reads_them() -> None:
    """Every frame_id length (the padding before the poses), both byte orders, and bytes that are not one."""
    rng = np.random.default_rng(3)
    for length in range(13):
        for count in (0, 1, 3):
            msg = pose_array_msg([], frame_id="f" * length, stamp_ns=int(rng.integers(0, 2**31 * 10**9)))
            for values in rng.normal(size=(count, 7)):
                pose = pose_array_msg([Pose((0.0, 0.0, 0.0))], frame_id="", stamp_ns=0).poses[0]
                p, q = pose.position, pose.orientation
                p.x, p.y, p.z, q.x, q.y, q.z, q.w = (float(v) for v in values)
                msg.poses.append(pose)
            for raw in (serialize_message(msg), big_endian(serialize_message(msg))):
                view = pose_array_view(raw)
                assert view is not None
                assert (view.stamp_ns, view.frame_id) == (nanoseconds_from_stamp(msg.header.stamp), msg.header.frame_id)
                expected = [[*raw_pose(pose)[0], *raw_pose(pose)[1]] for pose in msg.poses]
                assert view.poses.tolist() == expected
    assert pose_array_view(serialize_message(msg)[:-1]) is None  # truncated
    assert pose_array_view(b"\x00\x07\x00\x00" + bytes(serialize_message(msg))[4:]) is None  # not plain CDR


def test_a_frame_id_without_its_nul_reads_as_rclpy_reads_it() -> None:
    """A publisher's bytes whose frame_id ends in no NUL: its last byte is kept, as rclpy keeps it."""
    raw = bytearray(serialize_message(pose_array(((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0)), frame="world")))
    at = raw.index(b"world\0") + len("world")
    raw[at] = ord("x")
    view = pose_array_view(bytes(raw))
    assert view is not None and view.frame_id == deserialize_message(bytes(raw), PoseArray).header.frame_id == "worldx"


def big_endian(raw: bytes) -> bytes:
    """The same PoseArray serialised big-endian (rosbags; rclpy writes the machine's order)."""
    typestore = get_typestore(Stores.ROS2_JAZZY)
    message = typestore.deserialize_cdr(raw, "geometry_msgs/msg/PoseArray")
    return bytes(typestore.serialize_cdr(message, "geometry_msgs/msg/PoseArray", little_endian=False))


def test_hypotheses_round_trip_through_pose_array_and_weights() -> None:
    ranked = RankedHypotheses.from_weighted(
        [Hypothesis(TILTED, 0.2), Hypothesis(Pose((0.0, 0.0, 1.0)), 0.5), Hypothesis(Pose((1.0, 0.0, 0.0)), 0.3)]
    )
    poses_msg, weights = hypotheses_msgs(ranked, frame_id="world", stamp_ns=3_000_000_000)
    assert isinstance(weights, Float64MultiArray)
    assert list(weights.data) == [h.weight for h in ranked.hypotheses]
    in_use = rank(
        received_poses(poses_msg, expected_frame="world", workspace=WORKSPACE, received=3.0),
        received_weights(weights, received=3.0),
        max_hypotheses=100,
    )
    assert not isinstance(in_use, str)
    assert [h.weight for h in in_use.hypotheses.hypotheses] == pytest.approx([h.weight for h in ranked.hypotheses])
    assert [h.pose for h in in_use.hypotheses.hypotheses] == [h.pose for h in ranked.hypotheses]


@pytest.mark.parametrize(
    ("position", "orientation", "problem"),
    [
        ((math.nan, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0), "non-finite value (NaN or Inf) in pose"),
        ((0.0, 0.0, -math.inf), (0.0, 0.0, 0.0, 1.0), "non-finite value (NaN or Inf) in pose"),
        ((0.0, 0.0, 0.0), (0.0, 0.0, math.nan, 1.0), "non-finite value (NaN or Inf) in pose"),
        ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 0.0), "zero quaternion"),
        ((0.0, 0.0, 0.0), (0.0, 0.0, 0.5, 0.5), "quaternion norm 0.7071 is not 1"),
        ((0.0, 1e300, 0.0), (0.0, 0.0, 0.0, 1.0), "(0, 1e+300, 0) m is outside the workspace x [-10, 10]"),
    ],
)
def test_every_bad_pose_class_is_named(
    position: tuple[float, ...], orientation: tuple[float, ...], problem: str
) -> None:
    msg = pose_array(((0.0, 0.0, 0.1), (0.0, 0.0, 0.0, 1.0)), (position, orientation))
    received = received_poses(msg, expected_frame="world", workspace=WORKSPACE, received=0.0)
    assert received.refusal is None
    in_use = rank(received, None, max_hypotheses=100)
    assert not isinstance(in_use, str)
    assert len(in_use.hypotheses) == 1
    assert in_use.notes[1].startswith(f"dropped 1 of 2 poses: poses[1]: {problem}")
    alone_msg = pose_array((position, orientation))
    alone = rank(received_poses(alone_msg, expected_frame="world", workspace=WORKSPACE, received=0.0), None, 100)
    assert isinstance(alone, str) and alone.startswith(f"no usable pose (poses[0]: {problem}")


def test_a_wrong_frame_and_an_empty_array_are_refused() -> None:
    wrong = received_poses(
        pose_array(((0.0, 0.0, 0.1), (0, 0, 0, 1)), frame="map"),
        expected_frame="world",
        workspace=WORKSPACE,
        received=0,
    )
    assert wrong.refusal == "frame_id 'map' is not the scene frame 'world'"
    empty = received_poses(pose_array(), expected_frame="world", workspace=WORKSPACE, received=0.0)
    assert empty.refusal == "empty PoseArray"


@pytest.mark.parametrize(
    ("values", "refusal"),
    [
        ([0.2, -0.1], "negative weight"),
        ([0.0, 0.0], "weights sum to zero"),
        ([1e308, 1e308], "weights sum to infinity (too large to normalise)"),
        ([0.5, math.nan], "non-finite weight (NaN or Inf)"),
        ([0.5, math.inf], "non-finite weight (NaN or Inf)"),
        ([], "empty weights array"),
    ],
)
def test_every_bad_weights_class_is_named(values: list[float], refusal: str) -> None:
    assert received_weights(Float64MultiArray(data=values), received=0.0).refusal == refusal


def test_weights_of_the_wrong_length_and_oversized_arrays_through_messages() -> None:
    inputs = ObjectInputs("cube")
    poses = [Pose((0.01 * i, 0.0, 0.1)) for i in range(150)]
    inputs.add_poses(
        received_poses(
            pose_array_msg(poses, frame_id="world", stamp_ns=1), expected_frame="world", workspace=WORKSPACE, received=1
        )
    )
    inputs.add_weights(received_weights(Float64MultiArray(data=[1.0] * 149), received=1.0))
    status = inputs.status(2.0, InputSettings(max_hypotheses=100))
    assert status.level == Level.WARN
    assert "no weights message of length 150 (weights received have length 149)" in status.message
    assert "kept the 100 heaviest of 150 hypotheses (max_hypotheses_per_object)" in status.message
    assert status.hypotheses is not None and len(status.hypotheses) == 100


# --- results -------------------------------------------------------------------------------------

MIXED = Scene(
    objects=(
        ObjectModel("crate", Box((0.2, 0.1, 0.06))),
        ObjectModel("ball", Sphere(0.05), mass=0.1, rolling_friction=0.01),
        ObjectModel("peg", Cylinder(0.02, 0.1), mass=0.05),
    ),
    static=(StaticBody("floor", Plane()),),
    search=SearchParams(deadline=5.0),
    frame_id="table",
)
RESTING = (Pose((0.0, 0.0, 0.03)), Pose((0.5, 0.0, 0.05)), Pose((-0.5, 0.0, 0.05)))


@pytest.fixture(scope="module")
def mixed_result() -> object:
    hypotheses = [RankedHypotheses.from_weighted([Hypothesis(pose, 1.0)]) for pose in RESTING]
    with PhysicsChecker(MIXED) as checker:
        return paper_search(checker, hypotheses, MIXED.search).run(None)


def test_configuration_messages_hold_chosen_and_settled_poses(mixed_result: object) -> None:
    from physics_mapper.search.results import SearchResult

    assert isinstance(mixed_result, SearchResult) and mixed_result.valid
    messages = configuration_msgs(mixed_result, frame_id="table", stamp_ns=4_500_000_000)
    assert messages is not None
    chosen, settled = messages
    for msg, poses in ((chosen, mixed_result.poses), (settled, mixed_result.settled_poses)):
        assert msg.header.frame_id == "table" and nanoseconds_from_stamp(msg.header.stamp) == 4_500_000_000
        back = received_poses(msg, expected_frame="table", workspace=WORKSPACE, received=0.0)
        assert poses is not None
        assert back.poses.tolist() == [[*pose.position, *pose.orientation] for pose in poses]


def test_each_object_gets_its_chosen_and_settled_pose_with_the_map_s_header(mixed_result: object) -> None:
    from physics_mapper.search.results import SearchResult

    assert isinstance(mixed_result, SearchResult)
    assert mixed_result.poses is not None and mixed_result.settled_poses is not None
    per_object = object_pose_msgs(mixed_result, frame_id="table", stamp_ns=REALISTIC_STAMP_NS)
    configurations = configuration_msgs(mixed_result, frame_id="table", stamp_ns=REALISTIC_STAMP_NS)
    assert per_object is not None and configurations is not None and len(per_object) == len(MIXED.objects)
    for index, poses in enumerate(per_object):
        assert poses is not None
        chosen, settled = poses
        assert chosen.header == settled.header == configurations[0].header
        assert chosen.pose == configurations[0].poses[index]
        assert settled.pose == configurations[1].poses[index]


def test_an_object_the_map_leaves_out_is_in_no_array_and_its_markers_are_deleted(mixed_result: object) -> None:
    from physics_mapper.search.results import SearchResult

    assert isinstance(mixed_result, SearchResult) and mixed_result.poses is not None
    present = tuple(range(1, len(MIXED.objects)))  # the first object left out
    configurations = configuration_msgs(mixed_result, frame_id="table", stamp_ns=REALISTIC_STAMP_NS, present=present)
    per_object = object_pose_msgs(mixed_result, frame_id="table", stamp_ns=REALISTIC_STAMP_NS, present=present)
    assert configurations is not None and per_object is not None
    assert len(configurations[0].poses) == len(present) and per_object[0] is None
    assert all(poses is not None for poses in per_object[1:])
    markers = markers_msg(mixed_result, MIXED, stamp_ns=REALISTIC_STAMP_NS, present=present).markers
    deleted = [(m.ns, m.id) for m in markers if m.action == Marker.DELETE]
    assert deleted == [(SHAPE_NAMESPACE, 0), (LABEL_NAMESPACE, 0)]


def test_a_realistic_stamp_goes_from_input_to_outputs_exactly(mixed_result: object) -> None:
    """A PoseArray's stamp -> ReceivedPoses -> InputSnapshot -> configuration, settled and markers headers."""
    from physics_mapper.search.results import SearchResult

    assert isinstance(mixed_result, SearchResult)
    tracker = InputTracker(["crate"])
    msg = pose_array_msg([TILTED], frame_id="table", stamp_ns=REALISTIC_STAMP_NS)
    tracker.add_poses("crate", received_poses(msg, expected_frame="table", workspace=WORKSPACE, received=1.0))
    stamp_ns = tracker.snapshot(1.0, InputSettings()).stamp_ns
    assert stamp_ns == REALISTIC_STAMP_NS
    messages = configuration_msgs(mixed_result, frame_id="table", stamp_ns=stamp_ns)
    assert messages is not None
    headers = [m.header for m in messages] + [
        m.header for m in markers_msg(mixed_result, MIXED, stamp_ns=stamp_ns).markers
    ]
    assert {(h.stamp.sec, h.stamp.nanosec) for h in headers} == {(1_732_233_600, 123_456_789)}


def test_markers_show_each_objects_true_shape_and_a_label_with_its_jitter(mixed_result: object) -> None:
    from physics_mapper.search.results import SearchResult

    assert isinstance(mixed_result, SearchResult)
    markers = markers_msg(mixed_result, MIXED, stamp_ns=4_500_000_000).markers
    shapes = [m for m in markers if m.ns == SHAPE_NAMESPACE]
    labels = [m for m in markers if m.ns == LABEL_NAMESPACE]
    assert len(shapes) == len(labels) == 3
    assert [m.type for m in shapes] == [Marker.CUBE, Marker.SPHERE, Marker.CYLINDER]
    assert [(m.scale.x, m.scale.y, m.scale.z) for m in shapes] == [(0.2, 0.1, 0.06), (0.1, 0.1, 0.1), (0.04, 0.04, 0.1)]
    assert [m.id for m in shapes] == [0, 1, 2]
    assert all(m.header.frame_id == "table" for m in markers)
    assert [(m.pose.position.x, m.pose.position.z) for m in shapes] == [(p.position[0], p.position[2]) for p in RESTING]
    jitters = mixed_result.object_jitters
    assert jitters is not None
    assert [m.text for m in labels] == [
        f"{n}\nJ={j:.4f}" for n, j in zip(("crate", "ball", "peg"), jitters, strict=True)
    ]
    assert all(m.type == Marker.TEXT_VIEW_FACING for m in labels)
    assert sum(jitters) == pytest.approx(mixed_result.jitter)


def test_a_fallback_is_drawn_orange_at_its_settled_poses() -> None:
    """With fallback settled, the map shown is the corrected estimate: the ball at rest in the groove."""
    problem = load_problem(PROBLEMS / "sphere_groove.yaml")
    with PhysicsChecker(problem.scene) as checker:
        result = paper_search(checker, problem.hypotheses, problem.scene.search).run(None)
    assert result.fallback_used and result.settled_poses is not None and result.poses is not None
    (shape,) = [m for m in markers_msg(result, problem.scene, stamp_ns=0).markers if m.ns == SHAPE_NAMESPACE]
    settled = result.settled_poses[0].position
    assert (shape.pose.position.x, shape.pose.position.y, shape.pose.position.z) == settled
    assert settled != result.poses[0].position
    assert (shape.color.r, shape.color.g, shape.color.b) == (FALLBACK_COLOR.r, FALLBACK_COLOR.g, FALLBACK_COLOR.b)


def test_nothing_chosen_gives_no_configuration_and_no_markers() -> None:
    floating = [RankedHypotheses.from_weighted([Hypothesis(Pose((0.0, 0.0, 1.0)), 1.0)])] + [
        RankedHypotheses.from_weighted([Hypothesis(pose, 1.0)]) for pose in RESTING[1:]
    ]
    with PhysicsChecker(MIXED) as checker:
        result = paper_search(checker, floating, MIXED.search).run(None)
    assert result.code is None
    assert configuration_msgs(result, frame_id="table", stamp_ns=0) is None
    assert markers_msg(result, MIXED, stamp_ns=0).markers == []


# --- diagnostics ---------------------------------------------------------------------------------


def test_diagnostics_hold_the_spec_keys_and_one_status_per_object() -> None:
    scene = load_scene(SCENES / "pyramid.yaml")
    mapper = Mapper(scene)
    settings = MapperSettings(SearchParams(deadline=0.3), InputSettings(), rate_hz=2.0)
    try:
        waiting = diagnostics_msg(
            mapper.tick(0.0, settings), node_name="physics_mapper", hardware_id="/ns/physics_mapper", stamp_ns=0
        )
        assert waiting.status[0].level == DiagnosticStatus.WARN
        assert waiting.status[0].message == "waiting for hypotheses of: cube_left, cube_right, cube_top"
        for name, x, z in (("cube_left", -0.105, 0.1), ("cube_right", 0.105, 0.1), ("cube_top", 0.0, 0.3)):
            msg = pose_array_msg([Pose((x, 0.0, z))], frame_id="world", stamp_ns=1_000_000_000)
            mapper.inputs.add_poses(
                name, received_poses(msg, expected_frame="world", workspace=WORKSPACE, received=1.0)
            )
            mapper.inputs.add_weights(name, received_weights(Float64MultiArray(data=[1.0]), received=1.0))
        report = mapper.tick(1.0, settings)
    finally:
        mapper.close()
    diagnostics = diagnostics_msg(
        report, node_name="physics_mapper", hardware_id="/ns/physics_mapper", stamp_ns=1_000_000_000
    )
    search, *objects = diagnostics.status
    values = {kv.key: kv.value for kv in search.values}
    assert set(REQUIRED_DIAGNOSTIC_KEYS) <= set(values)
    assert (search.name, search.level) == ("physics_mapper: search", DiagnosticStatus.OK)
    assert search.message.startswith("valid C111, p(C)=1, J=")
    assert values["best code"] == "C111" and values["nodes visited"] == "1" and values["deadline [s]"] == "0.3"
    assert float(values["search time [s]"]) == pytest.approx(report.search_time, abs=1e-6)
    assert [values[f"input {n}"] for n in scene.object_names] == ["OK: 1 hypotheses, weighted"] * 3
    assert [s.name for s in objects] == [f"physics_mapper: hypotheses/{n}" for n in scene.object_names]
    assert all(s.level == DiagnosticStatus.OK for s in objects)
    assert {s.hardware_id for s in diagnostics.status} == {"/ns/physics_mapper"}
    assert dict((kv.key, kv.value) for kv in objects[0].values)["weights"] == "paired"


@pytest.mark.parametrize("strategy", ["joint", "conflict"])
def test_only_a_search_whose_parts_count_conflicts_reports_them(strategy: Strategy) -> None:
    """The conflict-directed default's parts count conflicts and settlings by kind: its stats, JSON and
    diagnostics carry them, under their words; the paper's parts count none, and the joint search's
    carry none of them."""
    scene = load_scene(SCENES / "pyramid.yaml")
    mapper = Mapper(scene)
    try:
        for name, x, z in (("cube_left", -0.105, 0.1), ("cube_right", 0.105, 0.1), ("cube_top", 0.0, 0.3)):
            msg = pose_array_msg([Pose((x, 0.0, z))], frame_id="world", stamp_ns=1_000_000_000)
            mapper.inputs.add_poses(
                name, received_poses(msg, expected_frame="world", workspace=WORKSPACE, received=1.0)
            )
        report = mapper.tick(1.0, MapperSettings(SearchParams(strategy=strategy), InputSettings()))
    finally:
        mapper.close()
    assert report.result is not None and report.result.valid
    stats = report.result.stats
    values = {
        kv.key: kv.value for kv in diagnostics_msg(report, node_name="n", hardware_id="/n", stamp_ns=0).status[0].values
    }
    if strategy == "joint":
        assert stats.part_counters == {} and all(group.part_counters == {} for group in report.result.groups)
        assert not set(COUNTER_WORDS) & set(stats_dict(stats))
        assert not set(COUNTER_WORDS.values()) & set(values) and "conflicts of group" not in values
    else:
        assert set(stats.part_counters) == set(COUNTER_WORDS) and stats.part_counters["full_settlings"] > 0
        assert {name: stats_dict(stats)[name] for name in COUNTER_WORDS} == stats.part_counters
        assert {name: int(values[words]) for name, words in COUNTER_WORDS.items()} == stats.part_counters
        assert values["conflicts of group"] == counters_text(stats.part_counters)


def test_every_diagnostics_string_is_clipped() -> None:
    """50 objects with 200-character names waiting for input: a 10,000-character message, clipped."""
    names = [f"{index:03d}" + "o" * 197 for index in range(50)]
    scene = Scene(objects=tuple(ObjectModel(name, Sphere(0.05)) for name in names))
    mapper = Mapper(scene)
    try:
        report = mapper.tick(0.0, MapperSettings(SearchParams(), InputSettings()))
    finally:
        mapper.close()
    diagnostics = diagnostics_msg(report, node_name="n", hardware_id="/n", stamp_ns=0)
    texts = [status.message for status in diagnostics.status]
    texts += [kv.value for status in diagnostics.status for kv in status.values]
    assert max(len(text) for text in texts) == MAX_DIAGNOSTIC_TEXT
    assert diagnostics.status[0].message.endswith(" characters)")
    assert diagnostics.status[0].message.startswith(f"waiting for hypotheses of: {names[0]}, {names[1]}")


def test_diagnostics_say_when_a_settling_continues_over_ticks() -> None:
    """A settling far longer than one tick's search (10 s simulated, 1 ms per tick) is named until it ends."""
    scene = load_scene(SCENES / "pyramid.yaml")
    mapper = Mapper(scene)
    settings = MapperSettings(SearchParams(deadline=0.001, settle_time=10.0), InputSettings(), rate_hz=2.0)
    try:
        for name, x, z in (("cube_left", -0.105, 0.1), ("cube_right", 0.105, 0.1), ("cube_top", 0.0, 0.3)):
            msg = pose_array_msg([Pose((x, 0.0, z))], frame_id="world", stamp_ns=1_000_000_000)
            mapper.inputs.add_poses(
                name, received_poses(msg, expected_frame="world", workspace=WORKSPACE, received=1.0)
            )
        # On a slow machine the first ticks' millisecond goes to making the search and Rule 1.
        states = [mapper.tick(1.0, settings)]
        while states[-1].settling_in_progress is None and len(states) < 100:
            states.append(mapper.tick(1.0, settings))
        settling = states[-1]
        while states[-1].settling_in_progress is not None and len(states) < 10_000:
            states.append(mapper.tick(1.0, settings))
    finally:
        mapper.close()
    assert settling.settling_in_progress == (1, 1, 1)
    values = {
        kv.key: kv.value
        for kv in diagnostics_msg(settling, node_name="n", hardware_id="/n", stamp_ns=0).status[0].values
    }
    started = "new" if settling is states[0] else "resumed"
    assert values["search"] == f"{started}, stopped at the deadline, settling C111 continues next tick"
    last = states[-1]
    assert last.settling_in_progress is None and last.result is not None and last.result.valid
    values = {
        kv.key: kv.value for kv in diagnostics_msg(last, node_name="n", hardware_id="/n", stamp_ns=0).status[0].values
    }
    assert values["search"] == "resumed, exhausted (every node visited)"


# --- meshes and fixed bodies in RViz ------------------------------------------------------------------


def test_a_mesh_object_is_a_mesh_resource_and_fixed_bodies_are_drawn_grey() -> None:
    table = {"name": "table", "shape": "box", "size": [1.0, 1.0, 0.05], "pose": {"position": [0.0, 0.0, 0.575]}}
    mug = mesh_object("mug", MUG_FILE, scale=[1.0, 1.0, 1.5], mass=0.3)
    scene = load_inline(floor_scene_dict(mug, static=(table,)), SCENES)
    with PhysicsChecker(scene) as checker:
        hypotheses = [RankedHypotheses.from_weighted([Hypothesis(Pose((0.0, 0.0, 0.6)), 1.0)])]
        result = paper_search(checker, hypotheses, scene.search).run(None)
    assert result.valid
    markers = markers_msg(result, scene, stamp_ns=0).markers
    (shape,) = [m for m in markers if m.ns == SHAPE_NAMESPACE]
    assert shape.type == Marker.MESH_RESOURCE
    assert shape.mesh_resource.startswith("file:///") and shape.mesh_resource.endswith("/pybullet_data/objects/mug.obj")
    assert (shape.scale.x, shape.scale.y, shape.scale.z) == (1.0, 1.0, 1.5)
    (label,) = [m for m in markers if m.ns == LABEL_NAMESPACE]
    assert label.pose.position.z == pytest.approx(0.6 + 1.5 * 0.1 + 0.04)  # above the mug's top
    floor, table_marker = [m for m in markers if m.ns == STATIC_NAMESPACE]
    assert [m.id for m in (floor, table_marker)] == [0, 1]
    assert (floor.type, floor.scale.x, floor.scale.z) == (Marker.CUBE, PLANE_MARKER_SIZE, pytest.approx(0.002))
    assert floor.pose.position.z == pytest.approx(-0.001)  # its top face is the plane
    assert (table_marker.type, table_marker.pose.position.z) == (Marker.CUBE, 0.575)
    assert all(m.color == STATIC_COLOR for m in (floor, table_marker))
    alone = static_markers_msg(scene, stamp_ns=5).markers
    assert [(m.ns, m.id, m.type) for m in alone] == [(m.ns, m.id, m.type) for m in (floor, table_marker)]
    assert all(m.header.frame_id == scene.frame_id and m.header.stamp.nanosec == 5 for m in alone)
