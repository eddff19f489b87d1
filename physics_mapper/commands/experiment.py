"""``physics-mapper experiment``: the paper's figures reproduced as plots and summaries."""

from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import replace
from pathlib import Path

from physics_mapper.model.errors import InputError
from physics_mapper.model.limits import printable

HELP = (
    "reproduce the paper's experiments (Figs. 4, 6, 8 and the peg in a hole) and the cluttered mesh scenes "
    "as PNG plots and summaries"
)

#: Experiment name -> module under ``physics_mapper.experiments``, in the order ``all`` runs them.
EXPERIMENTS = ("fig4", "fig6", "fig8", "peg", "clutter")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("experiment", choices=(*EXPERIMENTS, "all"), help="which figure to reproduce, or all")
    parser.add_argument(
        "-o", "--output", type=Path, default=Path("reports"), metavar="DIR", help="output folder (default: reports)"
    )
    parser.add_argument(
        "--runs",
        type=int,
        metavar="N",
        help="runs of figs. 6 and 8 (default: the paper's 20) and of clutter (default: 5)",
    )
    parser.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    parser.add_argument(
        "--particles", type=int, metavar="P", help="particles per filter in figs. 6 and 8 (default: the paper's 1000)"
    )
    parser.add_argument(
        "--search-budget",
        type=float,
        metavar="SECONDS",
        help="seconds per search in clutter (default: each scene's deadline, one node tick)",
    )
    parser.add_argument(
        "--scenes",
        type=Path,
        metavar="DIR",
        help="folder of the scene files (default: the shipped config/scenes)",
    )


def run(args: argparse.Namespace) -> int:
    if args.runs is not None and args.runs < 1:
        raise InputError(f"--runs must be at least 1, got {args.runs}")
    if args.seed < 0:
        raise InputError(f"--seed must not be negative, got {args.seed}")
    if args.output.exists() and not args.output.is_dir():
        raise InputError(f"{args.output} exists and is not a folder")
    if args.search_budget is not None and not (math.isfinite(args.search_budget) and args.search_budget > 0.0):
        raise InputError(f"--search-budget must be a positive number of seconds, got {args.search_budget}")
    if args.scenes is not None and not args.scenes.is_dir():
        raise InputError(f"--scenes {args.scenes} is not a folder")
    # matplotlib only once the arguments are known to be usable.
    import importlib

    from physics_mapper.experiments.common import ExperimentOptions
    from physics_mapper.perception.particle_filter import TrackerSettings

    top_m = TrackerSettings().top_m
    if args.particles is not None and args.particles < top_m:
        raise InputError(f"--particles must be at least {top_m} (the hypotheses kept per object), got {args.particles}")
    try:
        args.output.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise InputError(f"cannot create {args.output}: {error.strerror or error}") from None
    from physics_mapper.evaluation.outputs import lock_report_folder

    lock = lock_report_folder(args.output, "experiment")  # two runs into one folder would mix their reports
    options = ExperimentOptions(
        output_dir=args.output,
        seed=args.seed,
        runs=args.runs,
        particles=args.particles,
        progress=_progress,
        search_budget=args.search_budget,
    )
    if args.scenes is not None:
        options = replace(options, scenes_dir=args.scenes)
    for name in EXPERIMENTS if args.experiment == "all" else (args.experiment,):
        start = time.monotonic()
        output = importlib.import_module(f"physics_mapper.experiments.{name}").run(options)
        _progress(f"{name}: wrote {output.png}, {output.markdown}, {output.json} in {time.monotonic() - start:.1f} s")
    lock.close()
    return 0


def _progress(line: str) -> None:
    print(printable(line), file=sys.stderr, flush=True)
