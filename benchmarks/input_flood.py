"""Does the node keep its ticks on time under a 200 Hz input flood, and when does a message arrive?

The node runs in this process, once with rclpy's single-threaded executor (what ``main`` uses)
and once with a multi-threaded one (its subscriptions and timers are in separate callback
groups, so subscriptions then run while a tick searches). A child process publishes every
object's hypotheses and weights at ``--hz`` (6 messages per round, 60 poses per array) for the
whole run; every tick searches to its deadline (a problem far too large to finish), at
``rate_hz`` 5 and a 0.15 s deadline. Printed per executor:

- tick intervals (median / p99 / max, ms; the period is 200 ms) and late ticks (more than 1.5 periods);
- the longest search (ms; deadline 150 ms);
- how long a message waited between its reception by the middleware and its callback (median /
  p99 / max, ms): the error of an arrival time taken when the callback runs, which the node
  therefore does not use; it takes the middleware's receive timestamp;
- messages handled per second.

Run: ``.venv/bin/python benchmarks/input_flood.py [--seconds 20] [--hz 200]``.
"""

from __future__ import annotations

import argparse
import itertools
import subprocess
import sys
import time
from collections.abc import Mapping
from typing import Any

import rclpy
from geometry_msgs.msg import PoseArray
from live_node import PYRAMID_SCENE, busy_problem, isolate_ros, load_average, spread
from rclpy.executors import Executor, MultiThreadedExecutor, SingleThreadedExecutor
from rclpy.parameter import Parameter
from rclpy.signals import SignalHandlerOptions
from std_msgs.msg import Float64MultiArray

from physics_mapper.mapping.topics import poses_topic, weights_topic
from physics_mapper.msg_adapters.hypotheses import hypotheses_msgs
from physics_mapper.ros import node as node_module
from physics_mapper.ros.node import PhysicsMapperNode
from physics_mapper.ros.node_inputs import InputHandlers

RATE_HZ, DEADLINE = 5.0, 0.15
NAMESPACE = "/flood"


#: How long each message waited, in milliseconds, from its arrival to its callback (every node of this process).
WAITS_MS: list[float] = []


class TimedHandlers(InputHandlers):
    """The node's input handlers, noting how long each message waited."""

    def received(self, info: Mapping[str, Any]) -> float:
        if info.get("received_timestamp"):
            WAITS_MS.append((time.time_ns() - int(info["received_timestamp"])) / 1e6)
        return super().received(info)


class TimedNode(PhysicsMapperNode):
    """The node, noting when each tick starts and how long it searched; its handlers note the waits."""

    def __init__(self, **kwargs: Any) -> None:
        self.tick_starts: list[float] = []
        self.search_times: list[float] = []
        WAITS_MS.clear()
        self.waits_ms = WAITS_MS
        node_module.InputHandlers = TimedHandlers  # type: ignore[attr-defined]  # the node makes its handlers by this name
        super().__init__(**kwargs)

    def _tick(self) -> None:
        self.tick_starts.append(time.monotonic())
        super()._tick()
        report = self.outputs.diagnostics.last_report
        if report is not None:
            self.search_times.append(report.search_time)


def flood(hz: float, seconds: float) -> None:
    """The child process: publish the busy problem at ``hz`` rounds per second for ``seconds``."""
    rclpy.init()
    node = rclpy.create_node("flood", namespace=NAMESPACE)
    problem = busy_problem()
    round_ = []
    for name, hypotheses in zip(problem.scene.object_names, problem.hypotheses, strict=True):
        poses, weights = hypotheses_msgs(hypotheses, frame_id=problem.scene.frame_id, stamp_ns=0)
        round_ += [(node.create_publisher(PoseArray, poses_topic(name), 10), poses)]
        round_ += [(node.create_publisher(Float64MultiArray, weights_topic(name), 10), weights)]
    time.sleep(1.0)  # discovery
    end = next_round = time.monotonic()
    end += seconds
    while time.monotonic() < end:
        for publisher, message in round_:
            publisher.publish(message)
        next_round += 1.0 / hz
        time.sleep(max(0.0, next_round - time.monotonic()))
    rclpy.shutdown()


def run(executor_name: str, hz: float, seconds: float) -> str:
    """One run with the named executor; the table row."""
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    given = {"scene_file": str(PYRAMID_SCENE), "rate_hz": RATE_HZ, "deadline": DEADLINE, "probability_threshold": 0.0}
    overrides = [Parameter(name, value=value) for name, value in given.items()]  # type: ignore[no-untyped-call]
    node = TimedNode(namespace=NAMESPACE, parameter_overrides=overrides)
    executor: Executor = SingleThreadedExecutor() if executor_name == "single" else MultiThreadedExecutor(2)
    executor.add_node(node)
    command = [sys.executable, __file__, "--publish", "--hz", str(hz), "--seconds", str(seconds + 1.0)]
    publisher = subprocess.Popen(command)
    try:
        end = time.monotonic() + seconds + 2.0
        while time.monotonic() < end:
            executor.spin_once(timeout_sec=0.05)
    finally:
        publisher.wait()
        executor.shutdown()
        node.destroy_node()
        rclpy.shutdown()
    starts = node.tick_starts[len(node.tick_starts) // 10 :]  # after the flood began
    intervals = [(b - a) * 1000.0 for a, b in itertools.pairwise(starts)]
    late = sum(interval > 1.5 * 1000.0 / RATE_HZ for interval in intervals)
    longest = max(node.search_times) * 1000.0 if node.search_times else float("nan")
    handled = len(node.waits_ms) / (seconds + 2.0)
    return (
        f"| {executor_name}-threaded | {len(node.tick_starts)} | {spread(intervals)} | {late} | {longest:.1f} | "
        f"{spread(node.waits_ms)} | {handled:.0f} |"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=20.0, help="flood duration per executor (default 20)")
    parser.add_argument("--hz", type=float, default=200.0, help="input rounds per second (default 200)")
    parser.add_argument("--publish", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    isolate_ros()
    if args.publish:
        flood(args.hz, args.seconds)
        return
    print(f"load average before: {load_average()}; {args.hz:g} Hz x 6 messages for {args.seconds:g} s per executor")
    print(f"rate_hz {RATE_HZ:g} (period {1000 / RATE_HZ:.0f} ms), deadline {DEADLINE * 1000:.0f} ms")
    print(
        "| executor | ticks | tick interval ms (median / p99 / max) | late ticks | longest search ms "
        "| message wait before its callback ms (median / p99 / max) | messages/s |"
    )
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: |")
    for name in ("single", "multi"):
        print(run(name, args.hz, args.seconds), flush=True)
    print(f"load average after: {load_average()}")


if __name__ == "__main__":
    main()
