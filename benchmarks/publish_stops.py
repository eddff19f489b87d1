"""How often ``physics-mapper publish`` at a high rate stops badly on SIGTERM (the rare case
test/ros/test_publish_stop.py's six runs seldom reach).

Per run: ``publish`` of the pyramid at 2,000 rounds per second, SIGTERM after a uniformly random 0.05 to
0.5 s, a second SIGTERM 0 to 10 ms later if it is still running. A stop is bad when the exit code is not
0 or stderr holds a traceback (the signal's interrupt landing inside rclpy's executor while it built a
task once left a half-made ``Task`` whose collection printed one). Printed: bad stops of all, and the
first lines of each bad stop's stderr. Run:

    .venv/bin/python benchmarks/publish_stops.py [--runs 120] [--seed 0]
"""

from __future__ import annotations

import argparse
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

PYRAMID = Path(__file__).resolve().parent.parent / "config" / "problems" / "pyramid.yaml"


def stop_once(rng: random.Random) -> tuple[int, str]:
    """One publish stopped by SIGTERM at a random moment: its exit code and stderr."""
    command = [sys.executable, "-m", "physics_mapper", "publish", str(PYRAMID), "--rate", "2000", "--wait", "0"]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert process.stdout is not None
    process.stdout.readline()  # "publishing ...": ROS is up
    time.sleep(rng.uniform(0.05, 0.5))
    process.send_signal(signal.SIGTERM)
    time.sleep(rng.uniform(0.0, 0.01))
    if process.poll() is None:
        process.send_signal(signal.SIGTERM)
    _, stderr = process.communicate(timeout=60)
    return process.returncode, stderr


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=120, help="publish commands stopped (default: 120)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the signals' random times (default: 0)")
    args = parser.parse_args()
    os.environ.setdefault("ROS_DOMAIN_ID", "73")
    rng = random.Random(args.seed)
    bad = 0
    for _ in range(args.runs):
        code, stderr = stop_once(rng)
        if code != 0 or "Traceback" in stderr:
            bad += 1
            print(f"exit {code}: {' | '.join(stderr.strip().splitlines()[:3])}", flush=True)
    print(f"bad stops: {bad} of {args.runs}")


if __name__ == "__main__":
    main()
