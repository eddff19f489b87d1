"""Task functions that misbehave on purpose, for the executors' fault handling (``test_evaluate.py``).

Executors import them by name in their worker processes, so they live in a module of their own. Each
run of a task leaves a file ``<name>.<attempt>`` in ``marker_dir``, so a test can count the runs.
"""

from __future__ import annotations

import os
import signal
from collections.abc import Callable
from pathlib import Path
from typing import Any

from physics_mapper.bags.storage import Bag
from physics_mapper.evaluation.sources import UnreadableBag
from physics_mapper.evaluation.tasks import TaskOutput, evaluate_bag
from physics_mapper.model.scene import Scene


def _attempt(marker_dir: str, name: str) -> int:
    """Record one more run of task ``name`` and return its number (1 for the first)."""
    attempt = 1 + sum(1 for path in Path(marker_dir).iterdir() if path.stem == name)
    (Path(marker_dir) / f"{name}.{attempt}").touch()
    return attempt


def _die() -> None:
    os.kill(os.getpid(), signal.SIGKILL)  # as the out-of-memory killer does: no clean-up, no exception


def behave(marker_dir: str, name: str, behaviour: str, progress: Callable[[], None] | None = None) -> str:
    """``ok``: return; ``die``: kill its own process every time; ``die_once``: only on the first run;
    ``raise``: raise ValueError."""
    attempt = _attempt(marker_dir, name)
    if behaviour == "die" or (behaviour == "die_once" and attempt == 1):
        _die()
    if behaviour == "raise":
        raise ValueError(f"{name} cannot be used")
    if progress is not None:
        progress()
    return f"{name} done in run {attempt}"


#: The worker of :func:`die_on_bag` dies on the bag of this name.
FATAL_BAG = "b_pyramid_sqlite3"


def die_on_bag(
    scene: Scene,
    source: Path | Bag | UnreadableBag,
    budget: float | None,
    association: Any = None,
    progress: Any = None,
) -> TaskOutput:
    """The offline evaluation, except that a worker given the bag FATAL_BAG dies, every time."""
    if (source if isinstance(source, Path) else source.path).name == FATAL_BAG:
        _die()
    return evaluate_bag(scene, source, budget, association, progress)
