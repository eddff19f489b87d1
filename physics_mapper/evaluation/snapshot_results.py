"""Evaluating a bag: a search per input snapshot, or a live node's recorded choices, scored (ROS-free).

A :class:`SnapshotResult` pairs a snapshot (:mod:`physics_mapper.evaluation.snapshots`) with the
configuration chosen for it, by the offline search here or by a live node (read back from its
recorded outputs, matched by stamp: the node stamps its outputs with the newest input stamp
used). Errors are position errors in metres against the bag's ``/ground_truth``: per object,
and in total (the sum over objects, the paper's "total configuration error"), for C111 (every
object's top hypothesis), the chosen hypotheses and their settled poses; identical instances against the
true object of their class matched to them (:mod:`~physics_mapper.evaluation.scoring`).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from physics_mapper.bags.storage import (
    POSE_ARRAY,
    Bag,
    BagWriter,
    decoding,
    offered_qos,
    pose_array_cdr,
    pose_array_from_cdr,
)
from physics_mapper.evaluation.identity import identity_metrics, identity_text, record_frames
from physics_mapper.evaluation.scoring import ObjectClasses, matched_errors, rank_one_poses
from physics_mapper.evaluation.snapshots import BagSnapshot, Decision, bag_snapshots
from physics_mapper.mapping.association import AssociationSettings
from physics_mapper.mapping.previous_map import (
    PreviousMapCheck,
    result_hypotheses,
    search_with_previous_map,
    with_held,
)
from physics_mapper.mapping.topics import MAP_TOPIC_QOS, RECORDED_CONFIGURATION_TOPIC, RECORDED_SETTLED_TOPIC
from physics_mapper.model.geometry import Pose, is_same_pose
from physics_mapper.model.hypotheses import RankedHypotheses
from physics_mapper.model.scene import Scene
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.search.best_first import Search
from physics_mapper.search.report import code_text
from physics_mapper.search.results import Code, SearchResult

#: A published pose is a hypothesis whose position is this close (metres) and whose orientation q'
#: has 1 - |q . q'| at most :data:`SAME_ORIENTATION` (an angle of 2.8e-6 rad). Not a tolerance on the
#: angle: both quaternions went through make_pose, and after a CDR round trip and a second
#: normalisation |q . q'| can be 1 - 2^-52, which acos turns into an angle of 4e-8 rad.
SAME_POSITION = 1e-9
SAME_ORIENTATION = 1e-12


@dataclass(frozen=True)
class SnapshotResult:
    """A snapshot and the configuration chosen for it (``code`` None: nothing was chosen or published).

    ``search`` is the offline search's whole result (validity, fallback, counts, time); None for a
    live node's recorded choice, whose validity the recording does not hold.
    """

    snapshot: BagSnapshot
    code: Code | None
    chosen: tuple[Pose, ...] | None
    settled: tuple[Pose, ...] | None
    search: SearchResult | None = None


def search_offline(
    snapshots: Sequence[BagSnapshot],
    scene: Scene,
    budget: float | None,
    progress: Callable[[int, SearchResult], None] | None = None,
) -> list[SnapshotResult]:
    """One search per snapshot with the scene's parameters, ``budget`` seconds each (None: to the end).

    ``progress(index, result)`` is called after each search.
    """
    with PhysicsChecker(scene) as checker:
        search = OfflineSearch(checker, scene, budget, progress)
        for snapshot in snapshots:
            search(snapshot)
    return search.results


class OfflineSearch:
    """Searches snapshots one by one in one physics world, ``budget`` seconds each (None: to the end), keeping
    each :class:`SnapshotResult`; as a :data:`~physics_mapper.evaluation.snapshots.Decide`, it lets a bag's
    snapshots follow the maps chosen, as the node's inputs follow its ticks (:func:`replay_offline`). As the
    node's ticks, each search follows the last one (what it learned that still holds is kept)."""

    def __init__(
        self,
        checker: PhysicsChecker,
        scene: Scene,
        budget: float | None,
        progress: Callable[[int, SearchResult], None] | None = None,
    ) -> None:
        self.checker, self.scene, self.budget, self.progress = checker, scene, budget, progress
        self.results: list[SnapshotResult] = []
        self._search: Search | None = None
        self._check: PreviousMapCheck | None = None

    def __call__(self, snapshot: BagSnapshot) -> Decision:
        remembered = dict(snapshot.remembered)
        self._search, found, self._check = search_with_previous_map(
            self.checker,
            snapshot.hypotheses,
            self.scene.search,
            remembered,
            self.budget,
            self._search,
            self._check,
            refined=snapshot.remembered_refined,
        )
        ranked = result_hypotheses(snapshot.hypotheses, found, self._check)
        snapshot = replace(snapshot, hypotheses=ranked)
        self.results.append(SnapshotResult(snapshot, found.code, found.poses, found.settled_poses, found))
        if self.progress is not None:
            self.progress(len(self.results) - 1, found)
        return Decision(found, ranked)


