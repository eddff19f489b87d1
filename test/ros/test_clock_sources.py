"""Two ``/clock`` sources under ``use_sim_time``: the node names them in a WARN diagnostic and one log line
(its clock jumps between their times, which nothing else would say), and meanwhile ticks by wall clock
at its rate, its inputs aged by no jump."""

from __future__ import annotations

import signal
import subprocess
import time
from pathlib import Path

from builtin_interfaces.msg import Time
from conftest import PROBLEMS, SCENES
from diagnostic_msgs.msg import DiagnosticStatus
from ros_helpers import PHYSICS_MAPPER, NodeProcess, RosClient, object_status, search_status, values
from rosgraph_msgs.msg import Clock

from physics_mapper.mapping.stamps import time_parts
from physics_mapper.model.scene_files import load_problem
from physics_mapper.msg_adapters.hypotheses import hypotheses_msgs

NAMESPACE = "/two_clocks"
TEXT = "use_sim_time is true and 2 publishers are on /clock"


def test_two_clock_publishers_are_a_warn_diagnostic_and_a_log_line(tmp_path: Path) -> None:
    command = [str(PHYSICS_MAPPER), "node", "--ros-args", "-p", f"scene_file:={SCENES / 'pyramid.yaml'}"]
    command += ["-p", "use_sim_time:=true", "-r", f"__ns:={NAMESPACE}"]
    log = tmp_path / "node.log"
    with log.open("w") as output:
        process = subprocess.Popen(command, stdout=output, stderr=subprocess.STDOUT, text=True)
    client = RosClient(NAMESPACE)
    try:
        sources = [client.node.create_publisher(Clock, "/clock", 10) for _ in range(2)]
        ticks = [0]

        def publish() -> None:  # one source at 1000 s and on, the other at 500 s and on
            ticks[0] += 1
            for source, start in zip(sources, (1000, 500), strict=True):
                sec, nanosec = time_parts((start + ticks[0]) * 1_000_000_000)
                source.publish(Clock(clock=Time(sec=sec, nanosec=nanosec)))

        def warned() -> bool:
            status = search_status(client.diagnostics[-1]) if client.diagnostics else None
            return status is not None and status.level[0] >= DiagnosticStatus.WARN[0] and TEXT in status.message

        client.keep_publishing(publish, warned, "the two clocks' warning")
    finally:
        client.close()
        process.send_signal(signal.SIGINT)
        code = process.wait(timeout=30)
    text = log.read_text(encoding="utf-8")
    warnings = [line for line in text.splitlines() if line.startswith("[WARN]") and TEXT in line]
    assert code == 0 and len(warnings) == 1, text  # logged once, when it starts


#: Seconds between two clock messages, of each source in turn (jumps at 15 Hz, as the ticks fired).
CLOCK_PERIOD = 1.0 / 15.0
RATE_HZ = 2.0
#: Clock messages counted after the warning (8 s), and maps the node must publish meanwhile.
COUNTED = 120
MAPS = 6
#: Clock messages at most before giving up on the warning.
MAX_ROUNDS = 600
#: Ticks allowed beyond the sim-time periods: the last diagnostics before the count may lag the ticks.
TICK_MARGIN = 3


def test_under_two_clocks_the_node_ticks_at_its_rate_and_its_inputs_stay_fresh(tmp_path: Path) -> None:
    namespace = "/two_clocks_ticking"
    parameters = {"use_sim_time": True, "rate_hz": RATE_HZ, "deadline": 0.2, "max_age": 5.0, "diagnostics_period": 0.5}
    node = NodeProcess(SCENES / "pyramid.yaml", parameters, tmp_path / "node.log", namespace)
    client = RosClient(namespace)
    problem = load_problem(PROBLEMS / "pyramid.yaml")
    try:
        sources = [client.node.create_publisher(Clock, "/clock", 10) for _ in range(2)]
        starts = (1000.0, 500.0)
        elapsed = [0.0]  # seconds each source has advanced: the wall time of the run (simulators at real time)
        rounds = [0]

        def publish() -> None:
            before = time.monotonic()
            source = rounds[0] % 2  # in turn, as two simulators' clocks interleave
            sec, nanosec = time_parts(round((starts[source] + elapsed[0]) * 1e9))
            sources[source].publish(Clock(clock=Time(sec=sec, nanosec=nanosec)))
            if rounds[0] % 8 == 0:
                for name, hypotheses in zip(problem.scene.object_names, problem.hypotheses, strict=True):
                    messages = hypotheses_msgs(hypotheses, frame_id=problem.scene.frame_id, stamp_ns=rounds[0] + 1)
                    client.publish(name, *messages)
            client.spin_until(lambda: False, timeout=CLOCK_PERIOD)
            rounds[0] += 1
            elapsed[0] += time.monotonic() - before

        def warned() -> bool:
            status = search_status(client.diagnostics[-1]) if client.diagnostics else None
            return status is not None and TEXT in status.message

        while not warned():
            assert rounds[0] < MAX_ROUNDS, "no warning of the two clocks"
            publish()
        first, span_start, maps = client.diagnostics[-1], elapsed[0], len(client.configurations)
        for _ in range(COUNTED):
            publish()
        assert len(client.configurations) >= maps + MAPS, f"{len(client.configurations) - maps} maps under two clocks"
        last = client.diagnostics[-1]
        span = elapsed[0] - span_start  # each source's sim time over the counted part of the run
    finally:
        client.close()
        code = node.stop()
    assert code == 0, node.output()
    ticks = int(values(search_status(last) or DiagnosticStatus())["ticks"])
    ticks -= int(values(search_status(first) or DiagnosticStatus())["ticks"])
    # At most one tick per forward period of 1/rate_hz of a source's time, not one per jump.
    assert ticks <= RATE_HZ * span + TICK_MARGIN, (ticks, span)
    for name in problem.scene.object_names:
        assert "stale" not in object_status(last, name).message, object_status(last, name).message
