"""A batch run: bags read here, one task per (setting, readable bag) on an executor, results gathered.

The bags are read in this process (their input topics only, into snapshots), so workers, local or on
a cluster, need no access to the files; tasks go out longest first (most snapshots), which keeps
workers busy to the end. Ctrl-C (KeyboardInterrupt) ends the run early: what finished is kept
and :attr:`BatchRun.interrupted` says so.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from physics_mapper.batch.executors import Executor, TaskFailure
from physics_mapper.batch.progress import Progress, ProgressMode
from physics_mapper.batch.settings import Setting
from physics_mapper.batch.sources import LoadedBag, load_bag
from physics_mapper.batch.tasks import TaskOutput, evaluate_snapshots
from physics_mapper.core.scene import Scene

#: A task: (setting index, bag index).
TaskKey = tuple[int, int]


@dataclass
class BatchRun:
    """Everything a batch run did: its settings and bags, each task's output or failure, and how it ran.

    ``exhaustive``: every search ran to the end (else each stopped at its setting's deadline).
    ``executor`` describes what ran the tasks; ``started`` is an ISO 8601 UTC time, ``wall_time``
    and ``read_time`` the seconds spent running the tasks and reading the bags.
    """

    scene: Scene
    settings: Sequence[Setting]
    bags: Sequence[LoadedBag]
    exhaustive: bool
    executor: dict[str, Any]
    started: str
    outputs: dict[TaskKey, TaskOutput] = field(default_factory=dict)
    failures: dict[TaskKey, TaskFailure] = field(default_factory=dict)
    interrupted: bool = False
    wall_time: float = 0.0
    read_time: float = 0.0

    def status(self, key: TaskKey) -> tuple[str, str | None]:
        """A task's status (``evaluated``, ``unreadable``, ``failed``, ``not evaluated``) and error, if any."""
        bag = self.bags[key[1]]
        if bag.error is not None:
            return "unreadable", bag.error
        if key in self.outputs:
            return "evaluated", None
        if key in self.failures:
            return "failed", self.failures[key].error
        return "not evaluated", "the run was interrupted first"


class _Collector:
    """The executor's events, into a :class:`BatchRun` and a :class:`Progress`."""

    def __init__(self, run: BatchRun, keys: Sequence[TaskKey], progress: Progress) -> None:
        self.run, self.keys, self.bar = run, keys, progress
        self.counted = [0] * len(keys)  # snapshots of each task shown as done

    def _size(self, index: int) -> int:
        return len(self.run.bags[self.keys[index][1]].snapshots)

    def _catch_up(self, index: int) -> None:
        """Count a finished task's snapshots that no progress event counted (Ray reports per task)."""
        self.bar.snapshot_done(self._size(index) - self.counted[index])
        self.counted[index] = self._size(index)

    def _what(self, index: int) -> str:
        setting, bag = self.keys[index]
        where = str(self.run.bags[bag].path)
        return f"{where} [{self.run.settings[setting].label}]" if len(self.run.settings) > 1 else where

    def progress(self, index: int) -> None:
        self.counted[index] += 1
        self.bar.snapshot_done()

    def finished(self, index: int, output: Any) -> None:
        self.run.outputs[self.keys[index]] = output
        self._catch_up(index)
        valid = sum(1 for record in output.records if record["valid"])
        self.bar.task_done(f"{self._what(index)}: {len(output.records)} snapshots, {valid} with a valid map")

    def failed(self, index: int, failure: TaskFailure) -> None:
        self.run.failures[self.keys[index]] = failure
        self._catch_up(index)
        self.bar.task_done(f"{self._what(index)}: failed: {failure.error}")


def read_bags(paths: Sequence[Path], scene: Scene) -> tuple[list[LoadedBag], float]:
    """Every bag read into snapshots (or its error), in order, and the seconds it took."""
    started = time.monotonic()
    bags = [load_bag(path, scene) for path in paths]
    return bags, time.monotonic() - started


def run_batch(
    scene: Scene,
    settings: Sequence[Setting],
    bags: Sequence[LoadedBag],
    exhaustive: bool,
    executor: Executor,
    *,
    progress_prefix: str,
    progress_mode: ProgressMode = "auto",
    read_time: float = 0.0,
    function: Callable[..., TaskOutput] = evaluate_snapshots,
) -> BatchRun:
    """Search every snapshot of every readable bag with every setting, on ``executor``.

    ``function(scene, snapshots, budget, progress=...)`` runs one task (the default is the offline
    replay's search and scoring); each setting's scene carries its search parameters, and the budget
    is its deadline, or None when ``exhaustive``. ``read_time``: seconds it took to read ``bags``.
    """
    started_at = datetime.now(UTC).isoformat(timespec="seconds")
    run = BatchRun(scene, settings, bags, exhaustive, executor.description(), started_at, read_time=read_time)
    scenes = [replace(scene, search=setting.params) for setting in settings]
    keys = [(s, b) for s in range(len(settings)) for b, bag in enumerate(bags) if bag.error is None]
    keys.sort(key=lambda key: -len(bags[key[1]].snapshots))  # longest first; stable, so ties keep their order
    calls = [(scenes[s], bags[b].snapshots, None if exhaustive else settings[s].params.deadline) for s, b in keys]
    progress = Progress(progress_prefix, sum(len(bags[b].snapshots) for _, b in keys), len(keys), mode=progress_mode)
    started = time.monotonic()
    try:
        executor.run(function, calls, _Collector(run, keys, progress))
    except KeyboardInterrupt:
        run.interrupted = True
    finally:
        run.wall_time = time.monotonic() - started
        progress.close()
    return run
