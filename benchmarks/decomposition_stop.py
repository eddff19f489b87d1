"""How fast a runaway decomposition stops: SIGINT or SIGTERM to ``solve`` and to the node while V-HACD runs.

Run: ``.venv/bin/python benchmarks/decomposition_stop.py [--runs 5]``. The mesh is a 10 x 10 x 0.1 cm
plate, which V-HACD never finishes (it grows until the decomposition's memory limit ends it). Each run
starts the command with an empty cache, waits for its "decomposing" line and a further random 0-3 s,
sends the signal and measures the seconds until the process has exited (median / max), with the exit
codes. Also prints how long the plate takes to hit the default memory limit, and the cost a
decomposition pays for its child process (V-HACD on a small trough, with and without the child).
"""

from __future__ import annotations

import argparse
import os
import random
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import trimesh
import yaml

from physics_mapper.model.decomposition import DecompositionSettings, run_method

PHYSICS_MAPPER = Path(sys.executable).parent / "physics-mapper"
PLATE = {"name": "plate", "shape": "mesh", "file": "plate.obj", "collision": "decomposition", "mass": 0.1}


def prepare(folder: Path) -> None:
    trimesh.creation.box((0.1, 0.1, 0.001)).export(folder / "plate.obj")
    body = {**PLATE, "decomposition": {"method": "vhacd"}}
    scene = {"static": [{"name": "floor", "shape": "plane"}], "objects": [body]}
    (folder / "scene.yaml").write_text(yaml.safe_dump(scene), encoding="utf-8")
    problem = {**scene, "hypotheses": {"plate": [{"position": [0.0, 0.0, 0.001], "weight": 1.0}]}}
    (folder / "problem.yaml").write_text(yaml.safe_dump(problem), encoding="utf-8")


def stop_once(command: list[str], folder: Path, stop_signal: int, rng: random.Random) -> tuple[float, int]:
    environment = {**os.environ, "PHYSICS_MAPPER_CACHE_DIR": tempfile.mkdtemp(dir=folder)}
    process = subprocess.Popen(
        command, cwd=folder, env=environment, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
    )
    assert process.stdout is not None
    for line in process.stdout:
        if "decomposing" in line:
            break
    time.sleep(rng.uniform(0.0, 3.0))
    start = time.monotonic()
    process.send_signal(stop_signal)
    process.communicate()
    return time.monotonic() - start, process.returncode


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5, help="stops per command and signal (default: 5)")
    args = parser.parse_args()
    rng = random.Random(0)
    with tempfile.TemporaryDirectory() as name:
        folder = Path(name)
        prepare(folder)
        commands = {
            "solve": [str(PHYSICS_MAPPER), "solve", "problem.yaml"],
            "node": [str(PHYSICS_MAPPER), "node", "--ros-args", "-p", f"scene_file:={folder / 'scene.yaml'}"],
        }
        for label, command in commands.items():
            for stop_signal in (signal.SIGINT, signal.SIGTERM):
                runs = [stop_once(command, folder, stop_signal, rng) for _ in range(args.runs)]
                seconds = [s for s, _ in runs]
                name = signal.Signals(stop_signal).name
                print(
                    f"{label}, {name}: stopped in {statistics.median(seconds):.2f} s median, "
                    f"{max(seconds):.2f} s max; exit codes {sorted({code for _, code in runs})}"
                )
        start = time.monotonic()
        environment = {**os.environ, "PHYSICS_MAPPER_CACHE_DIR": tempfile.mkdtemp(dir=folder)}
        completed = subprocess.run(
            commands["solve"], cwd=folder, env=environment, capture_output=True, text=True, check=False
        )
        print(
            f"solve, no signal: exit {completed.returncode} after {time.monotonic() - start:.1f} s: "
            f"{completed.stderr.strip().splitlines()[-1][-110:]}"
        )
    trough = trimesh.creation.annulus(0.03, 0.05, 0.04)
    vertices, faces = np.asarray(trough.vertices), np.asarray(trough.faces)
    settings = DecompositionSettings("vhacd")
    with tempfile.TemporaryDirectory() as scratch:
        start = time.monotonic()
        run_method(vertices, faces, settings, Path(scratch))
        inside = time.monotonic() - start
    from physics_mapper.model.decomposition import _in_child_process

    start = time.monotonic()
    _in_child_process(Path("annulus.obj"), vertices, faces, settings)
    child = time.monotonic() - start
    print(f"V-HACD of a small annulus: {inside:.2f} s in this process, {child:.2f} s in a child process")


if __name__ == "__main__":
    main()
