"""The conflict-directed search's Rule 2 verdicts on the shipped mesh scenes, against full settling.

Run: ``.venv/bin/python benchmarks/mesh_verdicts.py [--runs N] [--seed S]`` (about 2 minutes at the
default 5 runs). The clutter experiment's searches (``physics-mapper experiment clutter``: its seeded
particle filter, 10 iterations per run, one search per iteration within the scene's deadline), with
``fallback: settled``: every configuration a search found unstable or valid is settled again for the
whole ``settle_time``, no early exit, in a second world of the same scene. Printed per scene: the
verdicts checked and how many a full settling agrees with. A disagreement is a verdict that an early
exit or a local settling got wrong, or Bullet's contact order, which follows the world's history.
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

from physics_mapper.experiments.clutter import DEFAULT_RUNS, SCENE_FILES, SIGMA_POSITION, SIGMA_ROTATION, timed_search
from physics_mapper.experiments.common import ExperimentOptions, load_experiment_scene
from physics_mapper.experiments.tracking import tracker_settings
from physics_mapper.perception.particle_filter import TrackerSettings, run_generators, settle_ground_truth, track
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.scenarios.crowded_suite import Verdict, settled_verdicts


def scene_verdicts(
    scene_file: str, options: ExperimentOptions, settings: TrackerSettings, runs: int
) -> dict[Verdict, tuple[int, int]]:
    """(verdicts, agreeing with a full settling) per verdict over every search of one scene."""
    scene, truth = load_experiment_scene(options, scene_file)
    truth = settle_ground_truth(scene, truth)
    params = replace(scene.search, fallback="settled")
    totals: dict[Verdict, tuple[int, int]] = {"unstable": (0, 0), "valid": (0, 0)}
    with PhysicsChecker(scene) as checker, PhysicsChecker(scene) as full:
        for rng in run_generators(options.seed, runs):
            for hypotheses in track(scene, truth, settings, rng):
                result = timed_search(checker, hypotheses, params, params.deadline).result
                for verdict, (checked, agreed) in settled_verdicts(full, hypotheses, params, result).items():
                    total_checked, total_agreed = totals[verdict]
                    totals[verdict] = total_checked + checked, total_agreed + agreed
    return totals


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument(
        "--runs", type=int, default=DEFAULT_RUNS, help=f"clutter runs per scene (default: {DEFAULT_RUNS})"
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of the particle filter (default: 0)")
    args = parser.parse_args()
    options = ExperimentOptions(output_dir=Path("."), seed=args.seed)  # writes nothing
    settings = tracker_settings(options, SIGMA_POSITION, SIGMA_ROTATION)
    print("scene            unstable verdicts confirmed   valid verdicts confirmed")
    for scene_file in SCENE_FILES:
        totals = scene_verdicts(scene_file, options, settings, args.runs)
        unstable, valid = totals["unstable"], totals["valid"]
        print(f"{scene_file:16} {unstable[1]:>14} of {unstable[0]:<10} {valid[1]:>13} of {valid[0]}", flush=True)


if __name__ == "__main__":
    main()
