"""The node over real DDSagainst reliability faults: engine faults, oversized input text, number spellings.

One node process, started from a parameters file that spells its numbers as people write them,
serves the size and spelling tests; the engine-fault test runs the node in this process (its
own context and executor, still talking over DDS) so that the test can break its pybullet world
between two of its ticks.
"""

from __future__ import annotations

import signal
import subprocess
from collections.abc import Iterator
from dataclasses import dataclass

import pytest
from conftest import PROBLEMS, SCENES
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.parameter import Parameter
from ros_helpers import PHYSICS_MAPPER, RosClient, object_status, search_status, values

from physics_mapper.model.bullet import pybullet
from physics_mapper.model.geometry import Pose
from physics_mapper.model.hypotheses import Hypothesis, RankedHypotheses
from physics_mapper.model.limits import MAX_QUOTED_TEXT
from physics_mapper.model.scene import Problem
from physics_mapper.model.scene_files import load_problem
from physics_mapper.msg_adapters.hypotheses import hypotheses_msgs, pose_array_msg
from physics_mapper.ros.node import PhysicsMapperNode

PYRAMID_SCENE = SCENES / "pyramid.yaml"
PYRAMID = load_problem(PROBLEMS / "pyramid.yaml")

#: Parameters as people write them: YAML 1.2 floats that YAML 1.1 would read as strings. rcl
#: parses a parameters file itself (C's strtod), so the node gets doubles.
SPELLED_PARAMETERS = {"deadline": ("3e-1", 0.3), "probability_threshold": ("1E-4", 1e-4), "settle_time": (".5", 0.5)}


@dataclass
class Spelled:
    process: subprocess.Popen[str]
    client: RosClient


@pytest.fixture(scope="module")
def spelled(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Spelled]:
    """A node started with ``--params-file`` holding :data:`SPELLED_PARAMETERS`, and a client."""
    folder = tmp_path_factory.mktemp("spelled")
    lines = [f"    {name}: {text}" for name, (text, _) in SPELLED_PARAMETERS.items()]
    params = folder / "params.yaml"
    params.write_text(
        "/**/physics_mapper:\n  ros__parameters:\n"
        f"    scene_file: {PYRAMID_SCENE}\n    rate_hz: 2.0\n" + "\n".join(lines) + "\n",
        encoding="utf-8",
    )
    log = (folder / "node.log").open("w")
    command = [str(PHYSICS_MAPPER), "node", "--ros-args", "--params-file", str(params), "-r", "__ns:=/spelled"]
    process = subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT, text=True)
    client = RosClient("/spelled")
    try:
        client.next_diagnostics(lambda d: True, timeout=30.0, what="the node's first diagnostics")
        yield Spelled(process, client)
    finally:
        client.close()
        process.send_signal(signal.SIGINT)
        process.wait(timeout=10)
        log.close()


def test_a_parameters_file_may_spell_floats_as_people_write_them(spelled: Spelled) -> None:
    client = spelled.client
    client.wait_for(lambda: client.parameters.wait_for_services(timeout_sec=0.1), what="parameter services")
    answer = client.answered(lambda: client.parameters.get_parameters(list(SPELLED_PARAMETERS)), "get_parameters")
    got = [value.double_value for value in answer.values]
    assert got == [number for _, number in SPELLED_PARAMETERS.values()]


def text_size(msg: DiagnosticArray) -> int:
    """Characters of every string in a DiagnosticArray."""
    strings = [text for s in msg.status for text in (s.name, s.message, s.hardware_id)]
    strings += [text for s in msg.status for kv in s.values for text in (kv.key, kv.value)]
    return sum(map(len, strings))