def replay_offline(
    bag: Bag,
    scene: Scene,
    budget: float | None,
    association: AssociationSettings | None = None,
    progress: Callable[[int, SearchResult], None] | None = None,
) -> list[SnapshotResult]:
    """The offline replay of a bag: its snapshots (:func:`~physics_mapper.evaluation.snapshots.bag_snapshots`,
    detections associated with ``association``) each searched as it is taken, so that with instances
    the next snapshots follow the map chosen, as the node's do. Without instances, the same as
    :func:`search_offline` of the bag's snapshots."""
    with PhysicsChecker(scene) as checker:
        search = OfflineSearch(checker, scene, budget, progress)
        bag_snapshots(bag, scene, association=association, decide=search)
    return search.results


def write_results(writer: BagWriter, results: Sequence[SnapshotResult], frame_id: str) -> None:
    """Record offline results on the node's output topics at each snapshot's bag time, offered latched as the node's."""
    for topic in (RECORDED_CONFIGURATION_TOPIC, RECORDED_SETTLED_TOPIC):
        writer.add_topic(topic, POSE_ARRAY, [offered_qos(MAP_TOPIC_QOS)])
    for result in results:
        snapshot = result.snapshot
        if result.chosen is None or result.settled is None:
            continue
        chosen = pose_array_cdr(snapshot.stamp_ns, frame_id, result.chosen)
        writer.write(RECORDED_CONFIGURATION_TOPIC, POSE_ARRAY, snapshot.time_ns, chosen)
        settled = pose_array_cdr(snapshot.stamp_ns, frame_id, result.settled)
        writer.write(RECORDED_SETTLED_TOPIC, POSE_ARRAY, snapshot.time_ns, settled)


def code_of(poses: Sequence[Pose], hypotheses: Sequence[RankedHypotheses]) -> Code | None:
    """The code whose hypotheses are ``poses`` (None if some pose is none of its object's hypotheses)."""
    code = []
    for pose, ranked in zip(poses, hypotheses, strict=True):
        rank = next(
            (
                r
                for r in range(1, len(ranked) + 1)
                if is_same_pose(pose, ranked.pose(r), SAME_POSITION, SAME_ORIENTATION)
            ),
            None,
        )
        if rank is None:
            return None
        code.append(rank)
    return tuple(code)


def _last_by_stamp(output: Bag, topic: str, count: int) -> dict[int, tuple[Pose, ...]]:
    """The last PoseArray of ``count`` poses recorded on ``topic`` for each header stamp (ns)."""
    latest: dict[int, tuple[Pose, ...]] = {}
    for message in output.on(topic):
        with decoding(output, message):
            data = pose_array_from_cdr(message.raw)
            if len(data.poses) == count:
                latest[data.stamp_ns] = data.checked_poses()
    return latest


def recorded_results(snapshots: Sequence[BagSnapshot], output: Bag, scene: Scene) -> list[SnapshotResult]:
    """What a live node chose for each snapshot: its last configuration stamped with the snapshot's stamp.

    Stamps are compared exactly (the node carries them as integer nanoseconds). A configuration
    that is not made of the snapshot's hypotheses (the node ticked halfway through a burst and
    never again before the next one) counts as no configuration. An instance the node's previous-map
    check put where an earlier map of the node's rested it (its *held* hypothesis,
    :mod:`~physics_mapper.mapping.existence`) has that pose as its held hypothesis in the result's snapshot.
    """
    count = len(scene.objects)
    chosen = _last_by_stamp(output, RECORDED_CONFIGURATION_TOPIC, count)
    settled = _last_by_stamp(output, RECORDED_SETTLED_TOPIC, count)
    rested: list[set[Pose]] = [set() for _ in range(count)]  # per object, where the maps so far rested it
    earlier = iter(sorted(settled.items()))
    following = next(earlier, None)
    results = []
    for snapshot in snapshots:
        while following is not None and following[0] < snapshot.stamp_ns:
            for rests, pose in zip(rested, following[1], strict=True):
                rests.add(pose)
            following = next(earlier, None)
        poses = chosen.get(snapshot.stamp_ns)
        if poses is not None:
            snapshot = _with_held(snapshot, poses, rested)
        code = None if poses is None else code_of(poses, snapshot.hypotheses)
        if code is None:
            results.append(SnapshotResult(snapshot, None, None, None))
        else:
            results.append(SnapshotResult(snapshot, code, poses, settled.get(snapshot.stamp_ns)))
    return results


