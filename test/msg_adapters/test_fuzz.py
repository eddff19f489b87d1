"""Property-based fuzzing (hypothesis) of the message adapters, the input rules, the mapper and the file loader.

Invariants:

- no exception escapes except the documented one (none from a message; :class:`SceneError` from a file);
- every refusal and every dropped pose has a reason, short and on one line;
- the usable part of a message survives: exactly its good poses, unchanged, in order;
- a result is valid only if it passed both rules inside the workspace (checked again in a fresh world).

Inputs: floats of every kind (NaN, +-Inf, subnormal, huge), array lengths, quaternions, weights,
frame ids, YAML documents and bytes. Example counts and randomness: the profiles in ``conftest.py``.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import pytest
import yaml
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Point, PoseArray, Quaternion
from geometry_msgs.msg import Pose as PoseMsg
from hypothesis import given, settings
from hypothesis import strategies as st
from std_msgs.msg import Float64MultiArray, Header

from physics_mapper.mapping.inputs import InputSettings, InputTracker, InUse, Level, ReceivedPoses, rank
from physics_mapper.mapping.mapper import Mapper, MapperSettings, TickReport
from physics_mapper.model.limits import MAX_DIAGNOSTIC_TEXT
from physics_mapper.model.scene import Box, ObjectModel, Plane, Scene, SearchParams, StaticBody, Workspace
from physics_mapper.model.scene_files import SceneError, load_problem, problem_from_dict
from physics_mapper.model.yaml_files import parse_yaml
from physics_mapper.msg_adapters.diagnostics import diagnostics_msg
from physics_mapper.msg_adapters.hypotheses import received_poses, received_weights
from physics_mapper.physics.checker import PhysicsChecker

FRAME = "world"
WORKSPACE = Workspace((-1.0, -1.0, 0.0), (1.0, 1.0, 1.0))
#: Floats that break naive code, beside hypothesis's own float strategy (which draws NaN, Inf and subnormals too).
AWKWARD: tuple[float, ...] = (0.0, -0.0, 1.0, -1.0, math.nan, math.inf, -math.inf, 5e-324, 2.2250738585072014e-308)
AWKWARD += (1e15, -1e15, 1e300, 4e292, 1.7976931348623157e308, -1.7976931348623157e308)
any_float = st.one_of(st.floats(), st.sampled_from(AWKWARD))
frame_ids = st.one_of(st.just(FRAME), st.text(st.characters(codec="utf-8"), max_size=300))
#: Longest reason the input rules give for a refused message or a dropped pose.
MAX_REASON = 400

RawPose = tuple[tuple[float, float, float], tuple[float, float, float, float]]


def pose_array(poses: Sequence[RawPose], frame_id: str = FRAME) -> PoseArray:
    msg = PoseArray(header=Header(frame_id=frame_id))
    for (x, y, z), (qx, qy, qz, qw) in poses:
        msg.poses.append(PoseMsg(position=Point(x=x, y=y, z=z), orientation=Quaternion(x=qx, y=qy, z=qz, w=qw)))
    return msg


def one_line(reason: str) -> bool:
    return bool(reason) and "\n" not in reason and len(reason) <= MAX_REASON


# --- poses: a message's good poses survive, every other one is dropped with its reason -------------


NEAR_ONE = st.floats(0.995, 1.005)


@st.composite
def unit_quaternions(draw: st.DrawFn, scale: st.SearchStrategy[float] = NEAR_ONE) -> tuple[float, ...]:
    """A quaternion along a random direction, with a norm drawn from ``scale``."""
    direction = draw(st.tuples(*[st.floats(-1.0, 1.0)] * 4).filter(lambda v: math.hypot(*v) > 0.1))
    norm, factor = math.hypot(*direction), draw(scale)
    return tuple(v / norm * factor for v in direction)


def inside(low: float, high: float) -> st.SearchStrategy[float]:
    return st.floats(low + 1e-6, high - 1e-6)


good_positions = st.tuples(
    *(inside(low, high) for low, high in zip(WORKSPACE.min_corner, WORKSPACE.max_corner, strict=True))
)
good_poses = st.tuples(good_positions, unit_quaternions())


@st.composite
def bad_poses(draw: st.DrawFn) -> RawPose:
    """A pose the input rules must drop: non-finite, zero or non-unit quaternion, or outside the workspace."""
    position, orientation = draw(good_poses)
    kind = draw(st.sampled_from(("non-finite", "zero quaternion", "non-unit quaternion", "outside")))
    values = [*position, *orientation]
    if kind == "non-finite":
        values[draw(st.integers(0, 6))] = draw(st.sampled_from((math.nan, math.inf, -math.inf)))
    elif kind == "zero quaternion":
        values[3:] = [0.0, -0.0, 0.0, 0.0]
    elif kind == "non-unit quaternion":
        values[3:] = draw(unit_quaternions(st.one_of(st.floats(0.0, 0.98), st.floats(1.02, 1e300))))
    else:
        axis = draw(st.integers(0, 2))
        beyond = draw(st.one_of(st.floats(1e-3, 1e3), st.sampled_from((1e15, 4e292, 1e300))))
        low, high = WORKSPACE.min_corner[axis], WORKSPACE.max_corner[axis]
        values[axis] = low - beyond if draw(st.booleans()) else high + beyond
    return (values[0], values[1], values[2]), (values[3], values[4], values[5], values[6])


@given(st.lists(st.one_of(good_poses.map(lambda p: (True, p)), bad_poses().map(lambda p: (False, p))), max_size=12))
def test_the_good_poses_of_a_message_survive_unchanged_and_every_other_is_dropped_with_a_reason(
    items: list[tuple[bool, RawPose]],
) -> None:
    """Poses are checked when adopted (rank), heaviest first: uniform weights examine them in published order."""
    received = received_poses(pose_array([p for _, p in items]), expected_frame=FRAME, workspace=WORKSPACE, received=0)
    good = [i for i, (ok, _) in enumerate(items) if ok]
    if not items:
        assert received.refusal == "empty PoseArray"
        return
    assert received.refusal is None
    in_use = rank(received, None, max_hypotheses=len(items))
    if not good:
        assert isinstance(in_use, str) and in_use.startswith("no usable pose (poses[") and one_line(in_use)
        return
    assert isinstance(in_use, InUse)
    assert [d.partition(": ")[0] for d in in_use.dropped] == [
        f"poses[{i}]" for i, (ok, _) in enumerate(items) if not ok
    ]
    assert all(one_line(d) for d in in_use.dropped)
    assert len(in_use.hypotheses) == len(good)
    for hypothesis, index in zip(in_use.hypotheses.hypotheses, good, strict=True):
        position, orientation = items[index][1]
        norm = math.hypot(*orientation)
        assert hypothesis.pose.position == position
        assert hypothesis.pose.orientation == pytest.approx(tuple(v / norm for v in orientation), abs=1e-12)


raw_poses = st.tuples(st.tuples(*[any_float] * 3), st.tuples(*[any_float] * 4))


def check_received(received: ReceivedPoses, count: int) -> None:
    """Structural invariants of any PoseArray received and adopted."""
    assert received.count == count
    if received.refusal is not None:
        assert one_line(received.refusal)
        return
    in_use = rank(received, None, max_hypotheses=max(count, 1))
    if isinstance(in_use, str):
        assert one_line(in_use) and in_use.startswith("no usable pose (")
        return
    dropped = [int(d[len("poses[") : d.index("]")]) for d in in_use.dropped]
    assert len(in_use.hypotheses) + len(dropped) == count and len(set(dropped)) == len(dropped)
    for hypothesis in in_use.hypotheses.hypotheses:
        pose = hypothesis.pose
        assert WORKSPACE.problem(pose.position) is None
        assert all(math.isfinite(v) for v in (*pose.position, *pose.orientation))
        assert math.hypot(*pose.orientation) == pytest.approx(1.0, abs=1e-12)


@given(st.lists(raw_poses, max_size=12), frame_ids)
def test_any_pose_array_is_checked_without_an_exception(poses: list[RawPose], frame_id: str) -> None:
    received = received_poses(pose_array(poses, frame_id), expected_frame=FRAME, workspace=WORKSPACE, received=0)
    check_received(received, len(poses))
    if frame_id not in (FRAME, ""):  # no frame at all is taken as the scene's
        assert received.refusal is not None and received.refusal.startswith("frame_id ")
    assert received.frame_assumed == (frame_id == "")


# --- weights ----------------------------------------------------------------------------------------

weights_lists = st.lists(st.one_of(any_float, st.floats(0.0, 1.0)), max_size=12)


@given(weights_lists)
def test_weights_are_kept_exactly_when_usable_and_refused_with_a_reason_otherwise(values: list[float]) -> None:
    received = received_weights(Float64MultiArray(data=values), received=0.0)
    usable = bool(values) and all(math.isfinite(v) and v >= 0.0 for v in values) and 0.0 < sum(values) < math.inf
    if usable:
        assert received.refusal is None and received.values.tolist() == values
    else:
        assert received.refusal is not None and one_line(received.refusal)


# --- the input rules over sequences of messages, and their diagnostics -----------------------------

OBJECTS = ("cube_a", "cube_b")
messages = st.one_of(
    st.tuples(st.just("poses"), st.sampled_from(OBJECTS), st.lists(raw_poses | good_poses, max_size=6), frame_ids),
    st.tuples(st.just("weights"), st.sampled_from(OBJECTS), weights_lists, st.just("")),
)


@given(
    st.lists(st.tuples(messages, st.floats(0.0, 2.0)), max_size=12),
    st.integers(1, 4),
    st.booleans(),
)
def test_any_sequence_of_messages_gives_a_usable_snapshot_and_bounded_diagnostics(
    events: list[tuple[tuple[str, str, Any, str], float]], max_hypotheses: int, require_weights: bool
) -> None:
    tracker, now = InputTracker(OBJECTS), 0.0
    settings_ = InputSettings(max_age=5.0, max_hypotheses=max_hypotheses, require_weights=require_weights)
    for (kind, name, payload, frame_id), wait in events:
        now += wait
        if kind == "poses":
            received = received_poses(
                pose_array(payload, frame_id), expected_frame=FRAME, workspace=WORKSPACE, received=now
            )
            check_received(received, len(payload))
            tracker.add_poses(name, received)
        else:
            tracker.add_weights(name, received_weights(Float64MultiArray(data=payload), received=now))
        tracker.snapshot(now, settings_)  # adopts what arrived, as a tick would
    snapshot = tracker.snapshot(now, settings_)
    for status in snapshot.objects:
        assert status.message and "\n" not in status.message
        # No hypotheses in use: an error, or a warning while nothing has come yet.
        assert (status.level == Level.OK) <= (status.hypotheses is not None)
        assert (status.hypotheses is None) == (
            status.level == Level.ERROR or status.message == "no hypotheses received yet"
        )
        if status.hypotheses is not None:
            weights = [h.weight for h in status.hypotheses.hypotheses]
            assert 1 <= len(weights) <= max_hypotheses
            assert all(math.isfinite(w) and w >= 0.0 for w in weights) and sum(weights) == pytest.approx(1.0)
            assert weights == sorted(weights, reverse=True)
            assert all(WORKSPACE.problem(h.pose.position) is None for h in status.hypotheses.hypotheses)
    report = TickReport(snapshot, None, 0.0, False, MapperSettings(SearchParams(), settings_))
    assert_bounded(diagnostics_msg(report, node_name="n", hardware_id="/n", stamp_ns=0))


def assert_bounded(diagnostics: DiagnosticArray) -> None:
    for status in diagnostics.status:
        assert len(status.message) <= MAX_DIAGNOSTIC_TEXT
        assert all(len(kv.value) <= MAX_DIAGNOSTIC_TEXT for kv in status.values)


# --- the mapper: valid only if both rules hold inside the workspace ---------------------------------

CUBE = 0.1
TABLE = Scene(
    objects=tuple(ObjectModel(name, Box((CUBE, CUBE, CUBE)), mass=0.3) for name in OBJECTS),
    static=(StaticBody("floor", Plane()),),
    search=SearchParams(settle_time=0.2),
    explicit_workspace=WORKSPACE,
)
MAPPER_SETTINGS = MapperSettings(TABLE.search, InputSettings(), rate_hz=0.5)
#: Positions a cube may rest at (on the floor, anywhere on the table) or not (anywhere at all).
resting = st.tuples(st.floats(-0.8, 0.8), st.floats(-0.8, 0.8), st.sampled_from((CUBE / 2, CUBE / 2 + 0.002)))
positions = st.one_of(resting, resting, good_positions, st.tuples(*[any_float] * 3))
hypothesis_poses = st.tuples(positions, st.one_of(st.just((0.0, 0.0, 0.0, 1.0)), unit_quaternions()))


@pytest.fixture(scope="module")
def mapper_and_judge() -> Any:
    """One mapper (its inputs replaced per example) and a second world that judges its results again."""
    mapper, judge = Mapper(TABLE), PhysicsChecker(TABLE)
    yield mapper, judge
    mapper.close()
    judge.close()


@settings(max_examples=max(10, settings().max_examples // 2))  # each example simulates up to 9 configurations
@given(st.lists(st.lists(hypothesis_poses, min_size=1, max_size=3), min_size=2, max_size=2), st.booleans())
def test_a_result_is_valid_only_if_both_rules_hold_inside_the_workspace(
    mapper_and_judge: Any, per_object: list[list[RawPose]], weighted: bool
) -> None:
    mapper, judge = mapper_and_judge
    mapper.inputs = InputTracker(TABLE.object_names)
    for name, poses in zip(OBJECTS, per_object, strict=True):
        received = received_poses(pose_array(poses), expected_frame=FRAME, workspace=TABLE.workspace, received=0.0)
        mapper.inputs.add_poses(name, received)
        if weighted:
            mapper.inputs.add_weights(name, received_weights(Float64MultiArray(data=[1.0] * len(poses)), received=0.0))
    report = mapper.tick(0.0, MAPPER_SETTINGS)
    assert_bounded(diagnostics_msg(report, node_name="n", hardware_id="/n", stamp_ns=0))
    result = report.result
    if result is None or not result.valid:
        return
    assert result.poses is not None and result.code is not None
    # Every object the map holds is in the workspace; an object with no usable pose is absent (not in the
    # world: its pose is its parking spot, which the judge's world holds absent too).
    assert all(TABLE.workspace.problem(result.poses[index].position) is None for index in report.present)
    assert all(report.hypotheses[i].is_absent(result.code[i]) for i, _ in enumerate(OBJECTS) if i not in report.present)
    assert judge.find_collision(result.poses, TABLE.search.penetration_threshold) is None
    assert judge.settle(result.poses, TABLE.search.settle_time, TABLE.search.angular_weight).is_stable(
        TABLE.search.jitter_threshold
    )
    for group in result.groups:  # each interaction group's part was visited, and valid
        assert [e.outcome for e in result.trace if e.group == group.id and e.code == group.code] == ["valid"]


# --- the loader: only SceneError, one line; what loads is usable -----------------------------------


def valid_problem() -> dict[str, Any]:
    return {
        "static": [{"name": "floor", "shape": "plane"}],
        "objects": [{"name": name, "shape": "box", "size": [CUBE] * 3} for name in OBJECTS],
        "hypotheses": {
            "cube_a": [{"position": [0.0, 0.0, 0.05], "weight": 0.7}, {"position": [0.0, 0.01, 0.05], "weight": 0.3}],
            "cube_b": [{"position": [0.5, 0.0, 0.05], "orientation": [0, 0, 0, 1]}],
        },
    }


yaml_scalars = st.one_of(st.none(), st.booleans(), st.integers(), any_float, st.text(max_size=20))
yaml_data = st.recursive(
    yaml_scalars,
    lambda children: (
        st.lists(children, max_size=4)
        | st.dictionaries(
            st.one_of(st.text(max_size=10), st.integers(), st.none(), st.booleans()), children, max_size=4
        )
    ),
    max_leaves=20,
)


def paths_of(data: Any, prefix: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    """Every key path into nested lists and mappings."""
    found = [prefix]
    if isinstance(data, dict):
        found += [p for key, value in data.items() for p in paths_of(value, (*prefix, key))]
    elif isinstance(data, list):
        found += [p for index, value in enumerate(data) for p in paths_of(value, (*prefix, index))]
    return found


def load(data: Any) -> None:
    """problem_from_dict: a Problem whose hypotheses are usable, or one SceneError line naming the source."""
    try:
        problem = problem_from_dict(data, "fuzzed.yaml")
    except SceneError as error:
        assert str(error).startswith("fuzzed.yaml: ") and "\n" not in str(error)
        return
    for ranked in problem.hypotheses:
        assert sum(h.weight for h in ranked.hypotheses) == pytest.approx(1.0)
        assert all(problem.scene.workspace.problem(h.pose.position) is None for h in ranked.hypotheses)


@given(st.data())
def test_a_problem_with_any_part_replaced_by_anything_loads_or_gives_one_error_line(data: st.DataObject) -> None:
    document = valid_problem()
    path = data.draw(st.sampled_from(paths_of(document)[1:]))
    *parents, last = path
    target: Any = document
    for part in parents:
        target = target[part]
    target[last] = copy.deepcopy(data.draw(yaml_data))
    load(document)
    load(parse_yaml(yaml.safe_dump(document), "fuzzed.yaml"))  # the same through YAML text


@given(yaml_data)
def test_any_yaml_document_loads_or_gives_one_error_line(document: Any) -> None:
    load(document)


@pytest.fixture(scope="module")
def scratch(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("fuzz") / "problem.yaml"


@given(st.one_of(st.binary(max_size=300), yaml_data.map(lambda d: yaml.safe_dump(d).encode())))
def test_any_file_content_loads_or_gives_one_error_line(scratch: Path, content: bytes) -> None:
    scratch.write_bytes(content)
    try:
        load_problem(scratch)
    except SceneError as error:
        assert str(error).startswith(f"{scratch}: ") and "\n" not in str(error)


SPELLINGS: dict[str, Callable[[float], str]] = {
    "repr": repr,
    "e": lambda x: f"{x:e}",
    "E+": lambda x: f"{x:+E}",
    "g": lambda x: f"{x:.12g}",
    "no leading zero": lambda x: f"{x:.6f}".replace("0.", ".", 1),
}


@given(st.floats(-0.9, 0.9), st.sampled_from(sorted(SPELLINGS)))
def test_a_number_reads_as_the_float_it_spells_however_it_is_written(value: float, spelling: str) -> None:
    text = SPELLINGS[spelling](value)
    document = parse_yaml(f"position: [{text}, 0, 0.05]", "fuzzed.yaml")
    assert document["position"][0] == float(text)
