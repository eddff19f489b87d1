"""One task of a batch run, as a worker runs it: every snapshot of one bag searched with one setting.

The search and its scoring are the offline replay's (:func:`physics_mapper.bags.evaluation.search_offline`,
:func:`~physics_mapper.bags.evaluation.snapshot_result_dict`), so ``evaluate`` gives, bag for bag,
what ``replay --offline`` gives. Each task builds its own physics world: a task's results depend
on its scene, settings and snapshots only, never on which worker ran it or what it ran before.
"""

from __future__ import annotations

import os
import socket
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from physics_mapper.bags.evaluation import SnapshotResult, search_offline, snapshot_result_dict
from physics_mapper.bags.snapshots import BagSnapshot
from physics_mapper.core.scene import Scene
from physics_mapper.core.search import SearchResult


@dataclass(frozen=True)
class TaskOutput:
    """What a task found: per snapshot its :func:`snapshot_result_dict` (``records``, the same on any machine
    in an exhaustive search) and its search time in seconds (``search_times``, wall clock), the seconds the
    whole task took in its worker (``busy_time``: world built, searched, scored), and the worker (``host:pid``)."""

    records: tuple[dict[str, Any], ...]
    search_times: tuple[float, ...]
    busy_time: float
    worker: str


def _search_time(result: SnapshotResult) -> float:
    assert result.search is not None  # set by every offline search
    return result.search.stats.search_time


def evaluate_snapshots(
    scene: Scene,
    snapshots: Sequence[BagSnapshot],
    budget: float | None,
    progress: Callable[[], None] | None = None,
) -> TaskOutput:
    """Search every snapshot with ``scene.search``, ``budget`` seconds each (None: exhaustively), and score it.

    ``progress()`` is called after each snapshot.
    """
    started = time.monotonic()

    def searched(_: int, __: SearchResult) -> None:
        if progress is not None:
            progress()

    results = search_offline(snapshots, scene, budget, searched)
    return TaskOutput(
        records=tuple(snapshot_result_dict(result) for result in results),
        search_times=tuple(map(_search_time, results)),
        busy_time=time.monotonic() - started,
        worker=f"{socket.gethostname()}:{os.getpid()}",
    )
