"""The node over real DDS: a child process fed by an in-test rclpy node.

Two node processes are shared by the tests of this module, for speed: ``pyramid`` (the shipped
pyramid scene) and ``busy`` (a problem far too large to finish). Each test feeds the shared node
what it needs itself (``fed_pyramid``, ``busy``), so that any test passes alone and in any order;
a test that needs a node that never had input starts its own (``fresh_pyramid``).
"""

from __future__ import annotations

import json
import math
import signal
import subprocess
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import pytest
import yaml
from conftest import PROBLEMS, REPO, SCENES
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseArray, PoseStamped
from rclpy.qos import ReliabilityPolicy
from ros_helpers import (
    PHYSICS_MAPPER,
    REQUIRED_DIAGNOSTIC_KEYS,
    NodeProcess,
    RosClient,
    object_status,
    run_cli,
    search_status,
    stamp_ns_of,
    values,
)
from std_msgs.msg import Float64MultiArray
from visualization_msgs.msg import Marker

from physics_mapper.mapping.topics import object_pose_topic, object_settled_pose_topic
from physics_mapper.model.geometry import Pose
from physics_mapper.model.scene import Problem
from physics_mapper.model.scene_files import load_problem, load_scene
from physics_mapper.msg_adapters.hypotheses import hypotheses_msgs, pose_array_msg
from physics_mapper.msg_adapters.results import SHAPE_NAMESPACE
from physics_mapper.scenarios.problems import floating_problem

PYRAMID_SCENE = SCENES / "pyramid.yaml"
PYRAMID_PROBLEM = PROBLEMS / "pyramid.yaml"
OBJECTS = ("cube_left", "cube_right", "cube_top")
PUBLISH = (str(PHYSICS_MAPPER), "publish")
#: The shared nodes report faster than the ~1 Hz default, so that tests waiting for diagnostics are quick.
FAST_DIAGNOSTICS = 0.1


@dataclass
class Running:
    node: NodeProcess
    client: RosClient


@contextmanager
def pyramid_node(log: Path, namespace: str) -> Iterator[Running]:
    """A node on the pyramid scene in ``namespace`` and a client, once the node publishes diagnostics."""
    parameters = {"rate_hz": 4.0, "deadline": 0.2, "max_age": 60.0, "diagnostics_period": FAST_DIAGNOSTICS}
    node = NodeProcess(PYRAMID_SCENE, parameters, log, namespace)
    client = RosClient(namespace)
    try:
        client.next_diagnostics(lambda d: True, timeout=30.0, what="the node's first diagnostics")
        yield Running(node, client)
    finally:
        client.close()
        node.stop()


@pytest.fixture(scope="module")
def pyramid(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Running]:
    """The shared pyramid node, in whatever state earlier tests left it."""
    with pyramid_node(tmp_path_factory.mktemp("pyramid") / "node.log", "/pyramid") as running:
        yield running


@pytest.fixture
def fresh_pyramid(tmp_path: Path) -> Iterator[Running]:
    """A pyramid node of this test alone, which has received nothing yet."""
    with pyramid_node(tmp_path / "node.log", "/fresh") as running:
        yield running


def publish_problem(client: RosClient, problem: Problem, stamp_ns: int, only: tuple[str, ...] = OBJECTS) -> None:
    for name, hypotheses in zip(problem.scene.object_names, problem.hypotheses, strict=True):
        if name in only:
            client.publish(name, *hypotheses_msgs(hypotheses, frame_id=problem.scene.frame_id, stamp_ns=stamp_ns))


def publish_until_configured(client: RosClient, problem: Problem, stamp_ns: int) -> PoseArray:
    """Publish ``problem`` stamped ``stamp_ns`` until a configuration computed from it arrives.

    Every object's PoseArray is replaced, so the configuration carries exactly ``stamp_ns``.
    """
    objects = len(problem.scene.objects)
    client.keep_publishing(
        lambda: publish_problem(client, problem, stamp_ns),
        lambda: client.map_of(stamp_ns, objects) is not None,
        f"a configuration stamped {stamp_ns} ns",
    )
    configuration = client.map_of(stamp_ns, objects)
    assert configuration is not None
    return configuration


