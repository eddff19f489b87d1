"""SIGINT and SIGTERM stop the node cleanly at any moment: exit code 0, nothing but its log.

One test, many runs at seeded random moments: during start-up (from the moment the process runs
our code, read from /proc: the entry point holds both signals from its first line until it
handles them), idle, in the middle of searches and under a 200 Hz input flood; a signal landing
while a tick publishes comes by chance in the last two. Runs go seven at a time, which also
loads the machine. Asserted: the exit code and the output, never how long the stop took (that
figure is in BENCHMARKS.md, "Stopping on a signal").
"""

from __future__ import annotations

import random
import re
import signal
import subprocess
import sys
import textwrap
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from conftest import PROBLEMS, SCENES
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseArray
from rclpy.publisher import Publisher
from ros_helpers import NodeProcess, RosClient, search_status, values
from std_msgs.msg import Float64MultiArray
from test_node import busy_problem, publish_problem

from physics_mapper.mapping.topics import poses_topic, weights_topic
from physics_mapper.model.scene_files import load_problem
from physics_mapper.msg_adapters.hypotheses import hypotheses_msgs

#: (phase, signal) of every run; each phase with both signals.
RUNS = [
    (phase, number)
    for phase, count in (("start-up", 2), ("idle", 1), ("searching", 2), ("flood", 2))
    for number in (signal.SIGINT, signal.SIGTERM)
    for _ in range(count)
]
AT_ONCE = 7
#: The longest random wait (seconds) before the signal, per phase: start-up takes about a second.
LONGEST_WAIT = {"start-up": 1.5, "idle": 0.5, "searching": 0.5, "flood": 0.5}
NODE_PARAMETERS = {"rate_hz": 4.0, "deadline": 0.2, "probability_threshold": 0.0, "diagnostics_period": 0.1}
FLOOD_HZ = 200
#: Lines a cleanly stopping node may print: its own log lines at level INFO.
# The node's own log lines (a tick may warn of its inputs, e.g. weights not yet received).
LOG_LINE = re.compile(r"\[(INFO|WARN)\] \[[0-9.]+\] \[[\w.]*physics_mapper\]: ")
SIGTERM_MASK = 1 << (signal.SIGTERM - 1)


