"""How fast the node and ``solve`` stop on SIGINT while they parse a large mesh (trimesh, which cannot be interrupted).

Run: ``.venv/bin/python benchmarks/mesh_load_stop.py``. The scene holds one 81,920-face ball (about a
second to parse, under the 200,000-face cap). Each command is started afresh and signalled after a
delay from 1.0 to 2.6 s (before, during and after the parse, which follows the imports); printed:
the seconds from the signal to the exit, per delay, and their median and maximum. The node loads in a
thread and leaves the parser to it when stopped; ``solve`` parses in its main thread, which holds
the signal until trimesh returns (``model/interrupts.py``).
"""

from __future__ import annotations

import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import trimesh
import yaml

PHYSICS_MAPPER = Path(sys.executable).parent / "physics-mapper"
DELAYS = (1.0, 1.2, 1.4, 1.6, 1.8, 2.0, 2.2, 2.4, 2.6)


def stop_after(command: list[str], delay: float) -> float:
    """Seconds from SIGINT, sent ``delay`` s after ``command`` started, to its exit."""
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    time.sleep(delay)
    start = time.monotonic()
    process.send_signal(signal.SIGINT)
    process.wait()
    return time.monotonic() - start


def main() -> None:
    os.environ.setdefault("ROS_DOMAIN_ID", "91")
    with tempfile.TemporaryDirectory() as name:
        folder = Path(name)
        trimesh.creation.icosphere(subdivisions=6, radius=0.05).export(folder / "ball.obj")
        ball = {"name": "ball", "shape": "mesh", "file": "ball.obj", "mass": 0.1}
        scene = {"static": [{"name": "floor", "shape": "plane"}], "objects": [ball]}
        (folder / "scene.yaml").write_text(yaml.safe_dump(scene), encoding="utf-8")
        problem = {**scene, "hypotheses": {"ball": [{"position": [0.0, 0.0, 0.05], "weight": 1.0}]}}
        (folder / "problem.yaml").write_text(yaml.safe_dump(problem), encoding="utf-8")
        commands = {
            "node": [str(PHYSICS_MAPPER), "node", "--ros-args", "-p", f"scene_file:={folder / 'scene.yaml'}"],
            "solve": [str(PHYSICS_MAPPER), "solve", str(folder / "problem.yaml")],
        }
        for label, command in commands.items():
            seconds = [stop_after(command, delay) for delay in DELAYS]
            listed = ", ".join(f"{s:.2f}" for s in seconds)
            print(f"{label}: {listed} s; median {statistics.median(seconds):.2f} s, max {max(seconds):.2f} s")


if __name__ == "__main__":
    main()
