"""What the node remembers of its inputs is bounded in bytes, not only in messages: an object fed large
arrays keeps at most ``HISTORY_BYTES`` of each kind beside its newest message, and pairing still works.

Memory is counted with ``tracemalloc`` (what Python allocated and still holds), a decision of the
program's, not a timing.
"""

from __future__ import annotations

import tracemalloc

import numpy as np

from physics_mapper.mapping.inputs import (
    HISTORY_BYTES,
    HISTORY_LENGTH,
    JUMPS_REMEMBERED,
    InputSettings,
    InputTracker,
    check_poses,
    check_weights,
)
from physics_mapper.model.scene import Workspace

WORKSPACE = Workspace((-10.0, -10.0, -10.0), (10.0, 10.0, 10.0))
POSES = 100_000
WEIGHTS = 1_000_000
MIB = 1024 * 1024


def large_messages(tracker: InputTracker, received: float, weights: int = WEIGHTS) -> None:
    block = np.zeros((POSES, 7))
    block[:, 2] = 0.1
    block[:, 6] = 1.0
    poses = check_poses(
        block, frame_id="world", expected_frame="world", workspace=WORKSPACE, stamp_ns=0, received=received
    )
    tracker.add_poses("cube", poses)
    tracker.add_weights("cube", check_weights(np.full(weights, 1.0), received=received))


def test_sixteen_large_messages_keep_the_history_within_its_bytes() -> None:
    tracemalloc.start()
    try:
        tracker = InputTracker(["cube"])
        for index in range(HISTORY_LENGTH):
            last = index == HISTORY_LENGTH - 1
            large_messages(tracker, received=float(index), weights=POSES if last else WEIGHTS)
        held = tracemalloc.get_traced_memory()[0]
    finally:
        tracemalloc.stop()
    newest = POSES * 7 * 8 + WEIGHTS * 8  # kept however large
    assert held < 2 * HISTORY_BYTES + newest + 4 * MIB, f"{held / MIB:.0f} MiB held"
    status = tracker.snapshot(HISTORY_LENGTH - 1.0, InputSettings(10.0, 100, True)).objects[0]
    assert status.hypotheses is not None and len(status.hypotheses) == 100, status  # the newest pair maps


def test_clock_jumps_are_counted_and_the_newest_remembered() -> None:
    tracker = InputTracker(["cube"])
    for index in range(3 * JUMPS_REMEMBERED):
        tracker.add_weights("cube", check_weights([1.0], received=100.0))
        tracker.add_weights("cube", check_weights([1.0], received=float(index)))  # back, from 100 s
    assert len(tracker.clock_jumps) == JUMPS_REMEMBERED
    status = tracker.snapshot(3 * JUMPS_REMEMBERED - 1.0, InputSettings(10.0, 100, False)).objects[0]
    assert f"({3 * JUMPS_REMEMBERED} jump(s) so far)" in dict(status.details)["clock jumped back"]