def handles_sigterm(pid: int) -> bool:
    """Whether the process runs our code: it holds SIGTERM pending or handles it (SigBlk, SigCgt in /proc)."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except FileNotFoundError:
        return False
    masks = [line.split()[1] for line in status.splitlines() if line.startswith(("SigBlk:", "SigCgt:"))]
    return any(int(mask, 16) & SIGTERM_MASK for mask in masks)


@dataclass
class Run:
    """One node started, brought to its phase, and signalled after a random wait."""

    index: int
    phase: str
    number: signal.Signals
    wait: float
    log: Path
    node: NodeProcess | None = None
    client: RosClient | None = None
    flood: threading.Thread | None = None
    flooding: threading.Event = field(default_factory=threading.Event)
    signal_at: float | None = None

    @property
    def namespace(self) -> str:
        return f"/signals{self.index}"

    def start(self) -> None:
        self.node = NodeProcess(SCENES / "pyramid.yaml", NODE_PARAMETERS, self.log, self.namespace)
        if self.phase != "start-up":
            self.client = RosClient(self.namespace)

    def advance(self) -> None:
        """Bring the run one step towards its phase; once there, signal it when its wait is over."""
        assert self.node is not None
        if self.signal_at is None and self._in_phase():
            self.signal_at = time.monotonic() + self.wait
        if self.signal_at is not None and time.monotonic() >= self.signal_at and self.node.alive:
            self.node.process.send_signal(self.number)
            self.signal_at = float("inf")

    def _in_phase(self) -> bool:
        assert self.node is not None
        if self.phase == "start-up":
            return handles_sigterm(self.node.process.pid)
        assert self.client is not None
        self.client.executor.spin_once(timeout_sec=0.01)
        if not self.client.diagnostics:
            return False
        if self.phase == "idle":
            return True
        search = values(search_status(self.client.diagnostics[-1]) or DiagnosticStatus())
        if search.get("nodes visited", "0") != "0":
            return True
        if self.phase == "searching" and len(self.client.diagnostics) % 5 == 1:
            publish_problem(self.client, busy_problem(), stamp_ns=10**9)
        if self.phase == "flood" and self.flood is None:
            self.flooding.set()
            self.flood = threading.Thread(target=self._flood, args=(self._flood_round(),), daemon=True)
            self.flood.start()
        return False

    def _flood_round(self) -> list[tuple[Publisher, Any]]:
        """Publishers and messages of one round: every object's hypotheses and weights (six messages)."""
        assert self.client is not None
        node, problem = self.client.node, load_problem(PROBLEMS / "pyramid.yaml")
        round_ = []
        for name, hypotheses in zip(problem.scene.object_names, problem.hypotheses, strict=True):
            poses, weights = hypotheses_msgs(hypotheses, frame_id=problem.scene.frame_id, stamp_ns=time.time_ns())
            round_.append((node.create_publisher(PoseArray, poses_topic(name), 10), poses))
            round_.append((node.create_publisher(Float64MultiArray, weights_topic(name), 10), weights))
        return round_

    def _flood(self, round_: list[tuple[Publisher, Any]]) -> None:
        """Publish the round at FLOOD_HZ until the run finishes (publishing only: the test's loop spins)."""
        next_round = time.monotonic()
        while self.flooding.is_set():
            for publisher, message in round_:
                publisher.publish(message)
            next_round += 1.0 / FLOOD_HZ
            time.sleep(max(0.0, next_round - time.monotonic()))

    def finish(self) -> tuple[int, str]:
        assert self.node is not None
        try:
            code = self.node.process.wait(timeout=20)
        finally:
            self.node.stop()
            self.flooding.clear()
            if self.flood is not None:
                self.flood.join()
            if self.client is not None:
                self.client.close()
        return code, self.node.output()


def test_every_signal_at_any_moment_stops_the_node_with_exit_code_0_and_no_traceback(tmp_path: Path) -> None:
    rng = random.Random(12)
    runs = [
        Run(index, phase, number, rng.uniform(0.0, LONGEST_WAIT[phase]), tmp_path / f"node{index}.log")
        for index, (phase, number) in enumerate(RUNS)
    ]
    failures = []
    for batch in (runs[i : i + AT_ONCE] for i in range(0, len(runs), AT_ONCE)):
        for run in batch:
            run.start()
        end = time.monotonic() + 60.0
        while any(run.signal_at != float("inf") for run in batch):
            assert time.monotonic() < end, [(run.phase, run.signal_at) for run in batch]
            for run in batch:
                run.advance()
            time.sleep(0.005)
        for run in batch:
            code, output = run.finish()
            noise = [line for line in output.splitlines() if line.strip() and not LOG_LINE.match(line)]
            if code != 0 or noise:
                failures.append(f"{run.phase} {run.number.name} after {run.wait:.3f} s: exit {code}\n{output}")
    assert failures == []


def test_the_entry_points_hold_the_signals_before_any_heavy_import() -> None:
    """numpy starts threads when imported; a thread that does not hold SIGTERM would take it and die of it."""
    probe = (
        "import sys, physics_mapper.cli, physics_mapper.commands.node; "
        "print(sorted(m for m in ('numpy', 'scipy', 'rclpy', 'pybullet', 'yaml') if m in sys.modules))"
    )
    completed = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=60, check=True)
    assert completed.stdout.strip() == "[]"


def test_the_cli_s_interrupted_exit_code_is_the_core_s() -> None:
    """Kept apart so that the entry point imports no numpy before the signals are set up."""
    from physics_mapper import cli
    from physics_mapper.model.errors import EXIT_INTERRUPTED

    assert cli.EXIT_INTERRUPTED == EXIT_INTERRUPTED


