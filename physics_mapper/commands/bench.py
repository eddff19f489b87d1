"""``physics-mapper bench``: what the physics checks and the search cost on a problem, on this machine."""

from __future__ import annotations

import argparse
from pathlib import Path

from physics_mapper.commands.files import load_problem_file
from physics_mapper.core.errors import InputError
from physics_mapper.core.shipped import shipped_path

HELP = "time the physics checks (Rule 1, Rule 2, rebuilt world) and an exhaustive search on a problem file"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "problem",
        type=Path,
        nargs="?",
        help="problem YAML (default: the shipped config/problems/pyramid.yaml)",
    )
    parser.add_argument("--repeats", type=int, default=50, help="timed repetitions per figure (default: 50)")


def run(args: argparse.Namespace) -> int:
    if args.repeats < 1:
        raise InputError(f"--repeats must be at least 1, got {args.repeats}")
    path = args.problem or shipped_path("config/problems/pyramid.yaml")
    problem = load_problem_file(path, "bench")
    from physics_mapper.bench.physics_costs import costs_text, measure

    scene = problem.scene
    print(
        f"{path}: {len(scene.objects)} objects, {len(scene.static)} static bodies, "
        f"settle_time {scene.search.settle_time} s; medians of {args.repeats} runs"
    )
    print(costs_text(measure(problem, args.repeats)))
    return 0
