"""``publish`` at a high rate stops on SIGTERM with exit 0 and no traceback, wherever the signal lands (in a
publish, in the executor's wait, in the shutdown), and a second SIGTERM soon after (a supervisor's
repeat, a process group's signal) neither breaks the shutdown nor kills the exiting process: ROS is
shut down once, by the command."""

from __future__ import annotations

import signal
import subprocess
import time

from conftest import PROBLEMS
from ros_helpers import PHYSICS_MAPPER

RUNS = 6


def test_sigterm_during_a_fast_publish_is_exit_0_without_traceback() -> None:
    command = [str(PHYSICS_MAPPER), "publish", str(PROBLEMS / "pyramid.yaml"), "--rate", "2000", "--wait", "0"]
    for run in range(RUNS):
        process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        assert process.stdout is not None
        assert process.stdout.readline().startswith("publishing ")
        time.sleep(0.2 + 0.05 * run)  # into the rounds, at a different phase each run (not an assertion)
        process.send_signal(signal.SIGTERM)
        time.sleep(0.003)  # the second lands in the stop: the shutdown, or the interpreter's exit
        if process.poll() is None:
            process.send_signal(signal.SIGTERM)
        _, stderr = process.communicate(timeout=60)
        assert process.returncode == 0 and "Traceback" not in stderr, (process.returncode, stderr)
