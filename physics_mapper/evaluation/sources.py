"""The bags of a batch run: found under the paths given, surveyed here, read into snapshots by the workers.

A rosbag2 bag is a folder with a ``metadata.yaml`` and its storage files (``.mcap`` or ``.db3``).
A folder with storage files but no ``metadata.yaml`` is a bag too, a broken one: it is listed so
that the run reports it instead of passing over it.

The command only *surveys* each bag (its metadata: storage and message counts, for the progress
bar and to hand out the longest bags first); the bag's messages are read where it is evaluated,
so that at most the bags in flight are in memory and reading runs in parallel. A worker on another
machine gets the bag's input topics read here (:func:`read_inputs`) instead of its path. A bag that
cannot be used (unreadable, corrupt, truncated, a topic of the wrong type, no hypotheses, or none
that pass the node's input rules) gives its one-line error; the other bags are evaluated.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from physics_mapper.bags.storage import Bag, BagError, BagMismatch, check_hypothesis_topics, message_counts, read_bag
from physics_mapper.evaluation.snapshots import BagSnapshot, Decide, bag_snapshots, input_topics, no_snapshot_reason
from physics_mapper.mapping.association import AssociationSettings
from physics_mapper.mapping.topics import recorded_poses_topic
from physics_mapper.model.errors import InputError
from physics_mapper.model.scene import Scene

METADATA = "metadata.yaml"
#: Storage file suffix -> rosbag2 storage plugin.
STORAGE_SUFFIXES = {".mcap": "mcap", ".db3": "sqlite3"}


@dataclass(frozen=True)
class SurveyedBag:
    """A bag of the run as its metadata describes it: storage plugin (None if unknown), the snapshots
    to expect (the most messages on an object's hypotheses topic), or why it cannot be opened."""

    path: Path
    storage: str | None
    expected_snapshots: int
    error: str | None = None


@dataclass(frozen=True)
class UnreadableBag:
    """What a remote worker gets for a bag that could not be read here: the error."""

    path: Path
    error: str


def _is_bag(files: Sequence[str]) -> bool:
    return METADATA in files or any(Path(name).suffix in STORAGE_SUFFIXES for name in files)


def _bags_under(path: Path) -> list[Path]:
    """``path`` if it is a bag (or a bag's storage file), else every bag in the folders below it, sorted."""
    if path.is_file():
        return [path.parent] if path.suffix in STORAGE_SUFFIXES or path.name == METADATA else []
    found = []
    walked: set[str] = set()
    for folder, subfolders, files in os.walk(path, followlinks=True):  # a bag may be a link to one elsewhere
        real = os.path.realpath(folder)
        if real in walked:  # a link back up the tree, or a second link to one folder
            subfolders.clear()
            continue
        walked.add(real)
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


def _error_text(path: Path, error: BagError) -> str:
    """A bag's error without the bag's path in front (reports show the path beside it)."""
    return str(error).removeprefix(f"{path}: ")


def survey_bag(path: Path, scene: Scene) -> SurveyedBag:
    """A bag's storage and expected snapshots from its metadata, or the error that keeps it from opening."""
    storage = storage_of(path)
    try:
        counts = message_counts(path)
    except BagError as error:
        return SurveyedBag(path, storage, 0, _error_text(path, error))
    expected = max(counts.get(recorded_poses_topic(name), 0) for name in scene.object_names)
    return SurveyedBag(path, storage, expected)


def read_inputs(path: Path, scene: Scene) -> Bag | UnreadableBag:
    """The bag's input topics read here, for a worker elsewhere (or the error)."""
    try:
        return read_bag(path, input_topics(scene))
    except BagError as error:
        return UnreadableBag(path, _error_text(path, error))


def load_snapshots(
    source: Path | Bag | UnreadableBag,
    scene: Scene,
    association: AssociationSettings | None = None,
    decide: Decide | None = None,
) -> tuple[BagSnapshot, ...]:
    """A bag's snapshots as the node would take them; BagError (without the path in front) if it cannot be
    read, BagMismatch if it reads but holds no usable hypotheses of the scene."""
    if isinstance(source, UnreadableBag):
        raise BagError(source.error)
    path = source if isinstance(source, Path) else source.path
    try:
        bag = read_bag(source, input_topics(scene)) if isinstance(source, Path) else source
        check_hypothesis_topics(bag, scene.object_names)
        snapshots = tuple(bag_snapshots(bag, scene, association=association, decide=decide))
    except BagError as error:
        raise type(error)(_error_text(path, error)) from None
    if not snapshots:
        raise BagMismatch(no_snapshot_reason(scene))
    return snapshots
