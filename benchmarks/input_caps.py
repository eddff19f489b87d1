"""What each input cap costs at the cap: the measurements behind the caps of ``model/limits.py`` and friends.

Run: ``.venv/bin/python benchmarks/input_caps.py [--objects 64 256]``. Prints, each at its cap:

* grouping 3 overlapping objects x ``MAX_SEARCHED_HYPOTHESES`` hypotheses (the pairwise step the
  cap bounds), and the peak memory it adds;
* loading a ``parts`` file of ``MAX_CONVEX_PARTS`` parts, and an OBJ file of ``MAX_MESH_FACES`` faces;
* the node on a scene of N far-apart cubes (N up to ``MAX_OBJECTS``): seconds from its start to its
  first diagnostics, its RSS then, and seconds from SIGINT to its exit.
"""

from __future__ import annotations

import argparse
import resource
import signal
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import rclpy
import yaml
from diagnostic_msgs.msg import DiagnosticArray
from live_node import isolate_ros, load_average

from physics_mapper.mapping.topics import DIAGNOSTICS_TOPIC
from physics_mapper.model.decomposition import MAX_CONVEX_PARTS, read_parts
from physics_mapper.model.geometry import Pose
from physics_mapper.model.hypotheses import Hypothesis, RankedHypotheses
from physics_mapper.model.limits import MAX_OBJECTS, MAX_SEARCHED_HYPOTHESES
from physics_mapper.model.meshes import MAX_MESH_FACES, MeshRequest, load_mesh_geometry
from physics_mapper.model.scene_files import load_problem
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.ros.child_process import start_node
from physics_mapper.ros.qos import DIAGNOSTICS_QOS
from physics_mapper.search.strategy import make_search

PYRAMID = Path(__file__).resolve().parent.parent / "config" / "problems" / "pyramid.yaml"


def peak_rss_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def hypotheses_at_the_cap() -> None:
    problem = load_problem(PYRAMID)
    assert problem.scene.ground_truth is not None
    rng = np.random.default_rng(0)
    hypotheses = []
    for pose in problem.scene.ground_truth:
        positions = np.asarray(pose.position) + rng.normal(0.0, 0.002, size=(MAX_SEARCHED_HYPOTHESES, 3))
        weights = rng.uniform(0.5, 1.0, size=MAX_SEARCHED_HYPOTHESES)
        hypotheses.append(
            RankedHypotheses.from_weighted(
                [Hypothesis(Pose(tuple(p.tolist())), float(w)) for p, w in zip(positions, weights, strict=True)]
            )
        )
    before = peak_rss_mib()
    with PhysicsChecker(problem.scene) as checker:
        start = time.perf_counter()
        make_search(checker, hypotheses, problem.scene.search)
        grouped = time.perf_counter() - start
    print(
        f"3 objects x {MAX_SEARCHED_HYPOTHESES} hypotheses: grouping {grouped * 1000:.0f} ms, "
        f"peak RSS +{peak_rss_mib() - before:.0f} MiB"
    )


def parts_file_at_the_cap(folder: Path) -> None:
    lines = []
    for index in range(MAX_CONVEX_PARTS):
        base = 4 * index
        lines += [f"o p{index}", f"v {index} 0 0", f"v {index + 0.5} 0 0", f"v {index} 0.5 0", f"v {index} 0 0.5"]
        lines += [f"f {base + a} {base + b} {base + c}" for a, b, c in ((1, 2, 3), (1, 2, 4), (1, 3, 4), (2, 3, 4))]
    path = folder / "parts.obj"
    path.write_text("\n".join(lines) + "\n", encoding="ascii")
    start = time.perf_counter()
    parts = read_parts(path)
    print(f"parts file of {len(parts)} parts: read in {(time.perf_counter() - start) * 1000:.0f} ms")


def mesh_at_the_face_cap(folder: Path) -> None:
    side = int((MAX_MESH_FACES / 2) ** 0.5) - 1  # a grid of side x side squares, two triangles each
    vertices = [f"v {i} {j} {(i * j) % 7 * 0.01}" for i in range(side + 1) for j in range(side + 1)]
    faces = []
    for i in range(side):
        for j in range(side):
            a, b = 1 + i * (side + 1) + j, 1 + (i + 1) * (side + 1) + j
            c, d = b + 1, a + 1
            faces += [f"f {a} {b} {c}", f"f {a} {c} {d}"]
    path = folder / "grid.obj"
    path.write_text("\n".join(vertices + faces) + "\n", encoding="ascii")
    before = peak_rss_mib()
    start = time.perf_counter()
    load_mesh_geometry(MeshRequest(path, mass_properties=False, collision="triangle_mesh"))
    seconds = time.perf_counter() - start
    print(
        f"mesh of {len(faces)} faces, {len(vertices)} vertices ({path.stat().st_size / 2**20:.1f} MiB): "
        f"loaded in {seconds:.2f} s, peak RSS +{peak_rss_mib() - before:.0f} MiB"
    )


def node_at(objects: int, folder: Path) -> None:
    scene = {
        "static": [{"name": "floor", "shape": "plane"}],
        "objects": [{"name": f"cube_{i}", "shape": "box", "size": [0.1, 0.1, 0.1]} for i in range(objects)],
    }
    path = folder / f"scene_{objects}.yaml"
    path.write_text(yaml.safe_dump(scene), encoding="utf-8")
    rclpy.init()
    node = rclpy.create_node("input_caps_probe")
    seen: list[DiagnosticArray] = []
    node.create_subscription(DiagnosticArray, DIAGNOSTICS_TOPIC, seen.append, DIAGNOSTICS_QOS)
    with (folder / "node.log").open("w") as log:
        start = time.monotonic()
        process = start_node(path, output=log)
        while not seen and process.poll() is None and time.monotonic() - start < 600:
            rclpy.spin_once(node, timeout_sec=0.05)
        started = time.monotonic() - start
        rss = int(Path(f"/proc/{process.pid}/status").read_text().split("VmRSS:")[1].split()[0]) / 1024
        signalled = time.monotonic()
        process.send_signal(signal.SIGINT)
        process.wait(timeout=600)
        stopped = time.monotonic() - signalled
    node.destroy_node()  # type: ignore[no-untyped-call]  # rclpy 7 leaves it unannotated
    rclpy.shutdown()
    print(
        f"node, {objects} objects: first diagnostics after {started:.1f} s, RSS {rss:.0f} MiB; "
        f"SIGINT to exit {stopped:.2f} s (exit {process.returncode})"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--objects",
        type=int,
        nargs="+",
        default=[64, MAX_OBJECTS],
        help=f"cubes of the node's scenes (default: 64 {MAX_OBJECTS})",
    )
    args = parser.parse_args()
    isolate_ros()
    print(f"python {sys.version.split()[0]}, load average {load_average()}")
    with tempfile.TemporaryDirectory() as name:
        folder = Path(name)
        hypotheses_at_the_cap()
        parts_file_at_the_cap(folder)
        mesh_at_the_face_cap(folder)
        for count in args.objects:
            node_at(count, folder)


if __name__ == "__main__":
    main()
