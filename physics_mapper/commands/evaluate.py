"""``physics-mapper evaluate``: the offline replay of many bags, in parallel, into one report.

Also the options and steps ``sweep`` shares: bags, scene, ``--set``, executor, progress, exit codes.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import shlex
import signal
import sys
import time
from collections.abc import Iterator, Sequence
from pathlib import Path
from types import FrameType
from typing import TYPE_CHECKING

from physics_mapper.commands.files import input_file, load_scene_file
from physics_mapper.model.errors import EXIT_FAILURE, EXIT_INCOMPLETE, EXIT_INTERRUPTED, InputError
from physics_mapper.model.limits import printable

if TYPE_CHECKING:
    from physics_mapper.evaluation.executors import Executor
    from physics_mapper.evaluation.runner import BatchRun
    from physics_mapper.evaluation.settings import Setting
    from physics_mapper.model.scene import Scene, SearchParams

HELP = "search every snapshot of many bags offline, as the node would, in parallel; one report of validity and errors"


#: Most local worker processes: each holds its own interpreter, pybullet and a bag's inputs, about 80 MB.
MAX_WORKERS = 64


def default_workers() -> int:
    """The cores this process may run on (at most :data:`MAX_WORKERS`)."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    return min(cores, MAX_WORKERS)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_batch_arguments(parser, "evaluate")


def add_batch_arguments(parser: argparse.ArgumentParser, name: str) -> None:
    """The options ``evaluate`` and ``sweep`` share."""
    parser.add_argument(
        "bags", nargs="+", type=Path, metavar="BAG_OR_DIR", help="bags (mcap or sqlite3), or folders searched for bags"
    )
    parser.add_argument("--scene", type=input_file, required=True, help="scene YAML the hypotheses are for")
    parser.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override the scene's search value KEY (a search: key, e.g. deadline=0.1); repeatable",
    )
    parser.add_argument(
        "-o", "--output", type=Path, metavar="REPORT_DIR", help=f"report folder (default: {name}_<date-time>)"
    )
    parser.add_argument(
        "--exhaustive",
        action="store_true",
        help="search every reachable configuration instead of stopping at the deadline "
        "(the results then do not depend on the machine, nor on the executor)",
    )
    parser.add_argument(
        "--workers",
        type=int,
        metavar="N",
        help=f"local worker processes (default: the cores, here {default_workers()}); 0: in this process",
    )
    parser.add_argument(
        "--ray",
        metavar="ADDRESS",
        help="run on a Ray cluster instead: auto, HOST:PORT of its head, ray://HOST:PORT, or local (a new one here)",
    )
    parser.add_argument(
        "--progress",
        choices=("auto", "bar", "lines", "off"),
        default="auto",
        help="on stderr: a bar with ETA (terminal), one line per finished bag (log), or nothing "
        "(default auto: bar on a terminal, lines otherwise)",
    )


def run(args: argparse.Namespace) -> int:
    from physics_mapper.evaluation.reports import ReportContext, write_evaluation
    from physics_mapper.evaluation.settings import Setting

    scene, params = load_scene_and_search(args)
    batch = run_batch_command(args, scene, [Setting((), params)])
    if batch is None:
        return EXIT_FAILURE
    output = write_evaluation(batch, ReportContext(command_line(args), args.scene), args.output)
    print_evaluation(output.summary)
    print(f"report: {output.markdown} (and {output.json.name}, {output.png.name})")
    return exit_code(batch)


def load_scene_and_search(args: argparse.Namespace) -> tuple[Scene, SearchParams]:
    """The scene and its search parameters with ``--set`` applied; the output folder checked."""
    from physics_mapper.evaluation.settings import with_overrides

    scene = load_scene_file(args.scene, args.command)
    params = with_overrides(scene.search, args.set)
    if args.output is None:
        args.output = Path(f"{args.command}_{time.strftime('%Y_%m_%d-%H_%M_%S')}")
    if args.output.exists() and not args.output.is_dir():
        raise InputError(f"{args.output} exists and is not a folder")
    if args.workers is not None and args.workers < 0:
        raise InputError(f"--workers must not be negative, got {args.workers}")
    if args.workers is not None and args.workers > MAX_WORKERS:
        raise InputError(f"--workers must be at most {MAX_WORKERS} (each takes about 80 MB), got {args.workers}")
    if args.ray is not None and args.ray != "local" and args.workers is not None:
        raise InputError("--workers is for the local pool and --ray local; a cluster's CPUs set its parallelism")
    return scene, params


