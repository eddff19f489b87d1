"""Interrupted-and-resumed settlings against uninterrupted ones, on every configuration of each shipped problem.

Run: ``.venv/bin/python benchmarks/interrupted_settling.py [--settle-time S]`` (default: each
scene's own). Twin checkers get
the same configurations in the same order; one settles each at once, the other is interrupted at
every look at the clock (every ``CLOCK_CHECK_STEPS`` steps) and resumed, either at once or after
other configurations used its world (one time in ten, seeded). Prints how many settled poses are
bit-identical and the largest difference (metres or quaternion components), beside Bullet's own
limit: uninterrupted settlings in a checker that settled the configurations before, against each
in a fresh world. Then the cost of keeping an interrupted settling when the world is used for
another configuration (a pybullet saveState).
"""

from __future__ import annotations

import argparse
import itertools
import random
import statistics
import time
from collections.abc import Callable
from pathlib import Path

from physics_mapper.model.geometry import Pose
from physics_mapper.model.scene import Problem
from physics_mapper.model.scene_files import load_problem
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.physics.settling import PartialSettling, Settling

PROBLEMS = Path(__file__).resolve().parent.parent / "config" / "problems"
PAST = 0.0  # a time.monotonic() instant long past: every look at the clock interrupts

Configuration = tuple[Pose, ...]
Settler = Callable[[PhysicsChecker, Configuration], Settling]


def configurations(problem: Problem) -> list[Configuration]:
    """Every combination of hypotheses, then the ground truth if the scene has one."""
    ranks = itertools.product(*(range(1, len(h) + 1) for h in problem.hypotheses))
    found = [tuple(h.pose(rank) for h, rank in zip(problem.hypotheses, code, strict=True)) for code in ranks]
    return found + ([problem.scene.ground_truth] if problem.scene.ground_truth else [])


def largest_difference(a: Settling, b: Settling) -> float:
    return max(
        abs(x - y)
        for pose_a, pose_b in zip(a.settled_poses, b.settled_poses, strict=True)
        for x, y in zip(pose_a.position + pose_a.orientation, pose_b.position + pose_b.orientation, strict=True)
    )


def uninterrupted_settler(settle_time: float) -> Settler:
    def settle(checker: PhysicsChecker, poses: Configuration) -> Settling:
        return checker.settle(poses, settle_time, checker.scene.search.angular_weight)

    return settle


def interrupted_settler(settle_time: float, others: list[Configuration], interleave: bool) -> Settler:
    """Settle interrupted at every clock check; if ``interleave``, check other configurations between resumes."""
    rng = random.Random(1)

    def settle(checker: PhysicsChecker, poses: Configuration) -> Settling:
        params = checker.scene.search
        outcome = checker.settle(poses, settle_time, params.angular_weight, PAST)
        while isinstance(outcome, PartialSettling):
            if interleave and rng.random() < 0.1:
                other = rng.choice(others)
                checker.find_collision(other, params.penetration_threshold)
                checker.settle(other, rng.uniform(0.0, settle_time), params.angular_weight)
            outcome = checker.resume_settling(outcome, PAST)
        return outcome

    return settle


def compare(problem: Problem, tested: Settler, reference: Settler, reference_in_fresh_world: bool = False) -> str:
    """Settle every configuration both ways, in twin checkers (or the reference in a fresh world each time)."""
    scene, found = problem.scene, configurations(problem)
    identical, largest = 0, 0.0
    with PhysicsChecker(scene) as reference_checker, PhysicsChecker(scene) as checker:
        for poses in found:
            if reference_in_fresh_world:
                with PhysicsChecker(scene) as fresh:
                    expected = reference(fresh, poses)
            else:
                expected = reference(reference_checker, poses)
            settled = tested(checker, poses)
            identical += settled == expected
            largest = max(largest, largest_difference(settled, expected))
    return f"{identical:3d}/{len(found):3d} identical, largest difference {largest:.1e}"


def save_cost(problem: Problem, repeats: int) -> float:
    """Median seconds a collision check takes longer right after an interruption (it saves that settling)."""
    scene, found = problem.scene, configurations(problem)
    params = scene.search

    def collision_check_seconds(checker: PhysicsChecker, after_interruption: bool) -> float:
        if after_interruption:
            checker.settle(found[0], 1.0, params.angular_weight, PAST)
        start = time.perf_counter()
        checker.find_collision(found[-1], params.penetration_threshold)
        return time.perf_counter() - start

    with PhysicsChecker(scene) as checker:
        kept = statistics.median(collision_check_seconds(checker, True) for _ in range(repeats))
        alone = statistics.median(collision_check_seconds(checker, False) for _ in range(repeats))
    return kept - alone


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--settle-time", type=float, help="simulated seconds (default: each scene's own)")
    parser.add_argument("--repeats", type=int, default=30, help="repeats of the cost measurement (default 30)")
    args = parser.parse_args()
    for name in ("stack", "pyramid", "peg_in_hole", "sphere_groove"):
        problem = load_problem(PROBLEMS / f"{name}.yaml")
        found = configurations(problem)
        settle_time = problem.scene.search.settle_time if args.settle_time is None else args.settle_time
        uninterrupted = uninterrupted_settler(settle_time)
        at_once = interrupted_settler(settle_time, found, interleave=False)
        interleaved = interrupted_settler(settle_time, found, interleave=True)
        print(f"\n{name}: {len(found)} configurations, settle_time {settle_time} s")
        print(f"  resumed at once              : {compare(problem, at_once, uninterrupted)}")
        print(f"  others checked in between    : {compare(problem, interleaved, uninterrupted)}")
        print(f"  uninterrupted, fresh world   : {compare(problem, uninterrupted, uninterrupted, True)}")
        print(f"  saving a kept settling       : {save_cost(problem, args.repeats) * 1e3:.2f} ms")


if __name__ == "__main__":
    main()