def test_ctrl_c_while_a_mesh_loads_is_never_lost(tmp_path: Path) -> None:
    """trimesh swallows KeyboardInterrupt in its import guards and parsers: a signal then must still
    stop ``solve`` (exit 130, no result), whenever it comes: loading, or the long search after it."""
    import trimesh

    trimesh.creation.icosphere(subdivisions=5).apply_scale(0.05).export(tmp_path / "ball.obj")
    names = ("ball_a", "ball_b", "ball_c")
    objects = "".join(f"  - {{name: {name}, shape: mesh, file: ball.obj, mass: 0.1}}\n" for name in names)
    floating = "".join(
        f"  {name}:\n"
        + "".join(f"    - {{position: [{0.2 * i - 0.2:.1f}, 0, {0.2 + 0.01 * k:.2f}]}}\n" for k in range(10))
        for i, name in enumerate(names)
    )
    problem = tmp_path / "problem.yaml"
    problem.write_text(  # the paper's joint search of 1000 floating configurations: busy for seconds
        f"objects:\n{objects}static:\n  - {{name: floor, shape: plane}}\n"
        "search: {deadline: 60.0, settle_exit: full, settle_time: 2.0, strategy: joint, bound: absolute, "
        "probability_threshold: 0.0}\n"
        f"hypotheses:\n{floating}"
    )
    for delay in (0.2, 0.5, 0.8, 1.2, 2.0):
        process = subprocess.Popen(
            [sys.executable, "-m", "physics_mapper", "solve", str(problem)], stdout=subprocess.PIPE, text=True
        )
        time.sleep(delay)  # when the signal comes, not how long anything takes
        process.send_signal(signal.SIGINT)
        out, _ = process.communicate(timeout=60)
        # 130: stopped by the KeyboardInterrupt; -SIGINT: the signal came before Python's handler was set up.
        assert process.returncode in (130, -signal.SIGINT) and out == "", (delay, process.returncode)


def test_ctrl_c_while_an_import_creates_a_dataclass_exits_as_interrupted() -> None:
    """CPython 3.11 re-raises an exception of ``__set_name__`` as a RuntimeError from it: a Ctrl-C that
    lands there (as while ``solve`` imports the search's result types) still exits 130, no traceback."""
    probe = textwrap.dedent(
        """
        import signal, sys
        from physics_mapper import cli

        class Field:
            def __set_name__(self, owner, name):
                signal.raise_signal(signal.SIGINT)

        def command_module(name):
            class Stats:  # created as an import creates a dataclass's fields
                counters = Field()

        cli.command_module = command_module
        sys.exit(cli.main(["solve", "problem.yaml"]))
        """
    )
    completed = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=60)
    assert (completed.returncode, completed.stderr) == (130, "")


def test_stopping_the_node_s_scene_load_does_not_wait_for_a_mesh_parser(tmp_path: Path) -> None:
    """A mesh parser cannot be stopped: cancelling the load leaves it to a daemon thread (the node then
    exits) instead of waiting for every mesh; the thread ends on its own afterwards."""
    import trimesh

    from physics_mapper.model.scene_files import load_scene
    from physics_mapper.model.scene_loading import SceneLoading

    ball = trimesh.creation.icosphere(subdivisions=6).apply_scale(0.05)  # 81,920 faces: a second to parse
    objects = []
    for index in range(4):  # distinct files: each is parsed
        ball.export(tmp_path / f"ball_{index}.obj")
        objects.append(f"  - {{name: ball_{index}, shape: mesh, file: ball_{index}.obj, mass: 0.1}}\n")
    scene = tmp_path / "scene.yaml"
    scene.write_text("static:\n  - {name: floor, shape: plane}\nobjects:\n" + "".join(objects))
    loading = SceneLoading(scene, load_scene)
    assert not loading.wait(0.2)  # parsing the first ball
    assert loading.cancel() is False  # returned while the parser goes on
    assert loading.wait(120.0)  # and that thread ends by itself