def _with_held(snapshot: BagSnapshot, poses: Sequence[Pose], rested: Sequence[set[Pose]]) -> BagSnapshot:
    """``snapshot`` where each object whose pose of ``poses`` is none of its hypotheses but one of ``rested``
    (where the node's maps rested it before) has that pose as its held hypothesis."""
    hypotheses = list(snapshot.hypotheses)
    for index, (pose, ranked) in enumerate(zip(poses, snapshot.hypotheses, strict=True)):
        if pose in rested[index] and code_of([pose], [ranked]) is None:
            hypotheses[index] = with_held(ranked.without_held(), pose)
    return replace(snapshot, hypotheses=tuple(hypotheses))


#: The estimates scored against ground truth: ``top``, every object's most likely hypothesis (the paper's
#: C111, no physics); ``chosen``, the configuration chosen with physics; ``settled``, its settled poses.
ESTIMATES = ("top", "chosen", "settled")


def _estimates(result: SnapshotResult) -> tuple[tuple[Pose, ...] | None, ...]:
    """The poses of each of :data:`ESTIMATES` (None where nothing was chosen)."""
    return rank_one_poses(result.snapshot.hypotheses), result.chosen, result.settled


EstimateErrors = Mapping[str, Sequence[float | None] | None]


def estimate_errors(
    result: SnapshotResult, objects: ObjectClasses
) -> dict[str, tuple[float | None, ...] | None] | None:
    """Each estimate's per-object position errors in metres, keyed by :data:`ESTIMATES`; None for an object
    the estimate leaves out of the map (its *absent* hypothesis). Instances are scored against the true object of
    their class they are matched to in the snapshot (:func:`~physics_mapper.evaluation.scoring.matched_errors`).

    ``chosen`` and ``settled`` are None where nothing was chosen (``top``, C11..1, always exists);
    the whole is None without a ground truth.
    """
    truth = result.snapshot.ground_truth
    if truth is None:
        return None
    return {
        name: None if poses is None else matched_errors(poses, truth, objects, _present(ranks, result))
        for name, poses, ranks in zip(ESTIMATES, _estimates(result), _estimate_codes(result), strict=True)
    }


def _estimate_codes(result: SnapshotResult) -> tuple[Code | None, ...]:
    """The ranks of each of :data:`ESTIMATES` (``top``: every object's first; settled: the chosen ones)."""
    return tuple(1 for _ in result.snapshot.hypotheses), result.code, result.code


def _present(code: Code | None, result: SnapshotResult) -> tuple[bool, ...]:
    """Per object, whether ``code`` puts it in the map (its hypothesis is not *absent*)."""
    hypotheses = result.snapshot.hypotheses
    if code is None:
        return tuple(True for _ in hypotheses)
    return tuple(not ranked.is_absent(rank) for ranked, rank in zip(hypotheses, code, strict=True))


def is_complete(errors: Sequence[float | None] | None) -> bool:
    """Whether an estimate has an error for every object (it was made, and left no object out)."""
    return errors is not None and all(error is not None for error in errors)


def is_scored(errors: EstimateErrors | None) -> bool:
    """Whether a snapshot's :func:`estimate_errors` count in the means: a ground truth and a chosen configuration
    holding every object (a map leaving some instance out is scored by identity alone)."""
    return errors is not None and all(is_complete(errors[name]) for name in ESTIMATES)


def mean_scored_errors(errors: Iterable[EstimateErrors | None]) -> dict[str, tuple[float, ...]] | None:
    """Per estimate (:data:`ESTIMATES`), each object's mean position error in metres.

    ``errors`` are snapshots' :func:`estimate_errors`; the mean is over the scored ones
    (:func:`is_scored`); None if there is none.
    """
    scored = [[e[name] for name in ESTIMATES] for e in errors if e is not None and is_scored(e)]
    if not scored:
        return None
    means = np.mean(np.asarray(scored, dtype=float), axis=0)  # [estimate, object]
    return {name: tuple(row.tolist()) for name, row in zip(ESTIMATES, means, strict=True)}


