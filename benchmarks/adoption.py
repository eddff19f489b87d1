"""What receiving and adopting one large PoseArray costs the node, the way it is done now beside the former one.

Before: rclpy turned the serialised message into a Python object per pose (about 80 ms for 9,000
poses), the node then checked and converted every pose, and ranked them all to keep the
``max_hypotheses_per_object`` (100) heaviest. Now: the node subscribes raw, reads the header and
views the poses as one numpy array (:mod:`physics_mapper.msg_adapters.pose_array_cdr`), and converts poses
heaviest first until it has the 100 it keeps (:func:`physics_mapper.mapping.inputs.rank`). Both
paths are timed here side by side on the same serialised messages, median of ``--repeats``, with
the share of one core that three such arrays at 5 Hz (15 per second) take. Run:

    .venv/bin/python benchmarks/adoption.py
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable

import numpy as np
from geometry_msgs.msg import PoseArray
from live_node import load_average
from rclpy.serialization import deserialize_message, serialize_message
from std_msgs.msg import Float64MultiArray

from physics_mapper.mapping.inputs import InUse, rank
from physics_mapper.model.geometry import make_pose
from physics_mapper.model.hypotheses import Hypothesis, RankedHypotheses
from physics_mapper.model.scene import Workspace
from physics_mapper.msg_adapters.hypotheses import pose_array_msg, raw_pose, received_pose_array, received_weights

SIZES = (100, 1_000, 9_000, 30_000)
KEPT = 100
ARRAYS_PER_SECOND = 15  # three objects at 5 Hz
WORKSPACE = Workspace((-10.0, -10.0, -10.0), (10.0, 10.0, 10.0))


def messages(count: int, rng: np.random.Generator) -> tuple[bytes, Float64MultiArray]:
    """A serialised PoseArray of ``count`` random unit-quaternion poses, and its weights message."""
    quaternions = rng.normal(size=(count, 4))
    quaternions /= np.linalg.norm(quaternions, axis=1, keepdims=True)
    positions = rng.uniform(-1.0, 1.0, size=(count, 3))
    poses = [make_pose(tuple(p), tuple(q)) for p, q in zip(positions.tolist(), quaternions.tolist(), strict=True)]
    raw = serialize_message(pose_array_msg(poses, frame_id="world", stamp_ns=1))
    return raw, Float64MultiArray(data=rng.random(count).tolist())


def before(raw: bytes, weights: Float64MultiArray) -> None:
    """rclpy's message object, every pose checked and converted, all ranked, the heaviest kept."""
    message = deserialize_message(raw, PoseArray)
    values = list(weights.data)
    hypotheses = []
    for index, pose in enumerate(message.poses):
        position, orientation = raw_pose(pose)
        hypotheses.append(Hypothesis(make_pose(tuple(position), tuple(orientation)), values[index]))
    RankedHypotheses.from_weighted(hypotheses, keep_at_most=KEPT)


def after(raw: bytes, weights: Float64MultiArray) -> None:
    """The node now: the serialised message viewed, the heaviest poses converted until 100 are kept."""
    poses = received_pose_array(raw, expected_frame="world", workspace=WORKSPACE, received=0.0)
    in_use = rank(poses, received_weights(weights, received=0.0), KEPT)
    assert isinstance(in_use, InUse) and len(in_use.hypotheses) == min(KEPT, poses.count)


def median_ms(action: Callable[[], None], repeats: int) -> float:
    samples = []
    for _ in range(repeats):
        start = time.perf_counter()
        action()
        samples.append((time.perf_counter() - start) * 1000.0)
    return statistics.median(samples)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=9, help="timed repetitions per figure (default 9)")
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    print(f"load average: {load_average()}; keep {KEPT} hypotheses; medians of {args.repeats}")
    print("| poses | message kB | before ms | after ms | speed-up | 15 arrays/s before | 15 arrays/s after |")
    print("| ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    for count in SIZES:
        raw, weights = messages(count, rng)
        old = median_ms(lambda: before(raw, weights), args.repeats)  # noqa: B023
        new = median_ms(lambda: after(raw, weights), args.repeats)  # noqa: B023
        print(
            f"| {count} | {len(raw) / 1024:.0f} | {old:.2f} | {new:.2f} | {old / new:.0f} x | "
            f"{old * ARRAYS_PER_SECOND / 10:.0f} % of a core | {new * ARRAYS_PER_SECOND / 10:.1f} % of a core |",
            flush=True,
        )


if __name__ == "__main__":
    main()