@pytest.fixture
def fed_pyramid(pyramid: Running) -> Running:
    """The shared pyramid node with the pyramid problem in use for every object and a map computed from it."""
    publish_until_configured(pyramid.client, load_problem(PYRAMID_PROBLEM), stamp_ns=time.time_ns())
    return pyramid


def publish_until_diagnosed(
    client: RosClient, publish: Callable[[], None], predicate: Callable[[DiagnosticArray], bool], what: str
) -> DiagnosticArray:
    """Publish until a DiagnosticArray arriving from now on satisfies ``predicate``; return it."""
    start = len(client.diagnostics)

    def found() -> DiagnosticArray | None:
        return next((d for d in client.diagnostics[start:] if predicate(d)), None)

    client.keep_publishing(publish, lambda: found() is not None, what)
    result = found()
    assert result is not None
    return result


def level_of(msg: DiagnosticArray, name: str) -> bytes:
    level: bytes = object_status(msg, name).level
    return level


# --- feeding, results, diagnostics, markers (pyramid node) ---------------------------------


def test_nothing_is_published_until_some_object_has_hypotheses_and_a_missing_one_stops_no_map(
    fresh_pyramid: Running,
) -> None:
    client = fresh_pyramid.client
    diagnostics = client.next_diagnostics(lambda d: True)
    search = search_status(diagnostics)
    assert search is not None
    assert search.message == "waiting for hypotheses of: cube_left, cube_right, cube_top"
    assert search.level == DiagnosticStatus.WARN  # waiting is not a failure
    assert object_status(diagnostics, "cube_top").message == "no hypotheses received yet"
    assert client.configurations == []
    problem = load_problem(PYRAMID_PROBLEM)
    mapped = publish_until_diagnosed(
        client,
        lambda: publish_problem(client, problem, stamp_ns=100 * 10**9, only=("cube_left", "cube_right")),  # no cube_top
        lambda d: values(search_status(d) or DiagnosticStatus()).get("absent") == "cube_top",
        "a map of cube_left and cube_right",
    )
    search = search_status(mapped)
    assert search is not None and search.message.startswith("valid ") and search.message.endswith("left out: cube_top")
    assert object_status(mapped, "cube_top").level == DiagnosticStatus.WARN
    # The tick that left cube_top out held both others (an earlier one may have held one only)
    client.wait_for(lambda: client.map_of(100 * 10**9, 2) is not None, what="the map of cube_left and cube_right")
    assert all(len(c.poses) <= 2 for c in client.configurations if stamp_ns_of(c) == 100 * 10**9)


def test_a_realistic_input_stamp_comes_back_exactly_on_the_outputs(pyramid: Running) -> None:
    """The outputs' stamp is the newest input stamp used, to the nanosecond."""
    client = pyramid.client
    stamp_ns = 1_732_233_600_123_456_789
    configuration = publish_until_configured(client, load_problem(PYRAMID_PROBLEM), stamp_ns)
    assert (configuration.header.stamp.sec, configuration.header.stamp.nanosec) == (1_732_233_600, 123_456_789)
    client.wait_for(lambda: any(stamp_ns_of(s) == stamp_ns for s in client.settled), what="settled, same stamp")
    client.wait_for(
        lambda: any(m.markers and all(stamp_ns_of(k) == stamp_ns for k in m.markers) for m in client.markers),
        what="markers, same stamp",
    )


