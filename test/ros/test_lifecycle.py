"""The managed (lifecycle) node over real DDS: transitions driven through lifecycle_msgs services."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from conftest import PROBLEMS, SCENES
from lifecycle_msgs.msg import State, Transition
from ros_helpers import Lifecycle, NodeProcess, RosClient, stamp_ns_of

from physics_mapper.mapping.topics import CONFIGURATION_TOPIC, output_topic
from physics_mapper.model.geometry import Pose
from physics_mapper.model.hypotheses import Hypothesis, RankedHypotheses
from physics_mapper.model.scene_files import load_problem
from physics_mapper.msg_adapters.hypotheses import hypotheses_msgs

NAMESPACE = "/managed"
#: Ticks a second: the deactivated node is watched for a few of its tick periods.
RATE_HZ = 4.0


@pytest.fixture
def managed(tmp_path: Path) -> Iterator[tuple[NodeProcess, RosClient, Lifecycle]]:
    parameters = {"rate_hz": RATE_HZ, "deadline": 0.2, "max_age": 60.0, "diagnostics_period": 0.25}
    node = NodeProcess(SCENES / "pyramid.yaml", parameters, tmp_path / "node.log", NAMESPACE, managed=True)
    client = RosClient(NAMESPACE)
    try:
        yield node, client, Lifecycle(client, NAMESPACE)
    finally:
        client.close()
        assert node.stop() == 0, node.output()


def publish_until_mapped(client: RosClient, stamp_ns: int) -> None:
    problem = load_problem(PROBLEMS / "pyramid.yaml")

    def publish() -> None:
        for name, hypotheses in zip(problem.scene.object_names, problem.hypotheses, strict=True):
            client.publish(name, *hypotheses_msgs(hypotheses, frame_id=problem.scene.frame_id, stamp_ns=stamp_ns))

    objects = len(problem.scene.objects)
    client.keep_publishing(publish, lambda: client.map_of(stamp_ns, objects) is not None, f"a map stamped {stamp_ns}")


def configuration_publishers(client: RosClient) -> int:
    return client.node.count_publishers(output_topic(CONFIGURATION_TOPIC, NAMESPACE))


def test_the_managed_node_follows_its_transitions(managed: tuple[NodeProcess, RosClient, Lifecycle]) -> None:
    node, client, lifecycle = managed
    assert lifecycle.state() == State.PRIMARY_STATE_UNCONFIGURED
    assert configuration_publishers(client) == 0  # nothing made before configure

    assert lifecycle.change(Transition.TRANSITION_CONFIGURE)
    assert lifecycle.state() == State.PRIMARY_STATE_INACTIVE
    client.wait_for(lambda: configuration_publishers(client) == 1, what="the configured node's publisher")

    assert lifecycle.change(Transition.TRANSITION_ACTIVATE)
    assert lifecycle.state() == State.PRIMARY_STATE_ACTIVE
    publish_until_mapped(client, stamp_ns=1_000)

    assert lifecycle.change(Transition.TRANSITION_DEACTIVATE)
    assert lifecycle.state() == State.PRIMARY_STATE_INACTIVE
    published = len(client.configurations)
    problem = load_problem(PROBLEMS / "pyramid.yaml")
    for name, hypotheses in zip(problem.scene.object_names, problem.hypotheses, strict=True):
        client.publish(name, *hypotheses_msgs(hypotheses, frame_id=problem.scene.frame_id, stamp_ns=2_000))
    client.spin_until(lambda: False, timeout=4 / RATE_HZ)  # four tick periods
    assert len(client.configurations) == published  # inactive: no tick, nothing published

    assert lifecycle.change(Transition.TRANSITION_ACTIVATE)  # the inputs kept arriving meanwhile
    client.wait_for(lambda: any(stamp_ns_of(c) == 2_000 for c in client.configurations), what="the map stamped 2000")

    assert lifecycle.change(Transition.TRANSITION_DEACTIVATE)
    assert lifecycle.change(Transition.TRANSITION_CLEANUP)
    assert lifecycle.state() == State.PRIMARY_STATE_UNCONFIGURED
    client.wait_for(lambda: configuration_publishers(client) == 0, what="the publisher gone after cleanup")

    assert lifecycle.change(Transition.TRANSITION_CONFIGURE)  # configured again after a cleanup
    assert lifecycle.state() == State.PRIMARY_STATE_INACTIVE
    assert lifecycle.change(Transition.TRANSITION_INACTIVE_SHUTDOWN)
    assert lifecycle.state() == State.PRIMARY_STATE_FINALIZED
    assert node.alive


def test_a_scene_that_cannot_be_loaded_fails_configure_and_keeps_the_node(tmp_path: Path) -> None:
    node = NodeProcess(tmp_path / "missing.yaml", {}, tmp_path / "node.log", "/bad_scene", managed=True)
    client = RosClient("/bad_scene")
    try:
        lifecycle = Lifecycle(client, "/bad_scene")
        assert not lifecycle.change(Transition.TRANSITION_CONFIGURE)
        assert lifecycle.state() == State.PRIMARY_STATE_UNCONFIGURED
        assert node.alive
    finally:
        client.close()
        code = node.stop()
    output = node.output()
    assert code == 0, output
    assert "configure failed:" in output and "missing.yaml" in output
    assert "Traceback" not in output


#: Searches that run to their deadline, tick after tick: floating cubes (none stays put) of many
#: hypotheses each, searched by the paper's joint branch and bound (which settles each to find it
#: unstable: the default search rules a free fall out before its first candidate), the bound low
#: enough that none is pruned, each settling long (a few ticks' deadlines for all), the settled top
#: hypotheses published as the map; ticks a little longer than the deadline apart.
SEARCH_DEADLINE = 2.0
FLOATING_HYPOTHESES = 1000
#: Deactivations tried until one is sent while a search runs (a map arrives before its answer).
DEACTIVATION_ATTEMPTS = 5


def floating_hypotheses(stamp_ns: int, shift: float) -> list[tuple[str, tuple[Any, Any]]]:
    """Each pyramid cube's hypotheses, all in the air and apart (every configuration falls: none is
    valid), moved ``shift`` metres along y (new inputs: the search starts again)."""
    problem = load_problem(PROBLEMS / "pyramid.yaml")
    messages = []
    for index, name in enumerate(problem.scene.object_names):
        poses = [
            Hypothesis(Pose((-0.6 + 0.6 * index, shift + 0.001 * k, 1.0 + 0.001 * k), (0.0, 0.0, 0.0, 1.0)), 1.0)
            for k in range(FLOATING_HYPOTHESES)
        ]
        hypotheses = RankedHypotheses.from_weighted(poses)
        messages.append((name, hypotheses_msgs(hypotheses, frame_id=problem.scene.frame_id, stamp_ns=stamp_ns)))
    return messages


def mapped(client: RosClient, stamp_ns: int) -> bool:
    """Whether a map of the inputs stamped ``stamp_ns`` came."""
    return any(stamp_ns_of(c) == stamp_ns for c in client.configurations)


def test_deactivating_during_a_search_answers_success_and_publishes_no_map_after(tmp_path: Path) -> None:
    parameters = {
        "rate_hz": 1.0 / (SEARCH_DEADLINE + 0.3),
        "deadline": SEARCH_DEADLINE,
        "probability_threshold": 1.0e-12,
        "settle_time": 2.0,
        "fallback": "settled",
        "strategy": "joint",
        "max_hypotheses_per_object": FLOATING_HYPOTHESES,
        "max_age": 600.0,
        "diagnostics_period": 0.25,
    }
    namespace = "/deactivated_in_search"
    node = NodeProcess(SCENES / "pyramid.yaml", parameters, tmp_path / "node.log", namespace, managed=True)
    client = RosClient(namespace)
    try:
        lifecycle = Lifecycle(client, namespace)
        assert lifecycle.change(Transition.TRANSITION_CONFIGURE)
        in_search = False
        for attempt in range(DEACTIVATION_ATTEMPTS):
            assert lifecycle.change(Transition.TRANSITION_ACTIVATE)
            stamp_ns = 1_000 * (attempt + 1)

            def publish(stamp_ns: int = stamp_ns, shift: float = 0.01 * attempt) -> None:
                for name, (poses, weights) in floating_hypotheses(stamp_ns, shift):
                    client.publish(name, poses, weights)

            def mapped_now(stamp_ns: int = stamp_ns) -> bool:
                return mapped(client, stamp_ns)

            # Under a loaded full run the first search after activation may take several ticks to answer.
            client.keep_publishing(publish, mapped_now, "a map", timeout=60.0)

            client.spin_until(lambda: False, timeout=SEARCH_DEADLINE / 2)  # into the next tick's search
            before = len(client.configurations)
            assert lifecycle.change(Transition.TRANSITION_DEACTIVATE)
            assert lifecycle.state() == State.PRIMARY_STATE_INACTIVE
            answered = len(client.configurations)
            for name, (poses, weights) in floating_hypotheses(stamp_ns + 500, -0.01):
                client.publish(name, poses, weights)
            client.spin_until(lambda: False, timeout=3 * (SEARCH_DEADLINE + 0.3))  # three tick periods
            # The search the request waited for published its map before the answer, none came after it.
            assert not mapped(client, stamp_ns + 500)
            assert len(client.configurations) - answered <= 1  # at most one map on its way at the answer
            assert node.alive
            # A map after the request was sent is of a search that ran then: inactive, the node starts none.
            if len(client.configurations) > before:
                in_search = True
                break
        assert in_search, f"no deactivation of {DEACTIVATION_ATTEMPTS} was sent during a search"
        assert lifecycle.change(Transition.TRANSITION_ACTIVATE)  # ticks again, with the inputs sent meanwhile
        client.wait_for(lambda: mapped(client, stamp_ns + 500), what="the newer map")
    finally:
        client.close()
        code = node.stop()
    assert code == 0 and "Traceback" not in node.output(), node.output()
