"""Cost of the physics checks, and of the persistent world against a world rebuilt per configuration.

Run: ``.venv/bin/python benchmarks/physics_costs.py [--repeats N]``. Prints per-operation
figures measured side by side in one run, and the ratio the persistent world buys.
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable
from pathlib import Path

from physics_mapper.physics import PhysicsChecker
from physics_mapper.scene import load_problem
from physics_mapper.search import BranchAndBound

REPO = Path(__file__).resolve().parent.parent


def median_seconds(action: Callable[[], object], repeats: int) -> float:
    samples = []
    for _ in range(repeats):
        start = time.perf_counter()
        action()
        samples.append(time.perf_counter() - start)
    return statistics.median(samples)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeats", type=int, default=50)
    args = parser.parse_args()
    problem = load_problem(REPO / "config" / "problems" / "pyramid.yaml")
    scene, params = problem.scene, problem.scene.search
    truth = scene.ground_truth
    assert truth is not None

    def fresh_world_check() -> None:
        with PhysicsChecker(scene) as fresh:
            fresh.find_collision(truth, params.penetration_threshold)
            fresh.settle(truth, params.settle_time, params.angular_weight)

    with PhysicsChecker(scene) as checker:
        collision = median_seconds(lambda: checker.find_collision(truth, params.penetration_threshold), args.repeats)
        settle = median_seconds(lambda: checker.settle(truth, params.settle_time, params.angular_weight), args.repeats)
        fresh = median_seconds(fresh_world_check, max(5, args.repeats // 5))
        search = median_seconds(lambda: BranchAndBound(checker, problem.hypotheses, params).run(None), 5)
        result = BranchAndBound(checker, problem.hypotheses, params).run(None)
    persistent = collision + settle
    print(f"scene: pyramid (3 boxes), settle_time {params.settle_time} s, median of {args.repeats} runs")
    print(f"collision check (Rule 1), persistent world : {collision * 1e6:8.1f} us")
    print(f"settle (Rule 2), persistent world          : {settle * 1e3:8.2f} ms")
    print(f"check + settle, persistent world           : {persistent * 1e3:8.2f} ms")
    print(f"check + settle, world rebuilt each time    : {fresh * 1e3:8.2f} ms")
    print(f"persistent world speed-up                  : {fresh / persistent:8.2f} x")
    stats = result.stats
    print(
        f"full search of config/problems/pyramid.yaml : {search * 1e3:8.1f} ms, {stats.visited} visited "
        f"({stats.collisions} collision, {stats.unstable} unstable, {stats.valid} valid), "
        f"{stats.visited / search:.0f} configurations/s"
    )


if __name__ == "__main__":
    main()