def test_configuration_equals_what_solve_finds(pyramid: Running) -> None:
    client = pyramid.client
    started_ns = time.time_ns()  # the publisher stamps its messages with its clock, after this
    publisher = subprocess.Popen(
        [*PUBLISH, str(PYRAMID_PROBLEM), "--count", "3", "--rate", "4", "--namespace", "/pyramid"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        client.wait_for(
            lambda: any(stamp_ns_of(c) >= started_ns for c in client.configurations),
            what="a configuration from the publisher's hypotheses",
        )
        done = client.next_diagnostics(
            lambda d: "exhausted" in values(search_status(d) or DiagnosticStatus()).get("search", ""),
            what="an exhausted search",
        )
    finally:
        out, err = publisher.communicate(timeout=30)
    assert publisher.returncode == 0, err
    assert "published 3 rounds" in out
    solved = json.loads(run_cli("solve", str(PYRAMID_PROBLEM), "--json").stdout)
    search = search_status(done)
    assert search is not None
    assert values(search)["best code"] == "C" + "".join(map(str, solved["code"]))
    configuration, settled = client.configurations[-1], client.settled[-1]
    assert configuration.header.frame_id == settled.header.frame_id == "world"
    # The chosen poses are hypotheses, exactly. The settled ones agree to micrometres: the node's world
    # has held objects absent (massless) while their inputs came in one by one, and Bullet solves the
    # contacts of a body whose mass changed in another order (physics/world.py).
    for msg, key, tolerance in ((configuration, "poses", 1e-9), (settled, "settled_poses", 1e-4)):
        assert len(msg.poses) == len(OBJECTS)
        for name, pose in zip(OBJECTS, msg.poses, strict=True):
            expected = solved[key][name]
            got_position = [pose.position.x, pose.position.y, pose.position.z]
            got_orientation = [pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w]
            assert got_position == pytest.approx(expected["position"], abs=tolerance)
            assert got_orientation == pytest.approx(expected["orientation"], abs=tolerance * 10)


def test_diagnostics_hold_the_spec_keys(fed_pyramid: Running) -> None:
    diagnostics = fed_pyramid.client.next_diagnostics(lambda d: True)
    search = search_status(diagnostics)
    assert search is not None
    found = values(search)
    assert set(REQUIRED_DIAGNOSTIC_KEYS) <= set(found)
    assert {f"input {name}" for name in OBJECTS} <= set(found)
    assert int(found["nodes visited"]) > 0
    assert found["deadline [s]"] == "0.2"
    # How the ticks kept time since the previous diagnostics (they come at diagnostics_period).
    tick_keys = {"ticks", "ticks since the last diagnostics", "search overruns", "late ticks"}
    assert tick_keys | {"max search time [s]", "max tick time [s]"} <= set(found)
    assert int(found["ticks"]) >= int(found["ticks since the last diagnostics"])
    top = values(object_status(diagnostics, "cube_top"))
    assert int(top["stamp [ns]"]) > 0 and top["poses lost"] == "0"
    assert [object_status(diagnostics, n).name for n in OBJECTS] == [f"physics_mapper: hypotheses/{n}" for n in OBJECTS]


def test_markers_show_one_shape_per_object(fed_pyramid: Running) -> None:
    client = fed_pyramid.client
    client.wait_for(lambda: bool(client.markers), what="markers")
    markers = client.markers[-1].markers
    shapes = [m for m in markers if m.ns == SHAPE_NAMESPACE]
    assert len(shapes) == len(OBJECTS)
    assert all(m.type == Marker.CUBE and (m.scale.x, m.scale.y, m.scale.z) == (0.2, 0.2, 0.2) for m in shapes)
    texts = [m.text for m in markers if m.type == Marker.TEXT_VIEW_FACING]
    assert [t.split("\n")[0] for t in texts] == list(OBJECTS)
    assert all(t.split("\n")[1].startswith("J=") for t in texts)


# --- bad input (pyramid node) ---------------------------------------------------------------

NAN, INF = math.nan, math.inf


def raw_pose_array(*poses: tuple[tuple[float, ...], tuple[float, ...]], frame: str = "world") -> PoseArray:
    msg = pose_array_msg([Pose((0.0, 0.0, 0.0))] * len(poses), frame_id=frame, stamp_ns=50 * 10**9)
    for pose, (position, orientation) in zip(msg.poses, poses, strict=True):
        pose.position.x, pose.position.y, pose.position.z = position
        pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w = orientation
    return msg


TOP = ((0.0, 0.0, 0.301), (0.0, 0.0, 0.0, 1.0))
OVERSIZED = 150


@dataclass(frozen=True)
class BadInput:
    poses: PoseArray
    weights: list[float] | None
    diagnostic: str


BAD_INPUTS = {
    "nan_position": BadInput(raw_pose_array(((NAN, 0.0, 0.3), TOP[1])), [1.0], "poses[0]: non-finite value"),
    "inf_orientation": BadInput(raw_pose_array((TOP[0], (0.0, 0.0, INF, 1.0))), [1.0], "poses[0]: non-finite value"),
    "zero_quaternion": BadInput(raw_pose_array((TOP[0], (0.0, 0.0, 0.0, 0.0))), [1.0], "poses[0]: zero quaternion"),
    "non_unit_quaternion": BadInput(
        raw_pose_array((TOP[0], (0.0, 0.0, 0.0, 2.0))), [1.0], "quaternion norm 2 is not 1"
    ),
    "one_bad_pose_of_two": BadInput(
        raw_pose_array(TOP, ((0.0, 0.0, 0.3), (0.0, 0.0, 0.0, 0.0))), [0.5, 0.5], "dropped 1 of 2 poses"
    ),
    "wrong_frame": BadInput(
        raw_pose_array(TOP, frame="camera"), [1.0], "PoseArray refused: no transform from 'camera' to 'world'"
    ),
    "outside_workspace": BadInput(
        raw_pose_array(((0.0, 0.0, 1e15), TOP[1])), [1.0], "poses[0]: (0, 0, 1e+15) m is outside the workspace"
    ),
    "empty_array": BadInput(raw_pose_array(), [], "PoseArray refused: empty PoseArray"),
    "negative_weights": BadInput(raw_pose_array(TOP, TOP), [-1.0, 2.0], "negative weight"),
    "all_zero_weights": BadInput(raw_pose_array(TOP, TOP), [0.0, 0.0], "weights sum to zero"),
    "nan_weights": BadInput(raw_pose_array(TOP, TOP), [NAN, 1.0], "non-finite weight"),
    "wrong_length_weights": BadInput(raw_pose_array(TOP, TOP), [0.2, 0.3, 0.5], "no weights message of length 2"),
    "oversized_array": BadInput(
        raw_pose_array(*[((0.0, 0.0, 0.301 + 0.0001 * i), TOP[1]) for i in range(OVERSIZED)]),
        [1.0 + i for i in range(OVERSIZED)],
        f"kept the 100 heaviest of {OVERSIZED} hypotheses",
    ),
}


@pytest.mark.parametrize("case", list(BAD_INPUTS))
def test_bad_input_gets_a_diagnostic_and_the_next_good_message_recovers(fed_pyramid: Running, case: str) -> None:
    client, bad = fed_pyramid.client, BAD_INPUTS[case]
    problem = load_problem(PYRAMID_PROBLEM)
    weights = None if bad.weights is None else Float64MultiArray(data=bad.weights)
    seen = publish_until_diagnosed(
        client,
        lambda: client.publish("cube_top", bad.poses, weights),
        lambda d: bad.diagnostic in object_status(d, "cube_top").message,
        f"the diagnostic {bad.diagnostic!r}",
    )
    assert level_of(seen, "cube_top") in (DiagnosticStatus.WARN, DiagnosticStatus.ERROR)
    assert level_of(seen, "cube_left") == DiagnosticStatus.OK  # the other objects keep working
    assert fed_pyramid.node.alive
    configuration = publish_until_configured(client, problem, stamp_ns=time.time_ns())
    assert len(configuration.poses) == len(OBJECTS)
    recovered = client.next_diagnostics(lambda d: level_of(d, "cube_top") == DiagnosticStatus.OK)
    assert bad.diagnostic not in object_status(recovered, "cube_top").message


def test_stale_hypotheses_leave_the_map_until_fresh_ones_arrive(fed_pyramid: Running) -> None:
    client = fed_pyramid.client
    assert client.set_parameter("max_age", 1.0) == (True, "")
    try:
        stale = client.next_diagnostics(
            lambda d: (
                object_status(d, "cube_top").message.startswith("stale:")
                and values(search_status(d) or DiagnosticStatus()).get("absent") == "cube_left, cube_right, cube_top"
            )
        )
        search = search_status(stale)
        assert search is not None and search.message.startswith("valid ")  # silent, and nothing needs them: dropped
        publish_until_configured(client, load_problem(PYRAMID_PROBLEM), stamp_ns=time.time_ns())
    finally:
        assert client.set_parameter("max_age", 60.0) == (True, "")
    assert fed_pyramid.node.alive


def test_each_object_s_poses_are_latched_with_the_map_s_stamp_and_frame(fed_pyramid: Running) -> None:
    """A grasp planner subscribes to the one object it needs, late, and gets the same as the map."""
    client = fed_pyramid.client
    late = {
        name: (
            client.latched(PoseStamped, object_pose_topic(name)),
            client.latched(PoseStamped, object_settled_pose_topic(name)),
        )
        for name in OBJECTS
    }
    client.wait_for(lambda: all(chosen and settled for chosen, settled in late.values()), what="per-object poses")
    configuration, settled_array = client.configurations[-1], client.settled[-1]
    for index, name in enumerate(OBJECTS):
        chosen, settled = late[name][0][-1], late[name][1][-1]
        assert chosen.header == settled.header == configuration.header == settled_array.header
        assert chosen.pose == configuration.poses[index]
        assert settled.pose == settled_array.poses[index]


def tick_count(diagnostics: DiagnosticArray) -> int:
    search = search_status(diagnostics)
    assert search is not None
    return int(values(search)["ticks"])


def test_diagnostics_keep_their_own_period_and_a_new_rate_applies_at_once(fed_pyramid: Running) -> None:
    """At 0.01 Hz no tick comes for 100 s, yet diagnostics do; back at 4 Hz, ticks resume at once, not 100 s on."""
    client = fed_pyramid.client
    assert client.set_parameter("rate_hz", 0.01) == (True, "")
    try:
        first = client.next_diagnostics(lambda d: True)
        idle = client.next_diagnostics(lambda d: True)
        assert tick_count(idle) == tick_count(first)  # diagnostics without ticks
        assert values(search_status(idle) or DiagnosticStatus())["ticks since the last diagnostics"] == "0"
        assert client.set_parameter("rate_hz", 4.0) == (True, "")
        client.next_diagnostics(lambda d: tick_count(d) > tick_count(idle), what="a tick at the new rate")
        # The map keeps rate_hz while diagnostics are rare.
        assert client.set_parameter("diagnostics_period", 3600.0) == (True, "")
        published = len(client.configurations)
        client.wait_for(lambda: len(client.configurations) >= published + 3, what="maps between diagnostics")
        assert client.set_parameter("diagnostics_period", FAST_DIAGNOSTICS) == (True, "")
        client.next_diagnostics(lambda d: True, what="diagnostics at once after a period change")
    finally:
        client.set_parameters({"rate_hz": 4.0, "diagnostics_period": FAST_DIAGNOSTICS})


def test_rate_and_deadline_are_judged_one_by_one_or_together(pyramid: Running) -> None:
    """SetParameters (``ros2 param load``) sets a request's parameters one at a time, in its order, each
    judged on its own (rclpy); SetParametersAtomically judges the combination."""
    client = pyramid.client
    try:
        # Faster and shorter, rate first: 0.2 s >= 1/10 Hz is refused, then the deadline applies.
        rate_result, deadline_result = client.set_parameters({"rate_hz": 10.0, "deadline": 0.05})
        assert not rate_result[0] and "shorter than the tick period" in rate_result[1]
        assert deadline_result == (True, "")
        assert client.get_parameters("rate_hz", "deadline") == [4.0, 0.05]
        # The same, deadline first (already 0.05 s), succeeds.
        assert client.set_parameters({"deadline": 0.05, "rate_hz": 10.0}) == [(True, ""), (True, "")]
        assert client.set_parameters({"rate_hz": 4.0, "deadline": 0.2}) == [(True, ""), (True, "")]
        # Together, in any order, atomically.
        assert client.set_parameters_atomically({"rate_hz": 10.0, "deadline": 0.05}) == (True, "")
        assert client.set_parameters_atomically({"deadline": 0.2, "rate_hz": 4.0}) == (True, "")
        # A combination that is invalid as a whole is refused as a whole.
        successful, reason = client.set_parameters_atomically({"rate_hz": 10.0, "deadline": 0.15})
        assert not successful and reason == "deadline 0.15 s must be shorter than the tick period 1/rate_hz = 0.1 s"
        assert client.get_parameters("rate_hz", "deadline") == [4.0, 0.2]
    finally:
        client.set_parameters({"deadline": 0.2, "rate_hz": 4.0})


# --- deadline, parameters, shutdown (busy node) ---------------------------------------------

BUSY_HYPOTHESES = 60  # per object: 60^3 configurations, each simulated: never finished in a test


def busy_problem() -> Problem:
    """Every hypothesis floats (no collision, always unstable), so every node is simulated."""
    return floating_problem(load_scene(PYRAMID_SCENE), BUSY_HYPOTHESES)


def start_searching(client: RosClient) -> None:
    """Feed the busy problem until the node has searched on it with every object's hypotheses (a search on
    the first object's alone ends at once, and a PoseArray sent before the node's reader matched is lost)."""
    problem = busy_problem()

    def searching_all(msg: DiagnosticArray) -> bool:
        inputs = all(level_of(msg, name) == DiagnosticStatus.OK for name in problem.scene.object_names)
        return inputs and values(search_status(msg) or DiagnosticStatus())["nodes visited"] != "0"

    publish_until_diagnosed(
        client, lambda: publish_problem(client, problem, stamp_ns=10**9), searching_all, "a search on the busy problem"
    )


BUSY_RATE_HZ = 4.0
BUSY_DEADLINE = 0.1


@pytest.fixture(scope="module")
def busy(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Running]:
    log = tmp_path_factory.mktemp("busy") / "node.log"
    parameters = {
        "rate_hz": BUSY_RATE_HZ,
        "deadline": BUSY_DEADLINE,
        "probability_threshold": 0.0,
        "max_age": 600.0,
        "diagnostics_period": 1.0 / BUSY_RATE_HZ,
    }
    node = NodeProcess(PYRAMID_SCENE, parameters, log, "/busy")
    client = RosClient("/busy")
    try:
        client.next_diagnostics(lambda d: True, timeout=30.0, what="the node's first diagnostics")
        start_searching(client)
        yield Running(node, client)
    finally:
        client.close()
        node.stop()


def search_ticks(client: RosClient, count: int) -> list[dict[str, str]]:
    """The search key-values of the next ``count`` ticks."""
    start = len(client.diagnostics)
    client.wait_for(lambda: len(client.diagnostics) >= start + count, timeout=60.0, what=f"{count} ticks")
    ticks = []
    for msg in client.diagnostics[start : start + count]:
        search = search_status(msg)
        assert search is not None
        ticks.append(values(search))
    return ticks


def test_every_tick_stops_at_its_deadline_and_the_next_resumes(busy: Running) -> None:
    """What the search decided, not how long it took (the overrun figures: BENCHMARKS.md, "Deadline slack")."""
    ticks = search_ticks(busy.client, 8)
    assert all("stopped at the deadline" in t["search"] for t in ticks)  # the problem is too large to finish
    assert sum(t["search"].startswith("resumed") for t in ticks) == len(ticks)  # unchanged inputs: resumed
    assert all(t["deadline [s]"] == str(BUSY_DEADLINE) for t in ticks)
    assert int(ticks[-1]["nodes visited"]) > int(ticks[0]["nodes visited"])


def test_deadline_changed_at_run_time_takes_effect_and_invalid_values_are_refused(busy: Running) -> None:
    client = busy.client
    assert client.set_parameter("deadline", 0.04) == (True, "")
    changed = client.next_diagnostics(
        lambda d: values(search_status(d) or DiagnosticStatus())["deadline [s]"] == "0.04"
    )
    search = search_status(changed)
    # The deadline changes neither which nodes are visited nor their outcomes: the search goes on.
    assert search is not None and values(search)["search"].startswith("resumed")
    assert all("stopped at the deadline" in t["search"] for t in search_ticks(client, 3))

    successful, reason = client.set_parameter("deadline", 0.3)  # the tick period is 0.25 s
    assert not successful
    assert reason == "deadline 0.3 s must be shorter than the tick period 1/rate_hz = 0.25 s"
    successful, reason = client.set_parameter("rate_hz", 40.0)  # period 0.025 s < deadline 0.04 s
    assert not successful and "shorter than the tick period" in reason
    successful, reason = client.set_parameter("deadline", -1.0)
    assert not successful and reason  # outside the declared range
    successful, reason = client.set_parameter("fallback", "sometimes")
    assert not successful and reason == "fallback must be one of none, settled, refine, got 'sometimes'"
    successful, reason = client.set_parameter("scene_file", "other.yaml")
    assert not successful and "read-only" in reason
    ticks = search_ticks(client, 2)
    assert [t["deadline [s]"] for t in ticks] == ["0.04", "0.04"]
    assert busy.node.alive


# --- start-up: parameters files and bad start-up input ------------------------------------------


def test_params_file_configures_the_node_and_unknown_keys_are_named(tmp_path: Path) -> None:
    """The shipped parameters file, plus two misspelt keys (and one -p) that a user would want to hear about."""
    shipped = yaml.safe_load((REPO / "config" / "params" / "node.yaml").read_text())
    expected = shipped["/**"]["ros__parameters"]
    shipped["/**"]["ros__parameters"] = {**expected, "deadlne": 0.1, "rate": 5.0}
    params_file = tmp_path / "params.yaml"
    params_file.write_text(yaml.safe_dump(shipped))
    log = (tmp_path / "node.log").open("w")
    command = [str(PHYSICS_MAPPER), "node", "--ros-args", "--params-file", str(params_file)]
    command += ["-r", "__ns:=/params", "-p", "settle_tme:=1.0", "-p", "input_reliability:=reliable"]
    process = subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT, text=True, cwd=tmp_path)
    client = RosClient("/params")
    try:
        diagnostics = client.next_diagnostics(lambda d: True, timeout=30.0)
        subscriptions = client.node.get_subscriptions_info_by_topic("/params/hypotheses/cube_top")
    finally:
        client.close()
        process.send_signal(signal.SIGINT)
        code = process.wait(timeout=10)
        log.close()
    search = search_status(diagnostics)
    assert search is not None
    assert float(values(search)["deadline [s]"]) == expected["deadline"]
    assert [object_status(diagnostics, n).name.split("/")[-1] for n in OBJECTS] == list(OBJECTS)
    output = (tmp_path / "node.log").read_text()
    assert code == 0, output
    assert "unknown parameters ignored (from --params-file or -p): deadlne, rate, settle_tme;" in output
    # input_reliability: reliable (no loss from a reliable publisher); the test client publishes reliably.
    assert [s.qos_profile.reliability for s in subscriptions] == [ReliabilityPolicy.RELIABLE]


@pytest.mark.parametrize(
    ("ros_args", "error"),
    [
        ([], "parameter scene_file is required"),
        (["-p", "scene_file:=no/such/scene.yaml"], "no/such/scene.yaml: cannot read file"),
        (["-p", f"scene_file:={PYRAMID_SCENE}", "-p", "deadline:=0.6"], "deadline 0.6 s must be shorter than"),
        (["-p", f"scene_file:={PYRAMID_SCENE}", "-p", "deadline:=-1.0"], "deadline"),
        (["-p", f"scene_file:={PYRAMID_SCENE}", "-p", "rate_hz:=fast"], "rate_hz"),
        (
            ["-p", f"scene_file:={PYRAMID_SCENE}", "-p", "input_reliability:=sometimes"],
            "input_reliability must be one of best_effort, reliable, got 'sometimes'",
        ),
        (["-p", "scene_file:=package://no_such_package/x.yaml"], "package 'no_such_package' is not in the ament index"),
        (["-p", "scene_file"], "Couldn't parse parameter override rule: '-p scene_file'"),
        (["--params-file", "no/such/params.yaml"], "Couldn't parse params file: '--params-file no/such/params.yaml'"),
    ],
)
def test_bad_start_up_input_is_one_error_line_and_exit_2(ros_args: list[str], error: str) -> None:
    completed = run_cli("node", "--ros-args", *ros_args, timeout=60)
    assert completed.returncode == 2, completed.stderr
    # rcl itself logs "[ERROR] ... [rcl]: Failed to parse global arguments" before our line.
    noise = ("pybullet build time", "[ERROR]")
    lines = [line for line in completed.stderr.splitlines() if not line.startswith(noise)]
    assert len(lines) == 1, completed.stderr
    assert lines[0].startswith("physics_mapper node: error: ")
    assert "Traceback" not in completed.stderr
    assert error in lines[0]
