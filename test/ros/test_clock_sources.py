"""Two ``/clock`` sources under ``use_sim_time``: the node names them in a WARN diagnostic and one log line
(its clock jumps between their times, which nothing else would say)."""

from __future__ import annotations

import signal
import subprocess
from pathlib import Path

from builtin_interfaces.msg import Time
from conftest import SCENES
from diagnostic_msgs.msg import DiagnosticStatus
from ros_helpers import PHYSICS_MAPPER, RosClient, search_status
from rosgraph_msgs.msg import Clock

from physics_mapper.mapping.stamps import time_parts

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
