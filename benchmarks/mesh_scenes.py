"""The shipped mesh scenes with ``fallback: settled``: a valid map at the tick, the tick scaled to this machine.

The clutter experiment's searches (``physics-mapper experiment clutter``: its seeded particle filter around each
scene's settled truth, 10 iterations per run, one search per iteration) on ``tabletop``, ``tray_pile`` and
``jenga_tower`` with ``fallback: settled``. Each search runs afresh in slices of :data:`SLICE` seconds until its
result is valid, the search ends or ``--budget`` seconds pass; its *time to a valid map* counts building the
search and searching, not assembling results between slices (as ``crowded.py``'s time to the answer).

Targets that travel: a reference settling (``crowded.py``'s :class:`ReferenceSettling`, the stack's Rule 2) is
measured just before and just after each search, and the search is judged against the scene's tick (its
``deadline``, 0.4 s in the three scenes) scaled to the machine as it ran: tick x reference / 6.3 ms. Printed per
scene: the searches, those with a valid map within ``--budget`` (*have one*), within the tick as a fixed wall
clock, and within the scaled tick; and the references' median and range. The target: a valid map at the scaled
tick in every search that has one.

Run: ``.venv/bin/python benchmarks/mesh_scenes.py [--runs N] [--seed S] [--budget SECONDS]``, or
``physics-mapper bench mesh_scenes`` with the same options (40 s at the default 5 runs and 4 s on the machine of
BENCHMARKS.md's round). Progress goes to stderr.
"""

from __future__ import annotations

import argparse
import statistics
import sys
from dataclasses import dataclass, replace
from functools import partial
from pathlib import Path

from crowded import REFERENCE_SETTLING, ReferenceSettling, beside_reference, scaled_deadline

from physics_mapper.experiments.clutter import DEFAULT_RUNS, SCENE_FILES, SIGMA_POSITION, SIGMA_ROTATION
from physics_mapper.experiments.common import ExperimentOptions, load_experiment_scene
from physics_mapper.experiments.tracking import tracker_settings
from physics_mapper.perception.particle_filter import TrackerSettings, run_generators, settle_ground_truth, track
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.scenarios.problems import search_until
from physics_mapper.search.results import SearchResult

#: Seconds a search runs between two looks at its result (1 ms: the time to a valid map within a millisecond).
SLICE = 0.001
#: Seconds a search may take to find a valid map, unless ``--budget`` says otherwise.
BUDGET = 4.0


@dataclass(frozen=True)
class TimedValid:
    """One search: seconds to its first valid map (None: not within the budget), the reference beside it (s), and
    which search of its scene it is (``run 2 iteration 3``, both from 1)."""

    seconds: float | None
    reference: float
    search: str

    def late(self, tick: float) -> bool:
        """Whether its valid map came after ``tick`` seconds scaled to its reference (False: none came at all)."""
        return self.seconds is not None and self.seconds > scaled_deadline(self.reference, tick)


def _is_valid(result: SearchResult) -> bool:
    return result.valid


def scene_searches(
    scene_file: str,
    options: ExperimentOptions,
    settings: TrackerSettings,
    reference: ReferenceSettling,
    runs: int,
    budget: float,
) -> tuple[float, list[TimedValid]]:
    """The scene's tick (s) and every search of the scene, each timed to its first valid map beside the reference."""
    scene, truth = load_experiment_scene(options, scene_file)
    truth = settle_ground_truth(scene, truth)
    params = replace(scene.search, fallback="settled")
    searches: list[TimedValid] = []
    with PhysicsChecker(scene) as checker:
        for run, rng in enumerate(run_generators(options.seed, runs)):
            print(f"mesh scenes: {scene_file} run {run + 1}/{runs}", file=sys.stderr, flush=True)
            for iteration, hypotheses in enumerate(track(scene, truth, settings, rng)):
                (seconds, _, _), beside = beside_reference(
                    reference, partial(search_until, checker, hypotheses, params, _is_valid, SLICE, budget)
                )
                searches.append(TimedValid(seconds, beside, f"run {run + 1} iteration {iteration + 1}"))
    return scene.search.deadline, searches


def counts(tick: float, searches: list[TimedValid]) -> tuple[int, int, int, int]:
    """(searches, those with a valid map within the budget, within ``tick`` seconds, within ``tick`` scaled to the
    reference beside each search: tick x reference / 6.3 ms)."""
    have = [s for s in searches if s.seconds is not None]
    fixed = sum(1 for s in have if s.seconds is not None and s.seconds <= tick)
    return len(searches), len(have), fixed, sum(1 for s in have if not s.late(tick))


def late(tick: float, searches: list[TimedValid]) -> list[str]:
    """The searches with a valid map within the budget but not within the scaled tick: which, when (ms) and the
    scaled tick (ms)."""
    return [
        f"{s.search} ({s.seconds * 1000:.0f} ms / {scaled_deadline(s.reference, tick) * 1000:.0f} ms)"
        for s in searches
        if s.seconds is not None and s.late(tick)
    ]


def scene_row(scene_file: str, tick: float, searches: list[TimedValid]) -> tuple[int, int, int, int]:
    """Print one scene's line, and the searches it has late; return its :func:`counts`."""
    row = counts(tick, searches)
    references = [s.reference * 1000 for s in searches]
    print(
        f"{scene_file:16} {row[0]:>8} {row[1]:>8} {row[2]:>11} {row[3]:>12}   "
        f"{statistics.median(references):.1f} ms, {min(references):.1f}-{max(references):.1f} ms",
        flush=True,
    )
    for search in late(tick, searches):
        print(f"{'':16} a valid map after the scaled tick: {search}")
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--runs", type=int, default=DEFAULT_RUNS, help=f"runs per scene (default {DEFAULT_RUNS})")
    parser.add_argument("--seed", type=int, default=0, help="the particle filters' seed (default 0)")
    parser.add_argument(
        "--budget", type=float, default=BUDGET, help=f"seconds a search may take to a valid map (default {BUDGET:g})"
    )
    args = parser.parse_args()
    if args.runs < 1 or not args.budget > 0.0:
        parser.error(f"--runs must be at least 1 and --budget positive (got {args.runs} and {args.budget:g})")
    options = ExperimentOptions(output_dir=Path("."), seed=args.seed)  # writes nothing
    settings = tracker_settings(options, SIGMA_POSITION, SIGMA_ROTATION)
    print(f"a valid map within {args.budget:g} s (have one), within the scene's tick, and within that tick scaled")
    print(f"by the reference beside each search / {REFERENCE_SETTLING * 1000:.1f} ms")
    print("scene            searches have one  fixed tick  scaled tick   reference beside the searches")
    totals = [0, 0, 0, 0]
    with ReferenceSettling() as reference:
        for scene_file in SCENE_FILES:
            tick, searches = scene_searches(scene_file, options, settings, reference, args.runs, args.budget)
            totals = [t + n for t, n in zip(totals, scene_row(scene_file, tick, searches), strict=True)]
    count, have, fixed, scaled = totals
    print(f"{'all':16} {count:>8} {have:>8} {fixed:>11} {scaled:>12}")
    verdict = "met" if scaled == have else "missed"
    print(f"target, a valid map at the scaled tick in every search that has one: {scaled} of {have} ({verdict})")


if __name__ == "__main__":
    main()
