"""Cost of simulated perception: particle-filter runs, and a whole ``generate`` of the paper's size.

Run: ``.venv/bin/python benchmarks/hypothesis_generation.py [--repeats N]``. Prints, side by side
for several particle counts, the median seconds of one :func:`physics_mapper.perception.particle_filter.track`
run on the pyramid (3 cubes, 10 iterations) and per object-iteration; then the wall time and bag
size of ``physics-mapper generate`` with the paper's Fig. 6 settings (20 runs, 1000 particles).
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from physics_mapper.cli import main as cli_main
from physics_mapper.model.scene_files import load_scene
from physics_mapper.perception.particle_filter import TrackerSettings, settle_ground_truth, track

REPO = Path(__file__).resolve().parent.parent
SCENE = REPO / "config" / "scenes" / "pyramid.yaml"
PARTICLE_COUNTS = (100, 1000, 10000)


def track_seconds(particles: int, repeats: int) -> float:
    scene = load_scene(SCENE)
    assert scene.ground_truth is not None
    truth = settle_ground_truth(scene, scene.ground_truth)
    settings = TrackerSettings(particles=particles)
    samples = []
    for seed in range(repeats):
        start = time.perf_counter()
        track(scene, truth, settings, np.random.default_rng(seed))
        samples.append(time.perf_counter() - start)
    return statistics.median(samples)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeats", type=int, default=5, help="timed runs per particle count (default: 5)")
    args = parser.parse_args()
    objects, iterations = 3, TrackerSettings().iterations
    print(f"{'particles':>10}  {'s per run':>10}  {'ms per object-iteration':>24}")
    for particles in PARTICLE_COUNTS:
        seconds = track_seconds(particles, args.repeats)
        print(f"{particles:>10}  {seconds:>10.3f}  {seconds / (objects * iterations) * 1000:>24.2f}")
    with tempfile.TemporaryDirectory() as folder:
        bag = Path(folder) / "bag"
        start = time.perf_counter()
        cli_main(["generate", str(SCENE), "-o", str(bag), "--runs", "20", "--sigma", "0.03"])
        seconds = time.perf_counter() - start
        size = sum(f.stat().st_size for f in bag.iterdir())
    print(f"generate, 20 runs x 10 iterations x 1000 particles x 3 cubes: {seconds:.2f} s, bag {size / 1000:.0f} kB")


if __name__ == "__main__":
    main()