def evaluation_summary(records: Sequence[Mapping[str, Any]], objects: ObjectClasses) -> str:
    """Snapshot counts, how often C11..1 was kept, and the error table (centimetres) when there is ground truth,
    of the snapshots' :func:`snapshot_result_dict` records.

    The total of a column is the sum over objects (the paper's total configuration error).
    """
    object_names = objects.names
    top = code_text((1,) * len(object_names))
    chosen = [r["code"] for r in records if r["code"] is not None]
    kept_top = sum(1 for code in chosen if all(rank == 1 for rank in code))
    lines = [
        f"{len(records)} snapshots, {len(chosen)} with a configuration: "
        f"{top} in {kept_top}, another configuration in {len(chosen) - kept_top}"
    ]
    identity = identity_text(identity_metrics(record_frames(records), objects))
    errors = mean_scored_errors(r["errors"] for r in records)
    if errors is None:
        lines.append(
            "no position error against ground truth (no /ground_truth in the bag, or no configuration holding "
            "every object)"
        )
        lines.append(identity)
        return "\n".join(lines)
    width = max(len(name) for name in (*object_names, "total"))
    scored = sum(1 for r in records if is_scored(r["errors"]))
    matched = " (instances against the true object matched to them in each)" if objects.classes != objects.names else ""
    lines.append(
        f"mean position error against ground truth over the {scored} snapshots with a configuration{matched} [cm]:"
    )
    labels = (top, "chosen", "settled")  # the names of ESTIMATES, for people
    lines.append(f"{'object':<{width}}" + "".join(f"{label:>10}" for label in labels))
    for index, name in enumerate(object_names):
        lines.append(f"{name:<{width}}" + "".join(f"{e[index] * 100:10.2f}" for e in errors.values()))
    lines.append(f"{'total':<{width}}" + "".join(f"{sum(e) * 100:10.2f}" for e in errors.values()))
    lines.append(identity)
    return "\n".join(lines)


def map_positions(result: SnapshotResult, names: Sequence[str]) -> dict[str, list[float]] | None:
    """The map's centre positions (m) by object name, objects left out (*absent*) not listed (None without a
    configuration): what identity metrics match to the ground truth (:mod:`~physics_mapper.evaluation.identity`).
    The map is the settled poses, as ``/tf`` and ``~/objects`` carry them by default: a valid configuration's
    within ``jitter_threshold`` of its hypotheses, a fallback's the corrected estimate (the refined map), not
    the hypotheses it started from."""
    if result.settled is None or result.code is None:
        return None
    placed = zip(names, result.settled, result.snapshot.hypotheses, result.code, strict=True)
    return {name: list(pose.position) for name, pose, ranked, rank in placed if not ranked.is_absent(rank)}


def snapshot_result_dict(result: SnapshotResult, objects: ObjectClasses) -> dict[str, Any]:
    """One snapshot's result as plain data: times, code, per-object position errors (m) of each estimate
    (:func:`estimate_errors`), the detection each instance took in the snapshot's last array (``detections``:
    name -> its index there), the map's and the truth's positions (``positions``: ``map`` by object name,
    :func:`map_positions`; ``truth`` in scene order, None without a ground truth) and, for an offline search,
    ``valid``, ``fallback_used``, ``previous_map`` (:mod:`~physics_mapper.mapping.previous_map`), ``visited``
    (configurations checked) and ``stopped_at_deadline`` (None for a live node's choice). Wall-clock times
    are left out, so that the same search gives the same data on any machine."""
    snapshot, search = result.snapshot, result.search
    truth = snapshot.ground_truth
    return {
        "time_ns": snapshot.time_ns,
        "stamp_ns": snapshot.stamp_ns,
        "code": None if result.code is None else list(result.code),
        "code_text": code_text(result.code),
        "valid": None if search is None else search.valid,
        "fallback_used": None if search is None else search.fallback_used,
        "previous_map": None if search is None else search.previous_map,
        "visited": None if search is None else search.stats.visited,
        "stopped_at_deadline": None if search is None else search.stats.stopped_at_deadline,
        "errors": estimate_errors(result, objects),
        "detections": dict(snapshot.detections),
        "positions": {
            "map": map_positions(result, objects.names),
            "truth": None if truth is None else [list(pose.position) for pose in truth],
        },
    }
