"""What ``fallback: refine`` costs, against one Rule 2 settling of the same scene, from 3 to 50 objects.

Run: ``.venv/bin/python benchmarks/refine_cost.py [--repeats N] [--seed S]``. The scene is a grid of
10 cm cubes on a floor, touching their neighbours; each cube's one hypothesis is its true pose
moved by Gaussian noise (1 cm per axis, seeded), so neighbours overlap and some cubes are sunk
into the floor or float. Printed per size: the refinement's median wall-clock time (start,
depenetration, settling), its depenetration iterations and the deepest overlap it resolved, one
settling of the same poses (``settle_time`` 0.5 s, what the search spends per collision-free
configuration) timed side by side, and their ratio; then how far the map lies from the map the
same refinement makes with Rule 2's solver iterations (:data:`SOLVER_ITERATIONS`, pybullet's 50)
instead of its own (:data:`SETTLING_SOLVER_ITERATIONS`), and that refinement's time: the largest
and the median J-distance between one object's two map poses, mm (m + 0.1 m per rad).
"""

from __future__ import annotations

import argparse
import math

import numpy as np
from physics_costs import median_seconds

from physics_mapper.model.geometry import Pose, pose_displacement
from physics_mapper.model.hypotheses import Hypothesis, RankedHypotheses
from physics_mapper.model.scene import Box, ObjectModel, Plane, Scene, SearchParams, StaticBody
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.physics.refine import SETTLING_SOLVER_ITERATIONS, RefinedMap, refine_objects
from physics_mapper.physics.world import SOLVER_ITERATIONS

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
    stiff: list[RefinedMap] = []
    with PhysicsChecker(scene) as checker:
        objects = range(count)
        refine_time = median_seconds(lambda: maps.append(refine_objects(checker, objects, hypotheses, PARAMS)), repeats)
        settle_time = median_seconds(lambda: checker.settle(poses, PARAMS.settle_time, PARAMS.angular_weight), repeats)
        stiff_time = median_seconds(
            lambda: stiff.append(refine_objects(checker, objects, hypotheses, PARAMS, SOLVER_ITERATIONS)), repeats
        )
    last = maps[-1]
    apart = [
        pose_displacement(a, b, PARAMS.angular_weight)
        for a, b in zip(last.settled_poses, stiff[-1].settled_poses, strict=True)
    ]
    return (
        f"{count:7d}  {refine_time * 1e3:11.1f}  {last.iterations:10d}  {last.initial_overlap * 100:20.2f}  "
        f"{last.converged!s:>9}  {settle_time * 1e3:11.1f}  {refine_time / settle_time:15.2f}  "
        f"{stiff_time * 1e3:14.1f}  {max(apart) * 1e3:13.2f}  {float(np.median(apart)) * 1e3:16.2f}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeats", type=int, default=10, help="timed refinements per size (default: 10)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the cubes' noise (default: 0)")
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    print(
        "objects  refine [ms]  iterations  deepest overlap [cm]  converged  settle [ms]  refine / settle  "
        f"{SOLVER_ITERATIONS}-iter. [ms]  apart max [mm]  apart median [mm]"
    )
    print(f"(the refinement's settling: {SETTLING_SOLVER_ITERATIONS} solver iterations per step)")
    for count in SIZES:
        print(measure(count, rng, args.repeats))


if __name__ == "__main__":
    main()
