"""The node against inputs of unbounded size: 100,000-pose arrays, with ``max_hypotheses_per_object`` at its maximum.

A real node process over DDS (reliable input, so the large arrays arrive); what is asserted is what the node
decided: it kept running, applied the hard cap and said so, published a map, and its memory stayed within
a generous ceiling over its own baseline (the comparison before the cap needed 224 GiB at once).
"""

from __future__ import annotations

import signal
import subprocess
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from conftest import PROBLEMS, SCENES
from ros_helpers import PHYSICS_MAPPER, RosClient, object_status

from physics_mapper.model.geometry import Pose
from physics_mapper.model.limits import MAX_SEARCHED_HYPOTHESES
from physics_mapper.model.scene_files import load_problem
from physics_mapper.msg_adapters.hypotheses import pose_array_msg, weights_msg

PYRAMID = load_problem(PROBLEMS / "pyramid.yaml")
POSES = 100_000
#: Memory the node may grow by while it takes 100,000-pose arrays for every object: generous (the arrays
#: themselves are 5.6 MB each), and far below what comparing them all pairwise would take.
GROWTH_CEILING_BYTES = 1 << 30


def memory_kib(pid: int, field: str) -> int:
    """A ``/proc/<pid>/status`` memory figure (``VmRSS``, ``VmHWM``: the peak), KiB."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith(f"{field}:"):
            return int(line.split()[1])
    raise AssertionError(f"no {field} in /proc/{pid}/status")


@pytest.fixture
def capped_node(tmp_path: Path) -> Iterator[tuple[subprocess.Popen[str], RosClient]]:
    log = (tmp_path / "node.log").open("w")
    parameters = {
        "scene_file": str(SCENES / "pyramid.yaml"),
        "max_hypotheses_per_object": "100000",
        "input_reliability": "reliable",
        "max_age": "600.0",
    }
    arguments = [item for name, value in parameters.items() for item in ("-p", f"{name}:={value}")]
    command = [str(PHYSICS_MAPPER), "node", "--ros-args", *arguments, "-r", "__ns:=/capped"]
    process = subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT, text=True)
    client = RosClient("/capped")
    try:
        client.next_diagnostics(lambda d: True, timeout=30.0, what="the node's first diagnostics")
        yield process, client
    finally:
        client.close()
        process.send_signal(signal.SIGINT)
        process.wait(timeout=30)
        log.close()


def test_a_node_taking_100000_pose_arrays_applies_the_hard_cap_maps_and_stays_bounded(
    capped_node: tuple[subprocess.Popen[str], RosClient],
) -> None:
    process, client = capped_node
    baseline = memory_kib(process.pid, "VmRSS")
    rng = np.random.default_rng(0)
    messages = {}
    truth = PYRAMID.scene.ground_truth
    assert truth is not None
    for name, pose in zip(PYRAMID.scene.object_names, truth, strict=True):
        # Within 0.1 mm of the true pyramid: every choice is valid, so the first configuration is the map.
        positions = np.asarray(pose.position) + rng.normal(0.0, 1e-4, size=(POSES, 3))
        poses = [Pose((float(x), float(y), float(z))) for x, y, z in positions]
        weights = rng.uniform(0.5, 1.0, size=POSES).tolist()
        messages[name] = (pose_array_msg(poses, frame_id="world", stamp_ns=10**9), weights_msg(weights))

    def publish() -> None:
        for name, (poses, weights) in messages.items():
            client.publish(name, poses, weights)

    capped = f"kept the {MAX_SEARCHED_HYPOTHESES} heaviest of {POSES} hypotheses (the hard cap"
    client.keep_publishing(
        publish,
        lambda: (
            bool(client.diagnostics)
            and all(capped in object_status(client.diagnostics[-1], name).message for name in messages)
        ),
        "every object's hypotheses capped",
        timeout=120.0,
    )
    # A map holding every object (one made before all had come leaves the others out)
    client.wait_for(
        lambda: any(len(c.poses) == len(messages) for c in client.configurations), 60.0, "a map of every object"
    )
    assert process.poll() is None  # alive: no MemoryError
    growth = (memory_kib(process.pid, "VmHWM") - baseline) * 1024
    assert growth < GROWTH_CEILING_BYTES, f"the node grew by {growth / 2**20:.0f} MiB"
