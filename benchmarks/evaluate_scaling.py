"""Snapshots evaluated per second by ``evaluate``'s executors, on one bag set, in one run.

Run: ``.venv/bin/python benchmarks/evaluate_scaling.py [--bags B] [--iterations K] [--top-m M] [--workers W]``.

Generates B seeded pyramid bags (``generate``: one particle-filter run of K iterations, M hypotheses
per cube, 5 mm noise, so that many configurations are simulated), then evaluates them exhaustively
(``--exhaustive``: every executor must give the same numbers, which is checked) with

* one worker: a process pool of 1,
* the local pool: a process pool of W workers (default: the cores),
* Ray started locally with W CPUs (``--ray local``),

each timed from the start of its workers to the last result. Start-up is measured apart (workers
started and their imports done, on an empty task each; for Ray also ``ray.init``), and from the
one-worker run come the cost per snapshot (time inside the workers, world built and scored) and,
per executor, the overhead per task (worker time not spent in tasks, per task). From these the
rate of a cluster of N machines of W cores is predicted. Prints the machine's load (uptime) first:
on a shared machine the speed-up is depressed.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import subprocess
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from physics_mapper.cli import main as cli_main
from physics_mapper.evaluation.executors import Executor, ProcessPool, RayCluster, TaskFailure
from physics_mapper.evaluation.runner import BatchRun, run_batch, survey_bags
from physics_mapper.evaluation.settings import Setting
from physics_mapper.evaluation.sources import SurveyedBag, find_bags, read_inputs
from physics_mapper.model.scene import Scene
from physics_mapper.model.scene_files import load_scene

REPO = Path(__file__).resolve().parent.parent
SCENE = REPO / "config" / "scenes" / "pyramid.yaml"
#: Machines in the cluster predictions.
CLUSTER_MACHINES = (1, 4, 16, 64)


def ready(progress: Callable[[], None] | None = None) -> int:
    """An empty task that imports what a real one imports: a worker's start-up, measured."""
    import physics_mapper.evaluation.tasks  # noqa: F401

    return os.getpid()


class _Quiet:
    """Events that keep nothing: the start-up runs."""

    def progress(self, index: int) -> None:
        return None

    def finished(self, index: int, output: Any) -> None:
        return None

    def failed(self, index: int, failure: TaskFailure) -> None:
        raise RuntimeError(f"start-up task failed: {failure.error}")


@dataclass(frozen=True)
class Measured:
    """One executor's evaluation: its ``startup`` (s: workers started, imports done) and the batch run.

    The pool starts its workers inside every run, Ray once when it starts: ``steady`` is the run's
    time without start-up, ``end_to_end`` with it.
    """

    name: str
    workers: int
    startup: float
    run: BatchRun
    startup_in_run: bool

    @property
    def snapshots(self) -> int:
        return sum(len(output.records) for output in self.run.outputs.values())

    @property
    def busy(self) -> float:
        return sum(output.busy_time for output in self.run.outputs.values())

    @property
    def steady(self) -> float:
        return self.run.wall_time - self.startup if self.startup_in_run else self.run.wall_time

    @property
    def end_to_end(self) -> float:
        return self.run.wall_time if self.startup_in_run else self.startup + self.run.wall_time


def make_bags(folder: Path, count: int, iterations: int, top_m: int) -> list[Path]:
    for seed in range(count):
        arguments = ["generate", str(SCENE), "-o", str(folder / f"bag_{seed:03d}"), "--iterations", str(iterations)]
        arguments += ["--top-m", str(top_m), "--particles", "200", "--sigma", "0.005", "--sigma-rotation", "0.005"]
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            assert cli_main([*arguments, "--seed", str(seed)]) == 0
    return find_bags([folder])


def measure(name: str, executor: Executor, workers: int, scene: Scene, bags: list[SurveyedBag]) -> Measured:
    """Start-up (entering the executor, then an empty task per worker), then the exhaustive evaluation."""
    pool = isinstance(executor, ProcessPool)
    started = time.monotonic()
    with executor:
        executor.run(ready, [()] * workers, _Quiet())  # a pool stops these workers again; Ray keeps them
        startup = time.monotonic() - started
        run = run_batch(
            scene, [Setting((), scene.search)], bags, True, executor, progress_prefix=name, progress_mode="off"
        )
    return Measured(name, workers, startup, run, startup_in_run=pool)


