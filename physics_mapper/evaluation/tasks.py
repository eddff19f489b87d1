"""One task of a batch run, as a worker runs it: one bag read and every snapshot searched with one setting.

The search and its scoring are the offline replay's (:func:`physics_mapper.evaluation.snapshot_results.search_offline`,
:func:`~physics_mapper.evaluation.snapshot_results.snapshot_result_dict`), so ``evaluate`` gives, bag for bag,
what ``replay --offline`` gives. Each task builds its own physics world: a task's results depend
on its scene, settings and bag only, never on which worker ran it or what it ran before.
"""

from __future__ import annotations

import os
import socket
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from physics_mapper.bags.storage import Bag, BagError, BagMismatch
from physics_mapper.evaluation.scoring import ObjectClasses
from physics_mapper.evaluation.snapshot_results import OfflineSearch, SnapshotResult, snapshot_result_dict
from physics_mapper.evaluation.sources import UnreadableBag, load_snapshots
from physics_mapper.mapping.association import AssociationSettings
from physics_mapper.model.scene import Scene
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.search.results import SearchResult


@dataclass(frozen=True)
class TaskOutput:
    """What a task found: ``error`` if the bag cannot be used, else per snapshot its
    :func:`snapshot_result_dict` (``records``, the same on any machine in an exhaustive search) and its
    search time in seconds (``search_times``, wall clock); the seconds the whole task took in its
    worker (``busy_time``: bag read, world built, searched, scored), and the worker (``host:pid``).
    ``unusable``: the bag read fine but holds no usable hypotheses of the scene (``error`` says why)."""

    records: tuple[dict[str, Any], ...]
    search_times: tuple[float, ...]
    busy_time: float
    worker: str
    error: str | None = None
    unusable: bool = False


def _search_time(result: SnapshotResult) -> float:
    assert result.search is not None  # set by every offline search
    return result.search.stats.search_time


def evaluate_bag(
    scene: Scene,
    source: Path | Bag | UnreadableBag,
    budget: float | None,
    association: AssociationSettings | None = None,
    progress: Callable[[], None] | None = None,
) -> TaskOutput:
    """Search every snapshot of a bag (its path, or its input topics read elsewhere) with ``scene.search``,
    ``budget`` seconds each (None: exhaustively), detections associated to instances with ``association``
    (None: the defaults), and score it. ``progress()`` is called after each snapshot.
    """
    started = time.monotonic()
    worker = f"{socket.gethostname()}:{os.getpid()}"

    def searched(_: int, __: SearchResult) -> None:
        if progress is not None:
            progress()

    with PhysicsChecker(scene) as checker:
        search = OfflineSearch(checker, scene, budget, searched)
        try:
            load_snapshots(source, scene, association, search)
        except BagError as error:
            unusable = isinstance(error, BagMismatch)
            return TaskOutput((), (), time.monotonic() - started, worker, str(error), unusable)
    results, objects = search.results, ObjectClasses.of(scene)
    return TaskOutput(
        records=tuple(snapshot_result_dict(result, objects) for result in results),
        search_times=tuple(map(_search_time, results)),
        busy_time=time.monotonic() - started,
        worker=worker,
    )