def test_a_200000_character_frame_id_is_quoted_clipped_in_the_diagnostics(spelled: Spelled) -> None:
    """Such a frame_id was copied into every /diagnostics message (858 -> 601,092 characters)."""
    client = spelled.client
    frame = "f" * 200_000
    huge = pose_array_msg([Pose((0.0, 0.0, 0.3))], frame_id=frame, stamp_ns=10**9)
    start = len(client.diagnostics)
    client.keep_publishing(
        lambda: client.publish("cube_top", huge),
        lambda: any("(200000 characters)" in object_status(d, "cube_top").message for d in client.diagnostics[start:]),
        "the refusal of the huge frame_id",
    )
    client.wait_for(lambda: len(client.diagnostics) >= start + 2, what="two more ticks")  # it stays in the last refusal
    refused = [d for d in client.diagnostics[start:] if "(200000 characters)" in object_status(d, "cube_top").message]
    assert refused
    assert max(text_size(d) for d in client.diagnostics[start:]) < 5_000
    message = object_status(refused[-1], "cube_top").message
    assert f"no transform from '{frame[: MAX_QUOTED_TEXT - 23]}... (200000 characters)' to 'world'" in message


# --- engine faults: the node in this process ------------------------------------------------------


@pytest.fixture
def in_process_node() -> Iterator[tuple[PhysicsMapperNode, RosClient]]:
    """The node, in this process and on the client's context and executor, so ticks run between the test's steps."""
    client = RosClient("/engine")
    given = {"scene_file": str(PYRAMID_SCENE), "rate_hz": 4.0, "deadline": 0.2, "max_age": 60.0}
    overrides = [Parameter(name, value=value) for name, value in given.items()]  # type: ignore[no-untyped-call]
    node = PhysicsMapperNode(context=client.context, namespace="/engine", parameter_overrides=overrides)
    client.executor.add_node(node)
    try:
        yield node, client
    finally:
        client.executor.remove_node(node)
        node.destroy_node()
        client.close()


def reweighted(problem: Problem, factor: float) -> Problem:
    """The same poses with the last hypothesis of every object a little heavier: a new search, the same ranking."""
    hypotheses = tuple(
        RankedHypotheses.from_weighted(
            [
                Hypothesis(h.pose, h.weight * (factor if rank == len(ranked) else 1.0))
                for rank, h in enumerate(ranked.hypotheses, 1)
            ]
        )
        for ranked in problem.hypotheses
    )
    return Problem(problem.scene, hypotheses)


def publish_until_configured(client: RosClient, problem: Problem, stamp_ns: int) -> None:
    def publish() -> None:
        for name, ranked in zip(problem.scene.object_names, problem.hypotheses, strict=True):
            client.publish(name, *hypotheses_msgs(ranked, frame_id="world", stamp_ns=stamp_ns))

    objects = len(problem.scene.objects)
    client.keep_publishing(publish, lambda: client.map_of(stamp_ns, objects) is not None, f"a map stamped {stamp_ns}")


def test_the_node_rebuilds_a_failed_world_reports_the_tick_as_an_error_and_maps_on(
    in_process_node: tuple[PhysicsMapperNode, RosClient],
) -> None:
    node, client = in_process_node
    publish_until_configured(client, PYRAMID, stamp_ns=1_000_000_000)
    before = client.configurations[-1]
    start = len(client.diagnostics)
    pybullet.disconnect(physicsClientId=node.mapper.checker.client_id)  # between two ticks: this thread runs them
    publish_until_configured(client, reweighted(PYRAMID, 1.01), stamp_ns=2_000_000_000)
    after = client.configurations[-1]
    client.next_diagnostics(lambda d: (search_status(d) or DiagnosticStatus()).level == DiagnosticStatus.OK)
    searches = [search_status(d) or DiagnosticStatus() for d in client.diagnostics[start:]]
    faults = [
        s for s in searches if s.level == DiagnosticStatus.ERROR and s.message.startswith("physics engine failed")
    ]
    assert len(faults) == 1, [s.message for s in searches]  # one tick: the next one searched in a rebuilt world
    assert faults[0].message.startswith("physics engine failed: Not connected to physics server.;")
    assert values(faults[0])["search"] == "physics engine failed"
    assert [p.position for p in after.poses] == [p.position for p in before.poses]  # the same map: C544
