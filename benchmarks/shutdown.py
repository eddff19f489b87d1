"""How long the node takes to stop on SIGINT or SIGTERM at various moments (the figure test_signals.py leaves out).

Per phase, ``--runs`` runs: the node is started (a child process), brought to the phase, then
signalled; printed are the seconds from the signal to its exit (median / max) and its exit codes.
Phases: ``idle`` (no input), ``searching`` (a problem far too large to finish, deadline 0.2 s),
``long search`` (the same with a 5 s deadline at 0.1 Hz: the signal interrupts the search) and
``start-up`` (0.3 s after the process started, during its imports). Run:

    .venv/bin/python benchmarks/shutdown.py [--runs 5]
"""

from __future__ import annotations

import argparse
import signal
import statistics
import tempfile
import time
from pathlib import Path

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseArray
from live_node import PYRAMID_SCENE, busy_problem, isolate_ros, load_average
from std_msgs.msg import Float64MultiArray

from physics_mapper.mapping.topics import DIAGNOSTICS_TOPIC, NODE_NAME, poses_topic, weights_topic
from physics_mapper.msg_adapters.hypotheses import hypotheses_msgs
from physics_mapper.ros.child_process import start_node
from physics_mapper.ros.qos import DIAGNOSTICS_QOS

PHASES = {
    "start-up": {},
    "idle": {"diagnostics_period": 0.1},
    "searching": {"rate_hz": 4.0, "deadline": 0.2, "probability_threshold": 0.0, "diagnostics_period": 0.1},
    "long search": {"rate_hz": 0.1, "deadline": 5.0, "probability_threshold": 0.0, "diagnostics_period": 0.1},
}
NAMESPACE = "/shutdown"


class Observer:
    """Watches the node's diagnostics and feeds it the busy problem."""

    def __init__(self) -> None:
        self.node = rclpy.create_node("shutdown_observer", namespace=NAMESPACE)
        self.searched = self.seen = False
        self.node.create_subscription(DiagnosticArray, DIAGNOSTICS_TOPIC, self._on_diagnostics, DIAGNOSTICS_QOS)
        problem = busy_problem()
        self._round = []
        for name, hypotheses in zip(problem.scene.object_names, problem.hypotheses, strict=True):
            poses, weights = hypotheses_msgs(hypotheses, frame_id=problem.scene.frame_id, stamp_ns=10**9)
            self._round += [(self.node.create_publisher(PoseArray, poses_topic(name), 10), poses)]
            self._round += [(self.node.create_publisher(Float64MultiArray, weights_topic(name), 10), weights)]

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        for status in msg.status:
            if status.name == f"{NODE_NAME}: search" and status.hardware_id == f"{NAMESPACE}/{NODE_NAME}":
                self.seen = True
                values = {kv.key: kv.value for kv in status.values}
                self.searched = self.searched or values.get("nodes visited", "0") != "0"

    def bring_to(self, phase: str, timeout: float = 60.0) -> None:
        end = time.monotonic() + timeout
        while not (self.searched if "search" in phase else self.seen):
            if time.monotonic() > end:
                raise RuntimeError(f"the node did not reach phase {phase!r}")
            if "search" in phase:
                for publisher, message in self._round:
                    publisher.publish(message)
            rclpy.spin_once(self.node, timeout_sec=0.2)


def stop_time(phase: str, number: signal.Signals) -> tuple[float, int]:
    with tempfile.TemporaryFile(mode="w+") as log:
        process = start_node(PYRAMID_SCENE, PHASES[phase], namespace=NAMESPACE, output=log)
        if phase == "start-up":
            time.sleep(0.3)
        else:
            observer = Observer()
            try:
                observer.bring_to(phase)
                if phase == "long search":
                    time.sleep(1.0)  # well inside the 5 s search
            finally:
                observer.node.destroy_node()  # type: ignore[no-untyped-call]
        start = time.monotonic()
        process.send_signal(number)
        code = process.wait(timeout=60)
        return time.monotonic() - start, code


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--runs", type=int, default=5, help="runs per phase and signal (default 5)")
    args = parser.parse_args()
    isolate_ros()
    rclpy.init()
    print(f"load average: {load_average()}; {args.runs} runs per row; scene {Path(PYRAMID_SCENE).name}")
    print("| phase | signal | signal to exit, s (median / max) | exit codes |")
    print("| --- | --- | ---: | --- |")
    for phase in PHASES:
        for number in (signal.SIGINT, signal.SIGTERM):
            results = [stop_time(phase, number) for _ in range(args.runs)]
            times = [seconds for seconds, _ in results]
            codes = sorted({code for _, code in results})
            print(
                f"| {phase} | {number.name} | {statistics.median(times):.3f} / {max(times):.3f} | {codes} |", flush=True
            )
    rclpy.shutdown()


if __name__ == "__main__":
    main()
