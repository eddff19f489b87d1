"""The bags of a batch run: found under the paths given, read, and turned into snapshots (or an error).

A rosbag2 bag is a folder with a ``metadata.yaml`` and its storage files (``.mcap`` or ``.db3``).
A folder with storage files but no ``metadata.yaml`` is a bag too, a broken one: it is listed so
that the run reports it instead of passing over it. A bag that cannot be used (unreadable,
corrupt, truncated, a topic of the wrong type, no hypotheses, or none that pass the node's input
rules) keeps its one-line error and gets no task; the other bags are evaluated.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from physics_mapper.bags.snapshots import BagSnapshot, bag_snapshots, input_topics, no_snapshot_reason
from physics_mapper.bags.storage import BagError, check_hypothesis_topics, read_bag
from physics_mapper.core.errors import InputError
from physics_mapper.core.scene import Scene

METADATA = "metadata.yaml"
#: Storage file suffix -> rosbag2 storage plugin.
STORAGE_SUFFIXES = {".mcap": "mcap", ".db3": "sqlite3"}


@dataclass(frozen=True)
class LoadedBag:
    """A bag of the run: its storage plugin (None if unknown), its snapshots, or why it cannot be evaluated."""

    path: Path
    storage: str | None
    snapshots: tuple[BagSnapshot, ...]
    error: str | None = None


def _is_bag(files: Sequence[str]) -> bool:
    return METADATA in files or any(Path(name).suffix in STORAGE_SUFFIXES for name in files)


def _bags_under(path: Path) -> list[Path]:
    """``path`` if it is a bag (or a bag's storage file), else every bag in the folders below it, sorted."""
    if path.is_file():
        return [path.parent] if path.suffix in STORAGE_SUFFIXES or path.name == METADATA else []
    found = []
    for folder, subfolders, files in os.walk(path):
        subfolders.sort()
        if _is_bag(files):
            found.append(Path(folder))
            subfolders.clear()  # a bag's folder holds no other bag
    return found


def find_bags(paths: Sequence[Path]) -> list[Path]:
    """Every bag at or under ``paths``, in the order given (folders: sorted), each once.

    Raises InputError for a path that does not exist or holds no bag.
    """
    found: list[Path] = []
    seen: set[Path] = set()
    for path in paths:
        if not path.exists():
            raise InputError(f"{path}: no such file or folder")
        bags = _bags_under(path)
        if not bags:
            raise InputError(f"{path}: no rosbag2 bag in it (a folder with {METADATA}, .mcap or .db3 files)")
        for bag in bags:
            if bag.resolve() not in seen:
                seen.add(bag.resolve())
                found.append(bag)
    return found


def storage_of(path: Path) -> str | None:
    """The storage plugin of a bag folder, from its files' suffixes (None if none or mixed)."""
    kinds = {STORAGE_SUFFIXES[f.suffix] for f in path.iterdir() if f.suffix in STORAGE_SUFFIXES}
    return kinds.pop() if len(kinds) == 1 else None


def load_bag(path: Path, scene: Scene) -> LoadedBag:
    """Read a bag's input topics and take its snapshots as the node would; an unusable bag keeps its error."""
    storage = storage_of(path) if path.is_dir() else None
    try:
        bag = read_bag(path, input_topics(scene))
        check_hypothesis_topics(bag, scene.object_names)
        snapshots = tuple(bag_snapshots(bag, scene))
    except BagError as error:
        return LoadedBag(path, storage, (), str(error).removeprefix(f"{path}: "))
    except Exception as error:  # a bag must not end the run of the others, whatever breaks on it
        return LoadedBag(path, storage, (), f"unexpected {type(error).__name__}: {error}")
    if not snapshots:
        return LoadedBag(path, storage, (), no_snapshot_reason(scene))
    return LoadedBag(path, storage, snapshots)
