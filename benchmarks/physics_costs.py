"""What the physics checks cost on a problem, measured side by side in one process.

The search's time goes almost entirely into Rule 2 (simulating ``settle_time`` seconds); Rule 1
is a single collision pass. Also measured: the same check in a world rebuilt per configuration,
which the persistent :class:`~physics_mapper.physics.checker.PhysicsChecker` avoids, and a whole search.
All figures are medians of wall-clock time (seconds).

Run: ``physics-mapper bench physics_costs [PROBLEM ...] [--repeats N]`` (default: the shipped
``config/problems/pyramid.yaml``, found installed or in the checkout from any working directory);
BENCHMARKS.md's figures are those of the four shipped problems ``stack``, ``pyramid``,
``peg_in_hole`` and ``sphere_groove``.
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from physics_mapper.commands.files import load_problem_file
from physics_mapper.model.errors import InputError
from physics_mapper.model.geometry import Pose
from physics_mapper.model.scene import Problem
from physics_mapper.model.shipped import shipped_path
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.search.results import SearchStats
from physics_mapper.search.strategy import make_search


@dataclass(frozen=True)
class PhysicsCosts:
    """Median seconds per operation, and the statistics of one exhaustive search."""

    collision_check: float
    settle: float
    rebuilt_world_check: float
    search: float
    search_stats: SearchStats

    @property
    def persistent_world_check(self) -> float:
        """Rule 1 + Rule 2 in the persistent world, seconds."""
        return self.collision_check + self.settle

    @property
    def rebuild_ratio(self) -> float:
        """How many times longer a configuration takes in a world rebuilt for it."""
        return self.rebuilt_world_check / self.persistent_world_check


def median_seconds(action: Callable[[], object], repeats: int) -> float:
    """Median wall-clock seconds of ``repeats`` calls of ``action``."""
    samples = []
    for _ in range(repeats):
        start = time.perf_counter()
        action()
        samples.append(time.perf_counter() - start)
    return statistics.median(samples)


def measure(problem: Problem, repeats: int = 50) -> PhysicsCosts:
    """Time Rule 1, Rule 2, a rebuilt-world check and a whole search on ``problem``.

    The configuration checked is the scene's ground truth if it has one, else C11..1.
    """
    scene, params = problem.scene, problem.scene.search
    poses: Sequence[Pose] = scene.ground_truth or tuple(h.pose(1) for h in problem.hypotheses)

    def rebuilt_world_check() -> None:
        with PhysicsChecker(scene) as fresh:
            fresh.find_collision(poses, params.penetration_threshold)
            fresh.settle(poses, params.settle_time, params.angular_weight)

    searches: list[SearchStats] = []

    def search() -> None:
        searches.append(make_search(checker, problem.hypotheses, params).run(None).stats)

    with PhysicsChecker(scene) as checker:
        return PhysicsCosts(
            collision_check=median_seconds(
                lambda: checker.find_collision(poses, params.penetration_threshold), repeats
            ),
            settle=median_seconds(lambda: checker.settle(poses, params.settle_time, params.angular_weight), repeats),
            rebuilt_world_check=median_seconds(rebuilt_world_check, max(5, repeats // 5)),
            search=median_seconds(search, max(3, repeats // 10)),
            search_stats=searches[-1],
        )


def costs_text(costs: PhysicsCosts) -> str:
    """The figures as aligned lines, for people."""
    stats = costs.search_stats
    return "\n".join(
        [
            f"collision check (Rule 1), persistent world : {costs.collision_check * 1e6:9.1f} us",
            f"settle (Rule 2), persistent world          : {costs.settle * 1e3:9.2f} ms",
            f"check + settle, persistent world           : {costs.persistent_world_check * 1e3:9.2f} ms",
            f"check + settle, world rebuilt each time    : {costs.rebuilt_world_check * 1e3:9.2f} ms",
            f"persistent world speed-up                  : {costs.rebuild_ratio:9.2f} x",
            f"exhaustive search                          : {costs.search * 1e3:9.1f} ms, {stats.visited} visited "
            f"({stats.collisions} collision, {stats.unstable} unstable, {stats.valid} valid), "
            f"{stats.visited / costs.search:.0f} configurations/s",
        ]
    )


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="physics-mapper bench physics_costs", description=__doc__)
    parser.add_argument("problems", type=Path, nargs="*", help="problem YAML (default: config/problems/pyramid.yaml)")
    parser.add_argument("--repeats", type=int, default=50, help="timed repetitions per figure (default: 50)")
    args = parser.parse_args(argv)
    if args.repeats < 1:
        raise InputError(f"--repeats must be at least 1, got {args.repeats}")
    for path in args.problems or [shipped_path("config/problems/pyramid.yaml")]:
        problem = load_problem_file(path, "bench")
        scene = problem.scene
        print(
            f"{path}: {len(scene.objects)} objects, {len(scene.static)} static bodies, "
            f"settle_time {scene.search.settle_time} s; medians of {args.repeats} runs"
        )
        print(costs_text(measure(problem, args.repeats)))


if __name__ == "__main__":
    main()