def records(run: BatchRun) -> list[Any]:
    return [run.outputs[key].records for key in sorted(run.outputs)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--bags", type=int, default=12, help="bags (default 12)")
    parser.add_argument("--iterations", type=int, default=4, help="snapshots per bag (default 4)")
    parser.add_argument("--top-m", type=int, default=4, help="hypotheses per cube (default 4: 64 configurations)")
    parser.add_argument("--workers", type=int, default=len(os.sched_getaffinity(0)), help="pool size (default: cores)")
    args = parser.parse_args()
    print("load:", subprocess.run(["uptime"], capture_output=True, text=True, check=False).stdout.strip())
    scene = load_scene(SCENE)
    with tempfile.TemporaryDirectory() as folder:
        paths = make_bags(Path(folder), args.bags, args.iterations, args.top_m)
        bags, survey_time = survey_bags(paths, scene)
        started = time.monotonic()
        for path in paths:
            read_inputs(path, scene)
        read_time = (time.monotonic() - started) / len(paths)  # what the command spends per bag for Ray
        snapshots = sum(bag.expected_snapshots for bag in bags)
        print(
            f"{len(bags)} bags, {snapshots} snapshots ({args.top_m}^3 configurations each), exhaustive; "
            f"per bag: surveyed in {survey_time / len(bags) * 1000:.1f} ms, input topics read in "
            f"{read_time * 1000:.1f} ms (for Ray, by the command)"
        )
        runs = [
            measure("1 worker", ProcessPool(1), 1, scene, bags),
            measure(f"pool of {args.workers}", ProcessPool(args.workers), args.workers, scene, bags),
            measure(f"Ray local, {args.workers} CPUs", RayCluster("local", args.workers), args.workers, scene, bags),
        ]
    identical = all(records(run.run) == records(runs[0].run) for run in runs)
    single = runs[0]
    cost = single.busy / single.snapshots
    tasks = len(bags)
    print(f"results identical across executors: {'yes' if identical else 'NO'}")
    print(f"cost per snapshot (in the worker, 1 worker): {cost * 1000:.0f} ms\n")
    columns = ["executor", "start-up", "evaluation", "snapshots/s", "speed-up", "end to end: snapshots/s", "speed-up"]
    print("| " + " | ".join([*columns, "overhead per task"]) + " |")
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    overheads = {}
    for run in runs:
        overheads[run.name] = (run.workers * run.steady - run.busy) / tasks
        print(
            f"| {run.name} | {run.startup:.2f} s | {run.run.wall_time:.2f} s | {run.snapshots / run.steady:.2f} | "
            f"{single.steady / run.steady:.2f} x | {run.snapshots / run.end_to_end:.2f} | "
            f"{single.end_to_end / run.end_to_end:.2f} x | {overheads[run.name] * 1000:.0f} ms |"
        )
    print(
        "\nsnapshots/s: without start-up (the pool starts its workers in each run, Ray once); end to end: with it. "
        "Overhead per task: worker time not spent inside tasks (dispatch, transfer, idle at the end), per task."
    )
    ray = runs[2]
    print(
        f"\nPredicted for a Ray cluster of N machines x {args.workers} cores and a data set of 1000 bags x 20 "
        f"snapshots: time = start-up + the longer of reading the bags here (1000 x {read_time * 1000:.1f} ms, "
        f"while tasks run) and computing ((20000 x {cost * 1000:.0f} ms + 1000 tasks x "
        f"{overheads[ray.name] * 1000:.0f} ms) / (N x {args.workers})):\n"
    )
    print("| machines | snapshots/s | minutes for 20000 snapshots |")
    print("| ---: | ---: | ---: |")
    for machines in CLUSTER_MACHINES:
        compute = (20_000 * cost + 1000 * overheads[ray.name]) / (machines * args.workers)
        seconds = ray.startup + max(1000 * read_time, compute)
        print(f"| {machines} | {20_000 / seconds:.1f} | {seconds / 60:.1f} |")


if __name__ == "__main__":
    main()
