"""What ``fallback: refine`` costs, against one Rule 2 settling of the same scene, from 3 to 50 objects.

Run: ``.venv/bin/python benchmarks/refine_cost.py [--repeats N] [--seed S]``. The scene is a grid of
10 cm cubes on a floor, touching their neighbours; each cube's one hypothesis is its true pose
moved by Gaussian noise (1 cm per axis, seeded), so neighbours overlap and some cubes are sunk
into the floor or float. Printed per size: the refinement's median wall-clock time (start,
depenetration, settling), its depenetration iterations and the deepest overlap it resolved, one
settling of the same poses (``settle_time`` 0.5 s, what the search spends per collision-free
configuration) timed side by side, and their ratio.
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from physics_mapper.bench.physics_costs import median_seconds
from physics_mapper.model.geometry import Pose
from physics_mapper.model.hypotheses import Hypothesis, RankedHypotheses
from physics_mapper.model.scene import Box, ObjectModel, Plane, Scene, SearchParams, StaticBody
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.physics.refine import RefinedMap, refine_objects

SIZES = (3, 10, 25, 50)
EDGE = 0.1  # metres
NOISE = 0.01  # metres per axis
PARAMS = SearchParams(fallback="refine")


def grid_problem(count: int, rng: np.random.Generator) -> tuple[Scene, tuple[RankedHypotheses, ...]]:
    """``count`` cubes in a square grid on the floor, touching, each with one noisy hypothesis."""
    side = math.ceil(math.sqrt(count))
    objects = tuple(ObjectModel(f"cube_{i}", Box((EDGE, EDGE, EDGE)), mass=0.3) for i in range(count))
    scene = Scene(objects=objects, static=(StaticBody("floor", Plane()),))
    hypotheses = []
    for index in range(count):
        x, y, z = (index % side) * EDGE, (index // side) * EDGE, EDGE / 2.0
        dx, dy, dz = rng.normal(0.0, NOISE, 3)
        pose = Pose((float(x + dx), float(y + dy), float(z + dz)))
        hypotheses.append(RankedHypotheses.from_weighted([Hypothesis(pose, 1.0)]))
    return scene, tuple(hypotheses)


def measure(count: int, rng: np.random.Generator, repeats: int) -> str:
    """One table row: the refinement of a ``count``-cube grid and one settling of it, timed side by side."""
    scene, hypotheses = grid_problem(count, rng)
    poses = [h.pose(1) for h in hypotheses]
    maps: list[RefinedMap] = []
    with PhysicsChecker(scene) as checker:
        objects = range(count)
        refine_time = median_seconds(lambda: maps.append(refine_objects(checker, objects, hypotheses, PARAMS)), repeats)
        settle_time = median_seconds(lambda: checker.settle(poses, PARAMS.settle_time, PARAMS.angular_weight), repeats)
    last = maps[-1]
    return (
        f"{count:7d}  {refine_time * 1e3:11.1f}  {last.iterations:10d}  {last.initial_overlap * 100:20.2f}  "
        f"{last.converged!s:>9}  {settle_time * 1e3:11.1f}  {refine_time / settle_time:15.2f}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeats", type=int, default=10)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    print("objects  refine [ms]  iterations  deepest overlap [cm]  converged  settle [ms]  refine / settle")
    for count in SIZES:
        print(measure(count, rng, args.repeats))


if __name__ == "__main__":
    main()
