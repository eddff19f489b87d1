"""A batch run: bags surveyed here, one task per (readable bag, setting) on an executor, results gathered.

Tasks go out bag by bag (every setting of a bag, then the next bag), the bags with the most snapshots
first, which keeps workers busy to the end. Local workers read their bag from its path; for workers
that may be on other machines (``Executor.remote_workers``) the bag's input topics are read here, one
bag at a time as its tasks go out. Ctrl-C (KeyboardInterrupt) ends the run early: what finished is
kept and :attr:`BatchRun.interrupted` says so.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from physics_mapper.bags.storage import Bag
from physics_mapper.evaluation.executors import Executor, TaskFailure
from physics_mapper.evaluation.progress import Progress, ProgressMode
from physics_mapper.evaluation.settings import Setting
from physics_mapper.evaluation.sources import SurveyedBag, UnreadableBag, read_inputs, survey_bag
from physics_mapper.evaluation.tasks import TaskOutput, evaluate_bag
from physics_mapper.model.scene import Scene

#: A task: (setting index, bag index).
TaskKey = tuple[int, int]


@dataclass
class BatchRun:
    """Everything a batch run did: its settings and bags, each task's output or failure, and how it ran.

    ``exhaustive``: every search ran to the end (else each stopped at its setting's deadline).
    ``executor`` describes what ran the tasks; ``started`` is an ISO 8601 UTC time, ``wall_time``
    and ``survey_time`` the seconds spent running the tasks and surveying the bags.
    """

    scene: Scene
    settings: Sequence[Setting]
    bags: Sequence[SurveyedBag]
    exhaustive: bool
    executor: dict[str, Any]
    started: str
    outputs: dict[TaskKey, TaskOutput] = field(default_factory=dict)
    failures: dict[TaskKey, TaskFailure] = field(default_factory=dict)
    interrupted: bool = False
    wall_time: float = 0.0
    survey_time: float = 0.0

    def evaluated(self, key: TaskKey) -> TaskOutput | None:
        """The task's output if it evaluated its bag (not if the bag was unusable)."""
        output = self.outputs.get(key)
        return output if output is not None and output.error is None else None

    def status(self, key: TaskKey) -> tuple[str, str | None]:
        """A task's status (``evaluated``, ``unreadable``, ``unusable``: read but not of the scene, ``failed``,
        ``not evaluated``) and error, if any."""
        bag, output = self.bags[key[1]], self.outputs.get(key)
        if bag.error is not None:
            return "unreadable", bag.error
        if output is not None:
            if output.error is None:
                return "evaluated", None
            return ("unusable" if output.unusable else "unreadable"), output.error
        if key in self.failures:
            return "failed", self.failures[key].error
        return "not evaluated", "the run was interrupted first"


class _Calls(Sequence[tuple[Any, ...]]):
    """Each task's arguments, made when the executor asks: (scene with the setting's search, the bag's
    path or, for remote workers, its input topics read here (the last bag read is kept), budget, the
    setting's association settings)."""

    def __init__(self, run: BatchRun, keys: Sequence[TaskKey], remote: bool) -> None:
        self.keys, self.remote = keys, remote
        self.scenes = [replace(run.scene, search=setting.params) for setting in run.settings]
        self.budgets = [None if run.exhaustive else setting.params.deadline for setting in run.settings]
        self.associations = [setting.association for setting in run.settings]
        self.bags, self.scene = run.bags, run.scene
        self._read: tuple[int, Bag | UnreadableBag] | None = None

    def __len__(self) -> int:
        return len(self.keys)

    def _source(self, bag: int) -> Path | Bag | UnreadableBag:
        if not self.remote:
            return self.bags[bag].path
        if self._read is None or self._read[0] != bag:
            self._read = (bag, read_inputs(self.bags[bag].path, self.scene))
        return self._read[1]

    def __getitem__(self, index: int) -> tuple[Any, ...]:  # type: ignore[override]  # no slices asked for
        setting, bag = self.keys[index]
        return (self.scenes[setting], self._source(bag), self.budgets[setting], self.associations[setting])


class _Collector:
    """The executor's events, into a :class:`BatchRun` and a :class:`Progress`."""

    def __init__(self, run: BatchRun, keys: Sequence[TaskKey], bar: Progress) -> None:
        self.run, self.keys, self.bar = run, keys, bar
        self.counted = [0] * len(keys)  # snapshots of each task shown as done

    def _settle(self, index: int, actual: int) -> None:
        """Correct the expected snapshot count of a finished task to the ``actual`` one."""
        self.bar.total_snapshots += actual - self.run.bags[self.keys[index][1]].expected_snapshots
        self.bar.snapshot_done(actual - self.counted[index])  # a remote worker reports no progress
        self.counted[index] = actual

    def _what(self, index: int) -> str:
        setting, bag = self.keys[index]
        where = str(self.run.bags[bag].path)
        return f"{where} [{self.run.settings[setting].label}]" if len(self.run.settings) > 1 else where

    def progress(self, index: int) -> None:
        self.counted[index] += 1
        self.bar.snapshot_done()

    def finished(self, index: int, output: Any) -> None:
        self.run.outputs[self.keys[index]] = output
        self._settle(index, len(output.records))
        if output.error is not None:
            kind = "unusable" if output.unusable else "unreadable"
            self.bar.task_done(f"{self._what(index)}: {kind}: {output.error}")
            return
        valid = sum(1 for record in output.records if record["valid"])
        self.bar.task_done(f"{self._what(index)}: {len(output.records)} snapshots, {valid} with a valid map")

    def failed(self, index: int, failure: TaskFailure) -> None:
        self.run.failures[self.keys[index]] = failure
        self._settle(index, self.counted[index])
        self.bar.task_done(f"{self._what(index)}: failed: {failure.error}")


def survey_bags(paths: Sequence[Path], scene: Scene) -> tuple[list[SurveyedBag], float]:
    """Every bag's metadata surveyed (or its error), in order, and the seconds it took."""
    started = time.monotonic()
    bags = [survey_bag(path, scene) for path in paths]
    return bags, time.monotonic() - started


def run_batch(
    scene: Scene,
    settings: Sequence[Setting],
    bags: Sequence[SurveyedBag],
    exhaustive: bool,
    executor: Executor,
    *,
    progress_prefix: str,
    progress_mode: ProgressMode = "auto",
    survey_time: float = 0.0,
    function: Callable[..., TaskOutput] = evaluate_bag,
) -> BatchRun:
    """Search every snapshot of every readable bag with every setting, on ``executor``.

    ``function(scene, source, budget, association, progress=...)`` runs one task (the default reads the bag and
    runs the offline replay's search and scoring); each setting's scene carries its search
    parameters, and the budget is its deadline, or None when ``exhaustive``. ``survey_time``:
    seconds it took to survey ``bags``.
    """
    started_at = datetime.now(UTC).isoformat(timespec="seconds")
    run = BatchRun(scene, settings, bags, exhaustive, executor.description(), started_at, survey_time=survey_time)
    order = sorted((b for b, bag in enumerate(bags) if bag.error is None), key=lambda b: -bags[b].expected_snapshots)
    keys = [(s, b) for b in order for s in range(len(settings))]
    total = sum(bags[b].expected_snapshots for _, b in keys)
    progress = Progress(progress_prefix, total, len(keys), mode=progress_mode)
    started = time.monotonic()
    try:
        executor.run(function, _Calls(run, keys, executor.remote_workers), _Collector(run, keys, progress))
    except KeyboardInterrupt:
        run.interrupted = True
    finally:
        run.wall_time = time.monotonic() - started
        progress.close()
    return run
