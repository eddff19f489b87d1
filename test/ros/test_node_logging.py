"""What the node says on its console over real DDS: refused inputs once, header-less input, its real topics."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
from conftest import PROBLEMS, SCENES
from ros_helpers import NodeProcess, RosClient

from physics_mapper.model.scene_files import load_problem
from physics_mapper.msg_adapters.hypotheses import hypotheses_msgs

NAMESPACE = "/console"
#: Where a remap sends one object's hypotheses, as a launch file's remappings would.
REMAPPED = "/perception/cube_top"
PARAMETERS = {"rate_hz": 4.0, "deadline": 0.2, "max_age": 60.0, "diagnostics_period": 0.25}


@pytest.fixture
def console(tmp_path: Path) -> Iterator[tuple[NodeProcess, RosClient]]:
    node = NodeProcess(SCENES / "pyramid.yaml", PARAMETERS, tmp_path / "node.log", NAMESPACE)
    client = RosClient(NAMESPACE)
    try:
        client.next_diagnostics(lambda d: True, timeout=30.0, what="the node's first diagnostics")
        yield node, client
    finally:
        client.close()
        assert node.stop() == 0, node.output()


def publish_problem(client: RosClient, frame_id: str, stamp_ns: int) -> None:
    problem = load_problem(PROBLEMS / "pyramid.yaml")
    for name, hypotheses in zip(problem.scene.object_names, problem.hypotheses, strict=True):
        client.publish(name, *hypotheses_msgs(hypotheses, frame_id=frame_id, stamp_ns=stamp_ns))


def test_a_refused_input_is_logged_once_however_often_it_comes(console: tuple[NodeProcess, RosClient]) -> None:
    node, client = console
    refusal = (
        "cube_top: PoseArray refused: no transform from 'camera' to 'world': frame 'camera' is unknown (waited 0.2 s)"
    )
    client.keep_publishing(
        lambda: publish_problem(client, "camera", stamp_ns=1_000), lambda: refusal in node.output(), "the refusal"
    )
    for stamp_ns in range(2_000, 7_000, 1_000):  # five more, refused for the same reason
        publish_problem(client, "camera", stamp_ns=stamp_ns)
    client.next_diagnostics(
        lambda d: any(int(kv.value) >= 6 for s in d.status for kv in s.values if kv.key == "poses refused"),
        what="every refused PoseArray counted",
    )
    assert node.output().count(refusal) == 1


def test_a_pose_array_without_a_frame_is_mapped_in_the_scene_frame(console: tuple[NodeProcess, RosClient]) -> None:
    node, client = console
    assumed = "cube_top: a PoseArray without a frame_id is taken in the scene frame 'world'"
    # A map comes as soon as some object has hypotheses (the others absent): wait for cube_top's too.
    client.keep_publishing(
        lambda: publish_problem(client, "", stamp_ns=3_000),
        lambda: assumed in node.output() and any(c.header.frame_id == "world" for c in client.configurations),
        "a map from header-less hypotheses",
    )
    assert node.output().count(assumed) == 1


def test_the_start_up_line_names_the_topics_as_remapped(tmp_path: Path) -> None:
    node = NodeProcess(
        SCENES / "pyramid.yaml",
        PARAMETERS,
        tmp_path / "node.log",
        "/remapped",
        remaps={
            "hypotheses/cube_top": REMAPPED,
        },
    )
    client = RosClient("/remapped")
    try:
        client.next_diagnostics(lambda d: True, timeout=30.0, what="the node's first diagnostics")
    finally:
        client.close()
        node.stop()
    started = next(line for line in node.output().splitlines() if "listening on" in line)
    assert REMAPPED in started and "/remapped/hypotheses/cube_top/weights" in started
    assert "/remapped/hypotheses/cube_top," not in started
    assert "/remapped/hypotheses/cube_left" in started