def executor_for(args: argparse.Namespace) -> Executor:
    """``--ray``, else the local pool of ``--workers`` (default: the cores), or this process for 0."""
    from physics_mapper.evaluation.executors import InProcess, ProcessPool, RayCluster

    workers = default_workers() if args.workers is None else args.workers
    if args.ray is not None:
        return RayCluster(args.ray, workers if args.ray == "local" else None)
    return ProcessPool(workers) if workers > 0 else InProcess()


def command_line(args: argparse.Namespace) -> str:
    """The command that reproduces the run (with every option that changes its results or its executor)."""
    words = ["physics-mapper", args.command, *map(str, args.bags), "--scene", str(args.scene)]
    for assignment in args.set:
        words += ["--set", assignment]
    for assignment in getattr(args, "grid", []):
        words += ["--grid", assignment]
    if getattr(args, "criterion", None) is not None:
        words += ["--criterion", args.criterion]
    if args.exhaustive:
        words.append("--exhaustive")
    if args.ray is not None:
        words += ["--ray", args.ray]
    if args.workers is not None:
        words += ["--workers", str(args.workers)]
    return shlex.join([*words, "-o", str(args.output)])


@contextlib.contextmanager
def sigterm_as_interrupt() -> Iterator[None]:
    """SIGTERM (a batch system's time limit, ``kill``) stops the run like Ctrl-C, with its partial report."""

    def interrupt(signum: int, frame: FrameType | None) -> None:
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def run_batch_command(args: argparse.Namespace, scene: Scene, settings: Sequence[Setting]) -> BatchRun | None:
    """Find and read the bags, then run every (setting, bag) task on the executor the options choose.

    None (with one error line) when the executor cannot start (no Ray cluster at the address).
    """
    from physics_mapper.evaluation.executors import RayUnavailable
    from physics_mapper.evaluation.runner import run_batch, survey_bags
    from physics_mapper.evaluation.sources import find_bags

    name = args.command
    paths = find_bags(args.bags)
    args.output.mkdir(parents=True, exist_ok=True)  # before the run: an unusable folder is known at once
    from physics_mapper.evaluation.outputs import lock_report_folder

    args.report_lock = lock_report_folder(args.output, name)  # held until the process ends
    executor = executor_for(args)
    try:
        with sigterm_as_interrupt(), executor:
            bags, survey_time = survey_bags(paths, scene)
            unreadable = sum(1 for bag in bags if bag.error is not None)
            where = executor.description()
            size = ", ".join(f"{key} {value}" for key, value in where.items() if key != "executor")
            found = f"{len(bags)} bag(s)" + (f", {unreadable} without readable metadata" if unreadable else "")
            tasks = len(settings) * (len(bags) - unreadable)
            progress(name, f"{found}; {tasks} task(s) on {where['executor']} ({size})")
            batch = run_batch(
                scene,
                settings,
                bags,
                args.exhaustive,
                executor,
                progress_prefix=name,
                progress_mode=args.progress,
                survey_time=survey_time,
            )
    except RayUnavailable as error:
        print(f"physics-mapper {name}: error: {printable(str(error))}", file=sys.stderr)
        return None
    if batch.interrupted:
        progress(name, "interrupted: writing the report of what finished")
    return batch


def progress(name: str, text: str) -> None:
    print(f"{name}: {printable(text)}", file=sys.stderr, flush=True)


def exit_code(batch: BatchRun) -> int:
    """130 interrupted, 3 some bags unreadable or failed, else 0."""
    if batch.interrupted:
        return EXIT_INTERRUPTED
    unusable = any(output.error is not None for output in batch.outputs.values())
    if batch.failures or unusable or any(bag.error is not None for bag in batch.bags):
        return EXIT_INCOMPLETE
    return 0


def print_evaluation(data: dict[str, object]) -> None:
    """A few lines on stdout: what was evaluated, the map shares, the mean errors and the main test."""
    from physics_mapper.evaluation.reports import overall_lines

    for line in overall_lines(data):
        print(line)
